package android.location;

import android.os.Looper;

/** Test double of android.location.LocationManager (the methods the bridge calls + hooks). */
public class LocationManager {
    private boolean gpsEnabled = true;
    private boolean throwSecurity;
    private Location lastGps;
    private Location lastNetwork;
    private LocationListener listener;
    private String request = "";
    private int removed;

    public boolean isProviderEnabled(String provider) {
        return !"gps".equals(provider) || gpsEnabled;
    }

    public Location getLastKnownLocation(String provider) {
        if ("gps".equals(provider)) return lastGps;
        if ("network".equals(provider)) return lastNetwork;
        return null;
    }

    public void requestLocationUpdates(String provider, long minTimeMs, float minDistanceM,
                                       LocationListener l, Looper looper) {
        if (throwSecurity) throw new SecurityException("uid 10123 does not have ACCESS_FINE_LOCATION");
        if (l == null || looper == null) throw new IllegalArgumentException("null listener or looper");
        listener = l;
        request = provider + "," + minTimeMs + "," + minDistanceM + "," + l.getClass().getName();
    }

    public void removeUpdates(LocationListener l) {
        if (l == listener) listener = null;
        removed++;
    }

    // ---- test hooks ----
    public void testSetGpsEnabled(boolean e) { gpsEnabled = e; }
    public void testSetThrowSecurity(boolean t) { throwSecurity = t; }
    public void testSetLastKnown(String provider, Location l) {
        if ("gps".equals(provider)) lastGps = l; else lastNetwork = l;
    }
    /** Deliver a fix the way the system does: through the registered listener. */
    public boolean testDeliver(Location l) {
        if (listener == null) return false;
        listener.onLocationChanged(l);
        return true;
    }
    public String testRequest() { return request; }
    public int testRemoved() { return removed; }
    public boolean testListening() { return listener != null; }
}
