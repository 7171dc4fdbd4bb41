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
    private boolean cameraGranted;
    /** The user's scripted answer to the next dialog: 0 none (dialog still up), 1 allow, 2 deny, 3 deny + don't ask again. */
    private int answer;
    private final java.util.Set<String> rationale = new java.util.HashSet<>();
    private final java.util.Set<String> neverAsk = new java.util.HashSet<>();
    private int requestCount;
    private String lastRequested = "";
    private int lastRequestCode;
    private final LocationManager locationManager = new LocationManager();
    private int rotation;

    public int checkSelfPermission(String permission) {
        boolean location = permission.equals("android.permission.ACCESS_FINE_LOCATION")
                || permission.equals("android.permission.ACCESS_COARSE_LOCATION");
        boolean camera = permission.equals("android.permission.CAMERA");
        return (granted && location) || (cameraGranted && camera) ? 0 : -1; // PERMISSION_GRANTED / PERMISSION_DENIED
    }

    public void requestPermissions(String[] permissions, int requestCode) {
        requestCount++;
        lastRequested = String.join(",", permissions);
        lastRequestCode = requestCode;
        for (String p : permissions) {
            if (neverAsk.contains(p)) {
                continue; // Android shows no dialog for it any more
            }
            boolean camera = p.equals("android.permission.CAMERA");
            switch (answer) {
                case 1:
                    if (camera) cameraGranted = true; else granted = true;
                    break;
                case 2:
                    rationale.add(p);
                    break;
                case 3:
                    rationale.remove(p);
                    neverAsk.add(p);
                    break;
                default:
                    break;
            }
        }
    }

    public boolean shouldShowRequestPermissionRationale(String permission) {
        return rationale.contains(permission);
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
    public void testSetAnswer(int a) { answer = a; }
    public int testRequestCount() { return requestCount; }
    public String testLastRequested() { return lastRequested; }
    public int testLastRequestCode() { return lastRequestCode; }
    public LocationManager testLocationManager() { return locationManager; }
    public void testSetRotation(int r) { rotation = r; }
}
