package android.location;

/** Test double of android.location.Location: the real class's getters, has* flags and setters. */
public class Location {
    private final String provider;
    private double latitude, longitude, altitude;
    private float accuracy, verticalAccuracy;
    private boolean hasAltitude, hasAccuracy, hasVerticalAccuracy;
    private long elapsedRealtimeNanos;

    public Location(String provider) { this.provider = provider; }

    public String getProvider() { return provider; }
    public double getLatitude() { return latitude; }
    public double getLongitude() { return longitude; }
    public double getAltitude() { return altitude; }
    public boolean hasAltitude() { return hasAltitude; }
    public float getAccuracy() { return accuracy; }
    public boolean hasAccuracy() { return hasAccuracy; }
    public float getVerticalAccuracyMeters() { return verticalAccuracy; }
    public boolean hasVerticalAccuracy() { return hasVerticalAccuracy; }
    public long getElapsedRealtimeNanos() { return elapsedRealtimeNanos; }

    public void setLatitude(double v) { latitude = v; }
    public void setLongitude(double v) { longitude = v; }
    public void setAltitude(double v) { altitude = v; hasAltitude = true; }
    public void setAccuracy(float v) { accuracy = v; hasAccuracy = true; }
    public void setVerticalAccuracyMeters(float v) { verticalAccuracy = v; hasVerticalAccuracy = true; }
    public void setElapsedRealtimeNanos(long v) { elapsedRealtimeNanos = v; }
}
