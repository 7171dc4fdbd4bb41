package android.location;

import android.os.Bundle;

/** Test double of android.location.LocationListener (the pre-API-30 abstract methods). */
public interface LocationListener {
    void onLocationChanged(Location location);
    void onProviderEnabled(String provider);
    void onProviderDisabled(String provider);
    void onStatusChanged(String provider, int status, Bundle extras);
}
