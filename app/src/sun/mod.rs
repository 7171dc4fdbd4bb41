//! The sun: where it is in the sky for a place and an instant, as angles and as a unit vector
//! in the world (ENU) frame or a camera's frame.
//!
//! Conventions (DESIGN.md): world frame ENU (+x East, +y North, +z Up); azimuth φ clockwise from
//! true north, zenith θ from the vertical; direction to the sun s = (sinθ sinφ, sinθ cosφ, cosθ).
//! Angles are degrees in the public structs (they come from and go to the CLI and files) and
//! radians in [`direction_enu`]. See `docs/sun.md` for algorithms, ranges, poles and polar days.

use std::fmt;
use std::str::FromStr;

use anyhow::{Result, bail};
use chrono::{DateTime, Datelike, Utc};
use glam::{Quat, Vec3};

pub mod accuracy;
pub mod atmosphere;
pub mod chart;
pub mod delta_t;
pub mod exif;
pub mod grena;
pub mod horizon;
pub mod julian;
pub mod psa;
pub mod spa;
#[rustfmt::skip]
mod spa_tables;
pub mod time;
pub mod twilight;

pub use twilight::sunlight_factor;

/// A solar position algorithm. SPA is the reference and the default; the others are cheaper
/// and valid over shorter periods (see `docs/PERFORMANCE.md` for the accuracy/speed chart).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Algorithm {
    /// NREL SPA (Reda & Andreas 2004): ±0.0003°, years −2000..6000.
    #[default]
    Spa,
    /// Grena (2012) Algorithm 1–5, years 2010–2110.
    Grena1,
    Grena2,
    Grena3,
    Grena4,
    Grena5,
    /// PSA (Blanco-Muriel et al. 2001), years 1999–2015.
    Psa,
    /// PSA with the 2020 coefficients (Blanco et al. 2020), years 2020–2050.
    Psa2020,
    /// The day-of-year formula of seed 002 / Preetham et al. 1999 (corrected), years 1900–2100.
    Julian,
}

impl Algorithm {
    /// Every algorithm, SPA first.
    pub const ALL: [Algorithm; 9] = [
        Algorithm::Spa,
        Algorithm::Grena1,
        Algorithm::Grena2,
        Algorithm::Grena3,
        Algorithm::Grena4,
        Algorithm::Grena5,
        Algorithm::Psa,
        Algorithm::Psa2020,
        Algorithm::Julian,
    ];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Spa => "spa",
            Algorithm::Grena1 => "grena1",
            Algorithm::Grena2 => "grena2",
            Algorithm::Grena3 => "grena3",
            Algorithm::Grena4 => "grena4",
            Algorithm::Grena5 => "grena5",
            Algorithm::Psa => "psa",
            Algorithm::Psa2020 => "psa2020",
            Algorithm::Julian => "julian",
        }
    }

    /// First and last year (inclusive) the algorithm is specified for.
    pub fn valid_years(self) -> (i32, i32) {
        match self {
            Algorithm::Spa => spa::VALID_YEARS,
            Algorithm::Grena1 | Algorithm::Grena2 | Algorithm::Grena3 | Algorithm::Grena4 | Algorithm::Grena5 => grena::VALID_YEARS,
            Algorithm::Psa => psa::PSA_2001.valid_years,
            Algorithm::Psa2020 => psa::PSA_2020.valid_years,
            Algorithm::Julian => julian::VALID_YEARS,
        }
    }

    /// Topocentric geometric (unrefracted) elevation and azimuth. No validation: callers check
    /// ranges first ([`position`] does).
    pub fn horizontal(self, site: &Site, jd: f64, delta_t_s: f64) -> horizon::Horizontal {
        let (lat, lon) = (site.latitude_deg, site.longitude_deg);
        match self {
            Algorithm::Spa => spa::horizontal(jd, delta_t_s, lat, lon, site.elevation_m),
            Algorithm::Grena1 => grena::horizontal(1, jd, delta_t_s, lat, lon),
            Algorithm::Grena2 => grena::horizontal(2, jd, delta_t_s, lat, lon),
            Algorithm::Grena3 => grena::horizontal(3, jd, delta_t_s, lat, lon),
            Algorithm::Grena4 => grena::horizontal(4, jd, delta_t_s, lat, lon),
            Algorithm::Grena5 => grena::horizontal(5, jd, delta_t_s, lat, lon),
            Algorithm::Psa => psa::horizontal(&psa::PSA_2001, jd, lat, lon),
            Algorithm::Psa2020 => psa::horizontal(&psa::PSA_2020, jd, lat, lon),
            Algorithm::Julian => julian::horizontal(jd, lat, lon),
        }
    }
}

impl fmt::Display for Algorithm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algorithm {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Self> {
        let lower = s.trim().to_ascii_lowercase();
        match Algorithm::ALL.iter().find(|a| a.name() == lower) {
            Some(a) => Ok(*a),
            None => {
                let names: Vec<_> = Algorithm::ALL.iter().map(|a| a.name()).collect();
                bail!("unknown algorithm {s:?}; expected one of {}", names.join(", "))
            }
        }
    }
}

/// A place on the Earth: latitude (−90..90) and longitude (−180..180, east positive) in
/// degrees, elevation above sea level in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Site {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub elevation_m: f64,
}

/// What the position depends on. `None` fields take defaults: pressure and temperature of the
/// standard atmosphere at the elevation, ΔT from Espenak & Meeus for the date.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunInput {
    pub time: DateTime<Utc>,
    pub site: Site,
    pub pressure_mbar: Option<f64>,
    pub temperature_c: Option<f64>,
    pub delta_t_s: Option<f64>,
}

impl SunInput {
    /// Sea level, no weather data, ΔT from the date.
    pub fn new(time: DateTime<Utc>, latitude_deg: f64, longitude_deg: f64) -> Self {
        SunInput {
            time,
            site: Site { latitude_deg, longitude_deg, elevation_m: 0.0 },
            pressure_mbar: None,
            temperature_c: None,
            delta_t_s: None,
        }
    }
}

/// Where the sun is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunPosition {
    pub algorithm: Algorithm,
    /// Topocentric zenith angle without refraction, degrees.
    pub zenith_deg: f64,
    /// Zenith angle as seen through the atmosphere (refraction applied), degrees.
    pub apparent_zenith_deg: f64,
    /// Azimuth clockwise from true north, degrees in [0, 360). See `docs/sun.md` for the poles.
    pub azimuth_deg: f64,
    /// The conditions used (given or defaulted).
    pub pressure_mbar: f64,
    pub temperature_c: f64,
    pub delta_t_s: f64,
}

impl SunPosition {
    /// Apparent elevation above the horizon, degrees.
    pub fn apparent_elevation_deg(&self) -> f64 {
        90.0 - self.apparent_zenith_deg
    }

    /// Unit vector towards the sun as seen (apparent zenith) in the ENU world frame.
    pub fn direction_enu(&self) -> Vec3 {
        direction_enu(self.apparent_zenith_deg.to_radians(), self.azimuth_deg.to_radians())
    }

    /// How strongly the sun lights the scene (see [`twilight`]).
    pub fn sunlight_factor(&self) -> f32 {
        sunlight_factor(self.apparent_elevation_deg())
    }
}

/// Unit vector towards the sun in ENU for a zenith angle and an azimuth (clockwise from north),
/// both in radians: s = (sinθ sinφ, sinθ cosφ, cosθ).
pub fn direction_enu(zenith_rad: f64, azimuth_rad: f64) -> Vec3 {
    let [x, y, z] = horizon::unit(zenith_rad, azimuth_rad);
    Vec3::new(x as f32, y as f32, z as f32)
}

/// The ENU sun direction in the frame of a camera whose pose (a unit quaternion rotating camera
/// frame → world) is `pose`: `pose⁻¹ · s`. Camera frame: +x right, +y up, looking along −z.
pub fn direction_in_camera(pose: Quat, sun_enu: Vec3) -> Vec3 {
    pose.inverse() * sun_enu
}

/// Angle of incidence (degrees) of the sun on a surface tilted `slope_deg` from horizontal
/// whose downhill side faces `surface_azimuth_deg` (clockwise from north): SPA Eq. 47 with the
/// azimuth rotation measured from north instead of south.
pub fn incidence_deg(zenith_deg: f64, azimuth_deg: f64, slope_deg: f64, surface_azimuth_deg: f64) -> f64 {
    let (z, s) = (zenith_deg.to_radians(), slope_deg.to_radians());
    let cos_i = z.cos() * s.cos() + s.sin() * z.sin() * (azimuth_deg - surface_azimuth_deg).to_radians().cos();
    cos_i.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Ranges accepted for the weather inputs (physically plausible on the Earth's surface).
pub const PRESSURE_RANGE_MBAR: (f64, f64) = (1.0, 1200.0);
pub const TEMPERATURE_RANGE_C: (f64, f64) = (-100.0, 100.0);
/// |ΔT| limit in seconds: more than the Espenak–Meeus estimate reaches anywhere in −2000..6000.
pub const DELTA_T_LIMIT_S: f64 = 86_400.0;

fn check_range(value: f64, (lo, hi): (f64, f64), flag: &str, unit: &str) -> Result<()> {
    if value.is_nan() {
        bail!("{flag}: not a number (NaN)");
    }
    if !(lo..=hi).contains(&value) {
        bail!("{flag}: {value} {unit} is outside {lo}..{hi} {unit}");
    }
    Ok(())
}

/// Check a place; errors name the command-line flag.
pub fn check_site(site: &Site) -> Result<()> {
    check_range(site.latitude_deg, (-90.0, 90.0), "--lat", "deg")?;
    check_range(site.longitude_deg, (-180.0, 180.0), "--lon", "deg")?;
    check_range(site.elevation_m, atmosphere::ELEVATION_RANGE_M, "--elevation", "m")
}

/// Check that an instant lies in an algorithm's valid years.
pub fn check_time(time: &DateTime<Utc>, algorithm: Algorithm) -> Result<()> {
    let (first, last) = algorithm.valid_years();
    let year = time.year();
    if !(first..=last).contains(&year) {
        bail!(
            "--time: year {year} is outside {first}..{last}, the years algorithm {algorithm} is valid for{}",
            if algorithm == Algorithm::Spa { "" } else { " (spa covers -2000..6000)" }
        );
    }
    Ok(())
}

/// Sun position for an input with one algorithm. Validates every input (errors name the flag)
/// and fills the defaults.
pub fn position(input: &SunInput, algorithm: Algorithm) -> Result<SunPosition> {
    check_site(&input.site)?;
    check_time(&input.time, algorithm)?;
    let elevation = input.site.elevation_m;
    let pressure_mbar = input.pressure_mbar.unwrap_or_else(|| atmosphere::standard_pressure_mbar(elevation));
    let temperature_c = input.temperature_c.unwrap_or_else(|| atmosphere::standard_temperature_c(elevation));
    let jd = time::julian_day(&input.time);
    let delta_t_s = input.delta_t_s.unwrap_or_else(|| delta_t::for_civil(&time::civil_from_julian_day(jd)));
    check_range(pressure_mbar, PRESSURE_RANGE_MBAR, "--pressure", "mbar")?;
    check_range(temperature_c, TEMPERATURE_RANGE_C, "--temperature", "C")?;
    check_range(delta_t_s, (-DELTA_T_LIMIT_S, DELTA_T_LIMIT_S), "--delta-t", "s")?;
    Ok(evaluate(algorithm, &input.site, jd, delta_t_s, pressure_mbar, temperature_c))
}

/// The position without validation: one algorithm evaluation plus the shared refraction. This
/// is what the accuracy chart times.
pub fn evaluate(algorithm: Algorithm, site: &Site, jd: f64, delta_t_s: f64, pressure_mbar: f64, temperature_c: f64) -> SunPosition {
    let h = algorithm.horizontal(site, jd, delta_t_s);
    let refraction = atmosphere::refraction_deg(h.elevation_deg, pressure_mbar, temperature_c);
    SunPosition {
        algorithm,
        zenith_deg: 90.0 - h.elevation_deg,
        apparent_zenith_deg: 90.0 - h.elevation_deg - refraction,
        azimuth_deg: h.azimuth_deg,
        pressure_mbar,
        temperature_c,
        delta_t_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn golden() -> SunInput {
        let t = time::parse_time("2003-10-17T12:30:30-07:00", "t").unwrap().with_timezone(&Utc);
        SunInput {
            time: t,
            site: Site { latitude_deg: 39.742_476, longitude_deg: -105.1786, elevation_m: 1830.14 },
            pressure_mbar: Some(820.0),
            temperature_c: Some(11.0),
            delta_t_s: Some(67.0),
        }
    }

    #[test]
    fn published_test_case_through_the_public_api() {
        // NREL/TP-560-34302 Table A5.1: zenith 50.11162°, azimuth 194.34024°, incidence 25.18700°
        // for slope 30° and azimuth rotation −10° (from south) = 170° from north.
        let p = position(&golden(), Algorithm::Spa).unwrap();
        assert!((p.apparent_zenith_deg - 50.111_62).abs() < 5e-6, "{}", p.apparent_zenith_deg);
        assert!((p.azimuth_deg - 194.340_24).abs() < 5e-6, "{}", p.azimuth_deg);
        let inc = incidence_deg(p.apparent_zenith_deg, p.azimuth_deg, 30.0, 170.0);
        assert!((inc - 25.187).abs() < 5e-6, "{inc}");
    }

    #[test]
    fn direction_follows_the_convention() {
        use std::f64::consts::FRAC_PI_2;
        // Zenith → +z; on the horizon due east → +x; due north → +y; south-west at 45° elevation.
        assert!(direction_enu(0.0, 1.234).abs_diff_eq(Vec3::Z, 1e-7));
        assert!(direction_enu(FRAC_PI_2, FRAC_PI_2).abs_diff_eq(Vec3::X, 1e-7));
        assert!(direction_enu(FRAC_PI_2, 0.0).abs_diff_eq(Vec3::Y, 1e-7));
        let sw = direction_enu(45f64.to_radians(), 225f64.to_radians());
        assert!(sw.abs_diff_eq(Vec3::new(-0.5, -0.5, std::f32::consts::FRAC_1_SQRT_2), 1e-6));
        let p = position(&golden(), Algorithm::Spa).unwrap();
        assert!((p.direction_enu().length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn camera_space_direction() {
        // A camera looking north at the horizon: camera −z = world +y (north), camera +y = up.
        // Rotating camera→world by +90° about x maps −z to +y and +y to +z.
        let pose = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        assert!((pose * Vec3::NEG_Z).abs_diff_eq(Vec3::Y, 1e-6));
        // The sun due north on the horizon is straight ahead (−z in the camera frame); due east
        // it is to the right (+x); at the zenith it is up (+y).
        assert!(direction_in_camera(pose, Vec3::Y).abs_diff_eq(Vec3::NEG_Z, 1e-6));
        assert!(direction_in_camera(pose, Vec3::X).abs_diff_eq(Vec3::X, 1e-6));
        assert!(direction_in_camera(pose, Vec3::Z).abs_diff_eq(Vec3::Y, 1e-6));
    }

    #[test]
    fn defaults_come_from_the_standard_atmosphere_and_the_date() {
        let mut input = golden();
        input.pressure_mbar = None;
        input.temperature_c = None;
        input.delta_t_s = None;
        let p = position(&input, Algorithm::Spa).unwrap();
        assert!((p.pressure_mbar - atmosphere::standard_pressure_mbar(1830.14)).abs() < 1e-9);
        assert!((p.temperature_c - (15.0 - 6.5 * 1.830_14)).abs() < 0.01); // geopotential ≈ geometric
        assert!((p.delta_t_s - delta_t::espenak_meeus(2003, 10)).abs() < 1e-9);
        // Defaults move the answer only slightly from the published weather and ΔT.
        let q = position(&golden(), Algorithm::Spa).unwrap();
        assert!((p.apparent_zenith_deg - q.apparent_zenith_deg).abs() < 0.01);
    }

    type Breaker = fn(&mut SunInput);

    #[test]
    fn bad_input_names_the_flag() {
        let cases: [(Breaker, &str); 7] = [
            (|i| i.site.latitude_deg = 90.5, "--lat"),
            (|i| i.site.latitude_deg = f64::NAN, "--lat"),
            (|i| i.site.longitude_deg = -180.01, "--lon"),
            (|i| i.site.elevation_m = f64::NAN, "--elevation"),
            (|i| i.pressure_mbar = Some(0.0), "--pressure"),
            (|i| i.temperature_c = Some(f64::INFINITY), "--temperature"),
            (|i| i.delta_t_s = Some(f64::NAN), "--delta-t"),
        ];
        for (break_it, flag) in cases {
            let mut input = golden();
            break_it(&mut input);
            let e = position(&input, Algorithm::Spa).unwrap_err().to_string();
            assert!(e.starts_with(flag), "{e}");
        }
        // Years: 2003 is outside Grena's 2010–2110; 6001 is outside SPA's range.
        let e = position(&golden(), Algorithm::Grena3).unwrap_err().to_string();
        assert!(e.contains("--time") && e.contains("2010..2110"), "{e}");
        let mut far = golden();
        far.time = time::parse_time("6001-01-01T00:00:00Z", "t").unwrap().with_timezone(&Utc);
        assert!(position(&far, Algorithm::Spa).unwrap_err().to_string().contains("--time"));
        far.time = time::parse_time("-2001-12-31T23:59:59Z", "t").unwrap().with_timezone(&Utc);
        assert!(position(&far, Algorithm::Spa).is_err());
        far.time = time::parse_time("-2000-01-01T00:00:00Z", "t").unwrap().with_timezone(&Utc);
        assert!(position(&far, Algorithm::Spa).is_ok());
    }

    #[test]
    fn algorithm_names_round_trip() {
        for a in Algorithm::ALL {
            assert_eq!(a.name().parse::<Algorithm>().unwrap(), a);
        }
        assert!("nope".parse::<Algorithm>().unwrap_err().to_string().contains("spa"));
    }
}
