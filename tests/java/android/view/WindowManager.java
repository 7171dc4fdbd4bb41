package android.view;

/** Test double of android.view.WindowManager. */
public interface WindowManager {
    Display getDefaultDisplay();
}
