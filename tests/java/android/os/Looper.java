package android.os;

/** Test double of android.os.Looper: just the main looper singleton. */
public final class Looper {
    private static final Looper MAIN = new Looper();
    private Looper() {}
    public static Looper getMainLooper() { return MAIN; }
}
