package org.previz;

import android.location.Location;
import android.location.LocationListener;
import android.os.Bundle;

/**
 * Keeps the newest location fix for the Rust side to poll (app/src/sensors/jni_location.rs).
 * LocationManager calls it on the main looper; Rust reads {@link #latest()} from its own thread,
 * hence the volatile field. Created by Rust through the app's class loader.
 */
public final class LocationListenerBridge implements LocationListener {
    private volatile Location latest;

    public LocationListenerBridge() {}

    @Override
    public void onLocationChanged(Location location) {
        latest = location;
    }

    // Abstract in LocationListener before API 30; no-ops here.
    public void onProviderEnabled(String provider) {}

    public void onProviderDisabled(String provider) {}

    public void onStatusChanged(String provider, int status, Bundle extras) {}

    /** The newest fix, or null before the first. */
    public Location latest() {
        return latest;
    }
}
