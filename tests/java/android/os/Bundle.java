package android.os;

/** Test double of android.os.Bundle (only named in a listener signature). */
public final class Bundle {}
