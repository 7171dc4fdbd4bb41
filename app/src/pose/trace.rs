//! Truth traces: the camera's true orientation over time, as the capture CLI replays it.
//!
//! File format (CSV, header required, columns in any order):
//!
//! | column | meaning |
//! |---|---|
//! | `t` | time in seconds, strictly increasing |
//! | `qw,qx,qy,qz` | unit quaternion, camera frame → ENU (camera looks along −z, image up +y) |
//! | `tap` | 1 on the row where the user taps the shutter, else 0 |
//!
//! NaN, a quaternion whose norm is off 1 by more than 1e-3, time going backwards, missing
//! columns and an empty file are errors naming the file and line. Accepted quaternions are
//! renormalised.

use crate::sensors::check_unit_quaternion;
use crate::sensors::csv::{Table, check_time_increases};
use anyhow::{Context, Result, bail};
use glam::DQuat;
use std::fmt::Write as _;
use std::path::Path;

/// One row of a truth trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthSample {
    pub t: f64,
    /// Camera → ENU, unit length.
    pub q: DQuat,
    pub tap: bool,
}

/// The header of a truth trace file.
pub const TRUTH_TRACE_HEADER: &str = "t,qw,qx,qy,qz,tap";

/// Load and check a truth trace (see the module documentation for the format).
pub fn load_truth_trace(path: &Path) -> Result<Vec<TruthSample>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_truth_trace(path, &text)
}

/// Check a truth trace given as text (`path` names it in errors).
pub fn parse_truth_trace(path: &Path, text: &str) -> Result<Vec<TruthSample>> {
    let table = Table::parse(path, text, &["t", "qw", "qx", "qy", "qz", "tap"])?;
    let mut out = Vec::with_capacity(table.len());
    let mut prev = None;
    for rec in table.records() {
        let t = rec.number("t")?;
        check_time_increases(&rec, prev, t)?;
        prev = Some(t);
        let q = DQuat::from_xyzw(rec.number("qx")?, rec.number("qy")?, rec.number("qz")?, rec.number("qw")?);
        check_unit_quaternion(q).map_err(|e| anyhow::anyhow!("{}: {e}", rec.at()))?;
        let tap = match rec.number("tap")? {
            0.0 => false,
            1.0 => true,
            v => bail!("{}: column 'tap' must be 0 or 1, got {v}", rec.at()),
        };
        out.push(TruthSample { t, q: q.normalize(), tap });
    }
    Ok(out)
}

/// Format a truth trace as CSV text (the inverse of [`load_truth_trace`]).
pub fn format_truth_trace(samples: &[TruthSample]) -> String {
    let mut s = String::with_capacity(samples.len() * 64);
    s.push_str(TRUTH_TRACE_HEADER);
    s.push('\n');
    for x in samples {
        // 17 significant digits keep f64 values exact through the round trip.
        let _ = writeln!(s, "{},{},{},{},{},{}", x.t, x.q.w, x.q.x, x.q.y, x.q.z, u8::from(x.tap));
    }
    s
}

/// Write a truth trace atomically.
pub fn write_truth_trace(path: &Path, samples: &[TruthSample]) -> Result<()> {
    crate::output::write_atomic(path, format_truth_trace(samples).as_bytes())
}

/// A truth trace with interpolation between its samples.
#[derive(Clone, Debug)]
pub struct TruthTrace {
    samples: Vec<TruthSample>,
}

impl TruthTrace {
    /// Wrap checked samples (as from [`load_truth_trace`]); there must be at least one and
    /// times must increase.
    pub fn new(samples: Vec<TruthSample>) -> Result<Self> {
        if samples.is_empty() {
            bail!("a truth trace needs at least one sample");
        }
        if samples.windows(2).any(|w| w[1].t <= w[0].t) {
            bail!("truth trace times must increase");
        }
        Ok(TruthTrace { samples })
    }

    pub fn samples(&self) -> &[TruthSample] {
        &self.samples
    }

    pub fn start(&self) -> f64 {
        self.samples[0].t
    }

    pub fn end(&self) -> f64 {
        self.samples[self.samples.len() - 1].t
    }

    /// Times of the rows with tap = 1.
    pub fn tap_times(&self) -> Vec<f64> {
        self.samples.iter().filter(|s| s.tap).map(|s| s.t).collect()
    }

    /// The orientation at time `t`: spherical interpolation between neighbouring samples,
    /// held constant before the first and after the last.
    pub fn orientation_at(&self, t: f64) -> DQuat {
        let s = &self.samples;
        let i = s.partition_point(|x| x.t <= t);
        if i == 0 {
            return s[0].q;
        }
        if i == s.len() {
            return s[s.len() - 1].q;
        }
        let (a, b) = (&s[i - 1], &s[i]);
        let u = (t - a.t) / (b.t - a.t);
        // Take the short way round whatever the signs stored in the file.
        let bq = if a.q.dot(b.q) < 0.0 { -b.q } else { b.q };
        a.q.slerp(bq, u).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::angle_between;

    fn tmp(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("previz-trace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn loads_a_good_trace_and_round_trips() {
        let p = tmp("good.csv", "t,qw,qx,qy,qz,tap\n0,1,0,0,0,0\n0.5,0.7071068,0.7071068,0,0,1\n");
        let s = load_truth_trace(&p).unwrap();
        assert_eq!(s.len(), 2);
        assert!(s[1].tap && !s[0].tap);
        assert!((s[1].q.length() - 1.0).abs() < 1e-15);
        let text = format_truth_trace(&s);
        let p2 = tmp("round.csv", &text);
        assert_eq!(load_truth_trace(&p2).unwrap(), s);
    }

    #[test]
    fn bad_traces_are_clear_errors() {
        let cases = [
            ("empty.csv", "", "empty file"),
            ("header.csv", "t,qw,qx,qy,qz,tap\n", "no records"),
            ("missing.csv", "t,qw,qx,qy,tap\n0,1,0,0,0\n", "missing column(s) qz"),
            ("nan.csv", "t,qw,qx,qy,qz,tap\n0,1,0,0,0,0\n1,NaN,0,0,0,0\n", "empty.csv:3"),
            ("nonunit.csv", "t,qw,qx,qy,qz,tap\n0,1,0,0,0,0\n1,1,1,0,0,0\n", "not unit length"),
            ("back.csv", "t,qw,qx,qy,qz,tap\n0,1,0,0,0,0\n1,1,0,0,0,0\n0.5,1,0,0,0,0\n", "backwards"),
            ("tap.csv", "t,qw,qx,qy,qz,tap\n0,1,0,0,0,2\n", "must be 0 or 1"),
        ];
        for (name, text, expect) in cases {
            let p = tmp(name, text);
            let e = format!("{:#}", load_truth_trace(&p).unwrap_err());
            let expect = expect.replace("empty.csv", name);
            assert!(e.contains(&expect), "{name}: {e}");
            assert!(e.contains(name), "{name}: error does not name the file: {e}");
        }
        let e = format!("{:#}", load_truth_trace(Path::new("/nonexistent/trace.csv")).unwrap_err());
        assert!(e.contains("/nonexistent/trace.csv"), "{e}");
    }

    #[test]
    fn interpolation_is_slerp_and_short_way() {
        let a = DQuat::IDENTITY;
        let b = DQuat::from_rotation_z(1.0);
        let tr = TruthTrace::new(vec![
            TruthSample { t: 0.0, q: a, tap: false },
            // Stored with the opposite sign: same rotation.
            TruthSample { t: 1.0, q: -b, tap: true },
        ])
        .unwrap();
        assert!(angle_between(tr.orientation_at(0.25), DQuat::from_rotation_z(0.25)) < 1e-12);
        assert!(angle_between(tr.orientation_at(-5.0), a) < 1e-12);
        assert!(angle_between(tr.orientation_at(5.0), b) < 1e-12);
        assert_eq!(tr.tap_times(), vec![1.0]);
        assert!(TruthTrace::new(vec![]).is_err());
    }
}
