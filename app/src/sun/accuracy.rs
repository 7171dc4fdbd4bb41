//! Accuracy against SPA and time per evaluation of every algorithm, measured in one run on one
//! machine: the data behind `previz sun chart` and `previz sun bench`.
//!
//! Error is the angle between the algorithm's geometric (unrefracted) sun direction and SPA's,
//! over random cases inside the algorithm's valid years: instants uniform in time, places
//! uniform over the sphere (latitude = asin(u)), sea level, ΔT from Espenak–Meeus. Refraction is
//! shared by all algorithms (see `atmosphere`), so it is left out of the comparison. Time per
//! evaluation covers the algorithm plus that shared refraction (what [`super::evaluate`] does).

use std::hint::black_box;
use std::time::Instant;

use rand::{Rng, SeedableRng, rngs::StdRng};

use super::horizon::{Horizontal, angular_separation_deg};
use super::{Algorithm, Site, atmosphere, delta_t, evaluate, julian, time};

/// One line of the chart: an algorithm, or the seed-002 formula as printed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    Algorithm(Algorithm),
    JulianAsPrinted,
}

impl Entry {
    /// Every chart entry.
    pub fn all() -> Vec<Entry> {
        let mut v: Vec<Entry> = Algorithm::ALL.iter().map(|a| Entry::Algorithm(*a)).collect();
        v.push(Entry::JulianAsPrinted);
        v
    }

    pub fn name(self) -> &'static str {
        match self {
            Entry::Algorithm(a) => a.name(),
            Entry::JulianAsPrinted => "julian-as-printed",
        }
    }

    pub fn valid_years(self) -> (i32, i32) {
        match self {
            Entry::Algorithm(a) => a.valid_years(),
            Entry::JulianAsPrinted => julian::VALID_YEARS,
        }
    }

    fn horizontal(self, case: &Case) -> Horizontal {
        match self {
            Entry::Algorithm(a) => a.horizontal(&case.site, case.jd, case.delta_t_s),
            Entry::JulianAsPrinted => julian::horizontal_as_printed(case.jd, case.site.latitude_deg, case.site.longitude_deg),
        }
    }

    fn evaluate_zenith(self, case: &Case) -> f64 {
        match self {
            Entry::Algorithm(a) => {
                evaluate(a, &case.site, case.jd, case.delta_t_s, STANDARD_PRESSURE, STANDARD_TEMPERATURE).apparent_zenith_deg
            }
            Entry::JulianAsPrinted => {
                let h = self.horizontal(case);
                90.0 - h.elevation_deg - atmosphere::refraction_deg(h.elevation_deg, STANDARD_PRESSURE, STANDARD_TEMPERATURE)
            }
        }
    }
}

const STANDARD_PRESSURE: f64 = 1013.25;
const STANDARD_TEMPERATURE: f64 = 15.0;

/// One random place and instant.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    pub site: Site,
    pub jd: f64,
    pub delta_t_s: f64,
}

/// `n` random cases in the years `first..=last` (whole years, UTC), reproducible from `seed`.
pub fn random_cases(n: usize, (first, last): (i32, i32), seed: u64) -> Vec<Case> {
    let jd_of_year = |y: i32| {
        let t = chrono::NaiveDate::from_ymd_opt(y, 1, 1).and_then(|d| d.and_hms_opt(0, 0, 0));
        t.map(|t| time::julian_day(&t.and_utc())).unwrap_or(f64::NAN)
    };
    let (start, end) = (jd_of_year(first), jd_of_year(last + 1));
    // An empty (or unrepresentable) year range gives no cases rather than a panic.
    if start.partial_cmp(&end) != Some(std::cmp::Ordering::Less) {
        return Vec::new();
    }
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let jd = rng.random_range(start..end);
            let site = Site {
                latitude_deg: rng.random_range(-1.0f64..=1.0).asin().to_degrees(),
                longitude_deg: rng.random_range(-180.0..=180.0),
                elevation_m: 0.0,
            };
            Case { site, jd, delta_t_s: delta_t::for_civil(&time::civil_from_julian_day(jd)) }
        })
        .collect()
}

/// Result for one chart entry.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    pub entry: Entry,
    pub cases: usize,
    /// Time of one evaluation, nanoseconds (lowest chunk mean, see [`ns_per_eval`]).
    pub ns_per_eval: f64,
    /// Maximum and root-mean-square angular error against SPA, degrees (0 for SPA itself).
    pub max_error_deg: f64,
    pub rms_error_deg: f64,
}

/// Evaluations per timed chunk in [`ns_per_eval`].
pub const TIMING_CHUNK: usize = 4096;

/// Time per evaluation in nanoseconds: the cases are timed in chunks of [`TIMING_CHUNK`], over
/// `passes` passes, and the lowest chunk mean is kept. On a shared machine a chunk that lost
/// the CPU to another process only reads slower, so the minimum is the undisturbed cost.
pub fn ns_per_eval(entry: Entry, cases: &[Case], passes: usize) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..passes.max(1) {
        for chunk in cases.chunks(TIMING_CHUNK) {
            let start = Instant::now();
            let mut sink = 0.0;
            for case in chunk {
                sink += entry.evaluate_zenith(black_box(case));
            }
            black_box(sink);
            best = best.min(start.elapsed().as_secs_f64() * 1e9 / chunk.len() as f64);
        }
    }
    best
}

/// Errors of `entry` against SPA over `cases`: (max, rms) in degrees. `tick` is called once
/// per case (progress bars).
pub fn errors_against_spa(entry: Entry, cases: &[Case], mut tick: impl FnMut()) -> (f64, f64) {
    let (mut max, mut sum_sq) = (0.0f64, 0.0f64);
    for case in cases {
        let a = entry.horizontal(case);
        let s = Algorithm::Spa.horizontal(&case.site, case.jd, case.delta_t_s);
        let e = angular_separation_deg(90.0 - a.elevation_deg, a.azimuth_deg, 90.0 - s.elevation_deg, s.azimuth_deg);
        max = max.max(e);
        sum_sq += e * e;
        tick();
    }
    (max, (sum_sq / cases.len().max(1) as f64).sqrt())
}

/// Measure one entry: `n` random cases in its valid years, errors against SPA, then timing.
pub fn measure(entry: Entry, n: usize, seed: u64, tick: impl FnMut()) -> Measurement {
    let cases = random_cases(n, entry.valid_years(), seed);
    let (max_error_deg, rms_error_deg) = errors_against_spa(entry, &cases, tick);
    Measurement { entry, cases: n, ns_per_eval: ns_per_eval(entry, &cases, 3), max_error_deg, rms_error_deg }
}

/// Measurements as CSV (header + one row per entry).
pub fn to_csv(ms: &[Measurement]) -> String {
    let mut s = String::from("algorithm,first_year,last_year,cases,ns_per_eval,max_error_deg,rms_error_deg\n");
    for m in ms {
        let (a, b) = m.entry.valid_years();
        s.push_str(&format!("{},{a},{b},{},{:.1},{:e},{:e}\n", m.entry.name(), m.cases, m.ns_per_eval, m.max_error_deg, m.rms_error_deg));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_stay_in_range_and_cover_the_sphere() {
        assert!(random_cases(10, (2000, 1999), 1).is_empty());
        let cases = random_cases(2000, (2010, 2110), 7);
        let (lo, hi) = (
            time::julian_day(&chrono::DateTime::parse_from_rfc3339("2010-01-01T00:00:00Z").unwrap().into()),
            time::julian_day(&chrono::DateTime::parse_from_rfc3339("2111-01-01T00:00:00Z").unwrap().into()),
        );
        assert!(cases.iter().all(|c| (lo..hi).contains(&c.jd)));
        // Uniform over the sphere: about half the cases within ±30° latitude (sin 30° = 0.5).
        let tropics = cases.iter().filter(|c| c.site.latitude_deg.abs() < 30.0).count();
        assert!((900..1100).contains(&tropics), "{tropics}");
        assert!(cases.iter().any(|c| c.site.longitude_deg < -170.0) && cases.iter().any(|c| c.site.longitude_deg > 170.0));
    }

    #[test]
    fn spa_has_zero_error_and_grena5_is_small() {
        let cases = random_cases(300, (2010, 2110), 1);
        assert_eq!(errors_against_spa(Entry::Algorithm(Algorithm::Spa), &cases, || {}), (0.0, 0.0));
        let (max, rms) = errors_against_spa(Entry::Algorithm(Algorithm::Grena5), &cases, || {});
        assert!(max < 0.0027 && rms <= max && rms > 0.0, "{max} {rms}");
        let csv =
            to_csv(&[Measurement { entry: Entry::JulianAsPrinted, cases: 3, ns_per_eval: 12.34, max_error_deg: 0.5, rms_error_deg: 0.25 }]);
        assert_eq!(csv.lines().nth(1), Some("julian-as-printed,1900,2100,3,12.3,5e-1,2.5e-1"));
    }
}
