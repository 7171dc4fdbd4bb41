package android.app;

import android.location.LocationManager;
import android.view.Display;
import android.view.WindowManager;

/**
 * Test double of android.app.Activity: only the methods the Rust JNI bridge calls, with the
 * same signatures, plus hooks the test uses to script the user's answers and inspect calls.
 */
public class Activity {
    private boolean granted;
    private int requestCount;
    private String lastRequested = "";
    private int lastRequestCode;
    private final LocationManager locationManager = new LocationManager();
    private int rotation;

    public int checkSelfPermission(String permission) {
        boolean location = permission.equals("android.permission.ACCESS_FINE_LOCATION")
                || permission.equals("android.permission.ACCESS_COARSE_LOCATION");
        return granted && location ? 0 : -1; // PERMISSION_GRANTED / PERMISSION_DENIED
    }

    public void requestPermissions(String[] permissions, int requestCode) {
        requestCount++;
        lastRequested = String.join(",", permissions);
        lastRequestCode = requestCode;
    }

    public Object getSystemService(String name) {
        return "location".equals(name) ? locationManager : null;
    }

    public ClassLoader getClassLoader() {
        return Activity.class.getClassLoader();
    }

    public String getPackageName() {
        return "org.previz.app";
    }

    public WindowManager getWindowManager() {
        final Display display = new Display(rotation);
        return () -> display;
    }

    // ---- test hooks ----
    public void testSetGranted(boolean g) { granted = g; }
    public int testRequestCount() { return requestCount; }
    public String testLastRequested() { return lastRequested; }
    public int testLastRequestCode() { return lastRequestCode; }
    public LocationManager testLocationManager() { return locationManager; }
    public void testSetRotation(int r) { rotation = r; }
}
