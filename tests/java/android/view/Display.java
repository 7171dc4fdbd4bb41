package android.view;

/** Test double of android.view.Display. */
public class Display {
    private final int rotation;
    public Display(int rotation) { this.rotation = rotation; }
    public int getRotation() { return rotation; }
}
