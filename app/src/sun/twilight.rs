//! How much the sun still lights the scene around sunset: a smooth fade through civil twilight.
//!
//! The band is civil twilight as defined by the U.S. Naval Observatory and the Astronomical
//! Almanac: it ends when the centre of the sun is 6° below the horizon, the point at which
//! outdoor objects can no longer be told apart without artificial light. Above the horizon
//! (apparent elevation ≥ 0°) the factor is 1; at −6° and below it is 0; in between it follows
//! the C¹ smoothstep 3x² − 2x³, so neither the factor nor its rate of change jumps as the sun
//! sets (no visible pop in an animation). Below −0.83° SPA applies no refraction, so apparent
//! and geometric elevation agree at the lower end of the band.

/// Apparent elevation (degrees) where the fade starts and where it reaches zero.
pub const FADE_START_DEG: f64 = 0.0;
pub const CIVIL_TWILIGHT_END_DEG: f64 = -6.0;

/// 1 with the sun up, fading smoothly to 0 at the end of civil twilight. NaN gives 0 (no light
/// rather than a NaN that would poison every shaded pixel).
pub fn sunlight_factor(apparent_elevation_deg: f64) -> f32 {
    if apparent_elevation_deg.is_nan() {
        return 0.0;
    }
    let x = ((apparent_elevation_deg - CIVIL_TWILIGHT_END_DEG) / (FADE_START_DEG - CIVIL_TWILIGHT_END_DEG)).clamp(0.0, 1.0);
    (x * x * (3.0 - 2.0 * x)) as f32
}

/// [`sunlight_factor`] for a sun in direction `dir` (ENU, any non-zero length): its elevation is
/// the asin of the unit vector's up component. A zero or NaN direction gives 0.
pub fn sunlight_factor_toward(dir: glam::Vec3) -> f32 {
    sunlight_factor(f64::from(dir.normalize().z.clamp(-1.0, 1.0).asin().to_degrees()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factor_toward_a_direction_uses_its_elevation() {
        // 3° below the horizon, at any length: half-way through civil twilight (smoothstep(0.5)).
        let e = (-3f32).to_radians();
        let f = sunlight_factor_toward(glam::Vec3::new(0.0, 2.0 * e.cos(), 2.0 * e.sin()));
        assert!((f - 0.5).abs() < 1e-5, "{f}");
        assert_eq!(sunlight_factor_toward(glam::Vec3::Z), 1.0);
        assert_eq!(sunlight_factor_toward(glam::Vec3::ZERO), 0.0);
    }

    #[test]
    fn ends_of_the_band() {
        assert_eq!(sunlight_factor(45.0), 1.0);
        assert_eq!(sunlight_factor(0.0), 1.0);
        assert_eq!(sunlight_factor(-6.0), 0.0);
        assert_eq!(sunlight_factor(-30.0), 0.0);
        assert_eq!(sunlight_factor(-3.0), 0.5);
        assert_eq!(sunlight_factor(f64::NAN), 0.0);
        assert_eq!(sunlight_factor(f64::INFINITY), 1.0);
        assert_eq!(sunlight_factor(f64::NEG_INFINITY), 0.0);
    }

    #[test]
    fn monotonic_and_without_a_pop() {
        // Step 0.001° (the sun moves about that much in 0.25 s): the factor never drops by more
        // than the smoothstep's steepest slope (1.5/6 per degree) allows, and never rises.
        let step = 0.001;
        let mut prev = sunlight_factor(2.0);
        let mut e = 2.0;
        while e > -8.0 {
            e -= step;
            let f = sunlight_factor(e);
            assert!(f <= prev, "{e}");
            assert!(prev - f <= (1.5 / 6.0 * step) as f32 + 1e-6, "{e}: {prev} -> {f}");
            prev = f;
        }
        // The slope is zero at both ends of the band (C¹): tiny steps there change almost nothing.
        assert!(1.0 - sunlight_factor(-0.01) < 1e-5);
        assert!(sunlight_factor(-5.99) < 1e-5);
    }
}
