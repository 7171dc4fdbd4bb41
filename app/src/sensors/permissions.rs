//! Android run-time permissions (camera, location) through JNI, and what the app tells the user
//! when one is refused. Written against `jni::Env` only, so the flows — granted, denied, denied
//! for ever — are tested on the host JVM against a test double of `Activity`
//! (tests/jni_location.rs).
//!
//! Calls made (public Android SDK API, level ≥ 23): `Context.checkSelfPermission(String)`,
//! `Activity.requestPermissions(String[], int)`,
//! `Activity.shouldShowRequestPermissionRationale(String)`.
//!
//! A NativeActivity is not told the user's answer (`onRequestPermissionsResult` is not forwarded
//! to native code), so [`PermissionFlow`] reads it back: while the system dialog is up the
//! activity has lost focus; once it has focus again the answer is in `checkSelfPermission`, and
//! Android's `shouldShowRequestPermissionRationale` tells a plain "deny" (true: the app may ask
//! again) from "deny, don't ask again" (false after a request: only the system settings can
//! grant it now).

use super::jni_location::{COARSE_LOCATION, FINE_LOCATION, PERMISSION_GRANTED, checked, jstring};
use anyhow::Result;
use jni::objects::JObject;
use jni::{Env, JValue, jni_sig, jni_str};

/// `android.permission.CAMERA`.
pub const CAMERA: &str = "android.permission.CAMERA";
/// The request code of the camera + location request ("PV").
pub const REQUEST_CODE: i32 = 0x5056;

/// A run-time permission the app asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Permission {
    Camera,
    Location,
}

impl Permission {
    /// The Android permission names requested for it (location: fine and coarse, as Android 12+
    /// requires both in one request; granted means fine).
    pub fn android_names(self) -> &'static [&'static str] {
        match self {
            Permission::Camera => &[CAMERA],
            Permission::Location => &[FINE_LOCATION, COARSE_LOCATION],
        }
    }

    fn label(self) -> &'static str {
        match self {
            Permission::Camera => "Camera",
            Permission::Location => "Location",
        }
    }
}

/// Where a permission stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    Granted,
    /// Not asked yet, or the system dialog is still up.
    Pending,
    /// Refused; the app may ask again.
    Denied,
    /// Refused with "don't ask again" (or refused twice on Android 11+): only the system
    /// settings can grant it now.
    DeniedForever,
}

/// The answer from what Android reports after the dialog closed (see the module text): not
/// granted and no rationale to show after a request means Android will not ask again.
pub fn classify(granted: bool, requested: bool, show_rationale: bool) -> Answer {
    match (granted, requested, show_rationale) {
        (true, _, _) => Answer::Granted,
        (false, false, _) => Answer::Pending,
        (false, true, true) => Answer::Denied,
        (false, true, false) => Answer::DeniedForever,
    }
}

/// What the app shows instead of (camera) or beside (location) the composite when a permission
/// is refused: what is missing, what still works, and how to grant it. `None` when there is
/// nothing to say.
pub fn refusal_message(p: Permission, a: Answer) -> Option<String> {
    let how = match a {
        Answer::Granted | Answer::Pending => return None,
        Answer::Denied => "Tap \"Ask again\", or allow it in Settings → Apps → Previz → Permissions".to_string(),
        Answer::DeniedForever => format!("Android will not ask again: allow it in Settings → Apps → Previz → Permissions → {}", p.label()),
    };
    Some(match p {
        Permission::Camera => {
            format!("Previz needs the camera to show the scene behind the model; without it there is nothing to composite. {how}.")
        }
        Permission::Location => {
            format!("Location is not allowed: the sun is placed from the place and time set in the panel instead of the GPS fix. {how}.")
        }
    })
}

/// `Context.checkSelfPermission(name) == PERMISSION_GRANTED`.
pub fn is_granted(env: &mut Env<'_>, activity: &JObject<'_>, name: &str) -> Result<bool> {
    let s = jstring(env, name)?;
    let r = env.call_method(activity, jni_str!("checkSelfPermission"), jni_sig!("(Ljava/lang/String;)I"), &[JValue::Object(&s)]);
    let v = checked(env, "Context.checkSelfPermission", r)?;
    Ok(checked(env, "checkSelfPermission result", v.i())? == PERMISSION_GRANTED)
}

/// `Activity.shouldShowRequestPermissionRationale(name)`.
pub fn show_rationale(env: &mut Env<'_>, activity: &JObject<'_>, name: &str) -> Result<bool> {
    let s = jstring(env, name)?;
    let r = env.call_method(
        activity,
        jni_str!("shouldShowRequestPermissionRationale"),
        jni_sig!("(Ljava/lang/String;)Z"),
        &[JValue::Object(&s)],
    );
    let v = checked(env, "Activity.shouldShowRequestPermissionRationale", r)?;
    checked(env, "shouldShowRequestPermissionRationale result", v.z())
}

/// `Activity.requestPermissions(names, REQUEST_CODE)`: the system dialog, one page per group.
pub fn request(env: &mut Env<'_>, activity: &JObject<'_>, names: &[&str]) -> Result<()> {
    let Some((first, rest)) = names.split_first() else { return Ok(()) };
    let first = jstring(env, first)?;
    let r = env.new_object_array(names.len() as i32, jni_str!("java/lang/String"), &first);
    let array = checked(env, "new String[]", r)?;
    for (i, n) in rest.iter().enumerate() {
        let s = jstring(env, n)?;
        let r = array.set_element(env, i + 1, &s);
        checked(env, "String[] store", r)?;
    }
    let r = env.call_method(
        activity,
        jni_str!("requestPermissions"),
        jni_sig!("([Ljava/lang/String;I)V"),
        &[JValue::Object(&array), JValue::Int(REQUEST_CODE)],
    );
    checked(env, "Activity.requestPermissions", r)?;
    Ok(())
}

/// The camera + location permission flow of the app's first start (and of every start until
/// both are answered).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PermissionFlow {
    requested: bool,
    camera: Answer,
    location: Answer,
}

impl Default for PermissionFlow {
    fn default() -> Self {
        PermissionFlow { requested: false, camera: Answer::Pending, location: Answer::Pending }
    }
}

impl PermissionFlow {
    /// Ask for what is not granted yet (one system dialog for both), unless already asked.
    pub fn start(&mut self, env: &mut Env<'_>, activity: &JObject<'_>) -> Result<()> {
        self.refresh(env, activity)?;
        let missing: Vec<&str> = [(Permission::Camera, self.camera), (Permission::Location, self.location)]
            .into_iter()
            .filter(|&(_, a)| a != Answer::Granted)
            .flat_map(|(p, _)| p.android_names().iter().copied())
            .collect();
        if !missing.is_empty() && !self.requested {
            request(env, activity, &missing)?;
            self.requested = true;
        }
        Ok(())
    }

    /// Ask again (the "Ask again" button of the refusal screen). Android shows no dialog for a
    /// permission denied for ever; the flow then stays [`Answer::DeniedForever`].
    pub fn ask_again(&mut self, env: &mut Env<'_>, activity: &JObject<'_>) -> Result<()> {
        self.requested = false;
        self.start(env, activity)
    }

    /// Read the answers back. Call it when the activity has focus again (the system dialog
    /// closed), and on every resume: the user may have changed them in the settings meanwhile.
    pub fn refresh(&mut self, env: &mut Env<'_>, activity: &JObject<'_>) -> Result<()> {
        let camera = is_granted(env, activity, CAMERA)?;
        let camera_rationale = !camera && self.requested && show_rationale(env, activity, CAMERA)?;
        let location = is_granted(env, activity, FINE_LOCATION)?;
        let location_rationale = !location && self.requested && show_rationale(env, activity, FINE_LOCATION)?;
        self.camera = classify(camera, self.requested, camera_rationale);
        self.location = classify(location, self.requested, location_rationale);
        Ok(())
    }

    pub fn answer(&self, p: Permission) -> Answer {
        match p {
            Permission::Camera => self.camera,
            Permission::Location => self.location,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify_follows_androids_rationale_rule() {
        // developer.android.com "Request runtime permissions": shouldShowRequestPermissionRationale
        // is true after a plain denial and false after "don't ask again" (and before any request).
        assert_eq!(classify(true, false, false), Answer::Granted);
        assert_eq!(classify(true, true, false), Answer::Granted);
        assert_eq!(classify(false, false, false), Answer::Pending);
        assert_eq!(classify(false, true, true), Answer::Denied);
        assert_eq!(classify(false, true, false), Answer::DeniedForever);
    }

    #[test]
    fn refusal_messages_say_what_is_missing_and_how_to_grant_it() {
        assert_eq!(refusal_message(Permission::Camera, Answer::Granted), None);
        assert_eq!(refusal_message(Permission::Location, Answer::Pending), None);
        let cam = refusal_message(Permission::Camera, Answer::DeniedForever).unwrap();
        assert!(cam.contains("camera") && cam.contains("Settings → Apps → Previz → Permissions → Camera"), "{cam}");
        let loc = refusal_message(Permission::Location, Answer::Denied).unwrap();
        assert!(loc.contains("place and time set in the panel") && loc.contains("Ask again"), "{loc}");
    }
}
