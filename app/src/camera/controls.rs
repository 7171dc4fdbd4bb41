//! A phone camera's automatic controls — auto-exposure ([`super::exposure`]) and auto white
//! balance ([`super::white_balance`]) — and their lock.
//!
//! Unlocked, both follow the view frame by frame, so the shots of a capture taken while the
//! user turns from sky to ground each get their own exposure and colour (seams between them).
//! Locked, both keep the values they had when the lock was set, as Camera2's
//! `CONTROL_AE_LOCK` + `CONTROL_AWB_LOCK` and AVFoundation's `AVCaptureExposureModeLocked` +
//! `AVCaptureWhiteBalanceModeLocked` do (the phone backends, [`super::FrameSource::lock_exposure`]).

use super::exposure::{AutoExposure, ExposureMode};
use super::white_balance::{AutoWhiteBalance, NEUTRAL, WhiteBalanceMode};
use anyhow::{Result, bail};

/// What a frame's pixels were exposed with: scene radiance × `exposure` × `white_balance[c]`
/// goes through the tone curve.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CameraSettings {
    /// Multiplier on scene radiance.
    pub exposure: f32,
    /// Per-channel (R, G, B) white balance gains.
    pub white_balance: [f32; 3],
}

impl CameraSettings {
    /// A plain exposure, neutral white balance.
    pub fn exposure(exposure: f32) -> CameraSettings {
        CameraSettings { exposure, white_balance: NEUTRAL }
    }

    /// The multiplier on each channel's radiance.
    pub fn gains(&self) -> [f32; 3] {
        self.white_balance.map(|g| g * self.exposure)
    }

    /// The same white balance at `ev` stops more exposure.
    pub fn with_ev(&self, ev: f32) -> CameraSettings {
        CameraSettings { exposure: self.exposure * ev.exp2(), ..*self }
    }

    pub fn validate(&self) -> Result<()> {
        if !self.gains().iter().all(|g| g.is_finite() && *g > 0.0) {
            bail!("exposure {} and white balance {:?} must be positive numbers", self.exposure, self.white_balance);
        }
        Ok(())
    }
}

/// What the metering grid saw (linear light): the log-average luminance (for exposure) and
/// the per-channel geometric means (for white balance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metering {
    pub log_average_luminance: f32,
    pub log_average_rgb: [f32; 3],
}

/// Auto-exposure and auto white balance, lockable.
#[derive(Clone, Debug)]
pub struct AutoCamera {
    ae: AutoExposure,
    awb: AutoWhiteBalance,
    locked: Option<CameraSettings>,
    last: Option<CameraSettings>,
}

impl AutoCamera {
    pub fn new(exposure: ExposureMode, white_balance: WhiteBalanceMode) -> Result<AutoCamera> {
        Ok(AutoCamera { ae: AutoExposure::new(exposure)?, awb: AutoWhiteBalance::new(white_balance)?, locked: None, last: None })
    }

    /// Whether frames need metering: something is automatic and not locked.
    pub fn needs_metering(&self) -> bool {
        self.locked.is_none() && (self.ae.is_auto() || self.awb.is_auto())
    }

    /// The settings for a frame metered as `metering`, `dt` seconds after the previous frame;
    /// while locked, the locked settings (the metering is ignored).
    pub fn update(&mut self, metering: Metering, dt: f64) -> CameraSettings {
        if let Some(l) = self.locked {
            return l;
        }
        let s = CameraSettings {
            exposure: self.ae.update(metering.log_average_luminance, dt),
            white_balance: self.awb.update(metering.log_average_rgb, dt),
        };
        self.last = Some(s);
        s
    }

    /// Lock exposure and white balance at the last frame's settings (None before the first
    /// frame: nothing to lock yet). Locking again keeps the first lock.
    pub fn lock(&mut self) -> Option<CameraSettings> {
        if self.locked.is_none() {
            self.locked = self.last;
        }
        self.locked
    }

    /// Let both follow the view again, from where they were.
    pub fn unlock(&mut self) {
        self.locked = None;
    }

    pub fn locked(&self) -> Option<CameraSettings> {
        self.locked
    }

    /// The last frame's settings.
    pub fn current(&self) -> Option<CameraSettings> {
        self.locked.or(self.last)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metering(lum: f32, rgb: [f32; 3]) -> Metering {
        Metering { log_average_luminance: lum, log_average_rgb: rgb }
    }

    #[test]
    fn locked_settings_ignore_the_view_until_unlocked() {
        let mut cam =
            AutoCamera::new(ExposureMode::Auto { key: 0.18, adaptation_s: 0.0 }, WhiteBalanceMode::Auto { adaptation_s: 0.0 }).unwrap();
        assert_eq!(cam.lock(), None, "nothing to lock before a frame");
        // Metered 0.72, reddish: exposure 0.18/0.72 = 0.25, gains 0.5, 1, 1.
        let first = cam.update(metering(0.72, [0.4, 0.2, 0.2]), 0.0);
        assert_eq!(first, CameraSettings { exposure: 0.25, white_balance: [0.5, 1.0, 1.0] });
        assert_eq!(cam.lock(), Some(first));
        assert!(!cam.needs_metering());
        // A darker, bluer view changes nothing while locked.
        assert_eq!(cam.update(metering(0.09, [0.1, 0.2, 0.4]), 0.5), first);
        assert_eq!(cam.current(), Some(first));
        cam.unlock();
        let after = cam.update(metering(0.09, [0.1, 0.2, 0.4]), 0.5);
        assert_eq!(after, CameraSettings { exposure: 2.0, white_balance: [2.0, 1.0, 0.5] });
        assert_eq!(first.gains(), [0.125, 0.25, 0.25]);
        assert_eq!(first.with_ev(2.0).exposure, 1.0);
        assert!(CameraSettings::exposure(0.0).validate().is_err());
    }
}
