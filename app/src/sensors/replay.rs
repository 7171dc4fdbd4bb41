//! Replaying a recorded sensor trace.
//!
//! Format: CSV with the header `t,sensor,x,y,z,w,accuracy` (columns in any order), one reading
//! per line, times in seconds and never decreasing (readings of different sensors may share a
//! time). Cells a sensor does not use are left empty.
//!
//! | sensor | x | y | z | w | accuracy |
//! |---|---|---|---|---|---|
//! | `accel` | m/s² | m/s² | m/s² | | |
//! | `gyro` | rad/s | rad/s | rad/s | | |
//! | `mag` | µT | µT | µT | | |
//! | `gps` | latitude ° | longitude ° | altitude m | vertical accuracy m | horizontal accuracy m |
//! | `attitude_magnetic`, `attitude_true` | qx | qy | qz | qw | heading accuracy ° (optional) |
//!
//! Vectors are in the device frame (see [`crate::sensors`]); attitudes are device → ENU
//! quaternions referenced to magnetic or true north. NaN or infinite values, non-unit
//! quaternions, time going backwards, unknown sensors, missing columns and an empty file are
//! errors naming the file and line.

use super::csv::Table;
use super::{GpsFix, North, Reading, SensorSource};
use anyhow::{Context, Result, bail};
use glam::{DQuat, DVec3};
use std::fmt::Write as _;
use std::path::Path;

pub const SENSOR_TRACE_HEADER: &str = "t,sensor,x,y,z,w,accuracy";
const COLUMNS: [&str; 7] = ["t", "sensor", "x", "y", "z", "w", "accuracy"];

/// Load and check every reading of a sensor trace.
pub fn load_sensor_trace(path: &Path) -> Result<Vec<Reading>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_sensor_trace(path, &text)
}

/// Check every reading of a sensor trace given as text (`path` names it in errors).
pub fn parse_sensor_trace(path: &Path, text: &str) -> Result<Vec<Reading>> {
    let table = Table::parse(path, text, &COLUMNS)?;
    let mut out = Vec::with_capacity(table.len());
    let mut prev: Option<f64> = None;
    for rec in table.records() {
        let t = rec.number("t")?;
        if let Some(p) = prev
            && t < p
        {
            bail!("{}: time goes backwards ({t} after {p})", rec.at());
        }
        if let Some(p) = prev
            && t - p > crate::sensors::csv::MAX_TIME_GAP_S
        {
            bail!("{}: time jumps {} s ({p} to {t}); at most {} s between records", rec.at(), t - p, crate::sensors::csv::MAX_TIME_GAP_S);
        }
        prev = Some(t);
        let vec3 = || -> Result<DVec3> { Ok(DVec3::new(rec.number("x")?, rec.number("y")?, rec.number("z")?)) };
        let sensor = rec.text("sensor")?;
        let reading = match sensor {
            "accel" => Reading::Accel { t, v: vec3()? },
            "gyro" => Reading::Gyro { t, v: vec3()? },
            "mag" => Reading::Mag { t, v: vec3()? },
            "gps" => Reading::Gps(GpsFix {
                t,
                lat_deg: rec.number("x")?,
                lon_deg: rec.number("y")?,
                alt_m: rec.number("z")?,
                vertical_accuracy_m: rec.number("w")?,
                horizontal_accuracy_m: rec.number("accuracy")?,
            }),
            "attitude_magnetic" | "attitude_true" => {
                let v = vec3()?;
                let q = DQuat::from_xyzw(v.x, v.y, v.z, rec.number("w")?);
                let north = if sensor == "attitude_true" { North::True } else { North::Magnetic };
                let heading_accuracy_rad = rec.optional_number("accuracy")?.map(f64::to_radians);
                Reading::Attitude { t, q, north, heading_accuracy_rad }
            }
            other => bail!("{}: unknown sensor '{other}' (expected accel, gyro, mag, gps, attitude_magnetic or attitude_true)", rec.at()),
        };
        reading.validate().with_context(|| rec.at())?;
        let reading = match reading {
            Reading::Attitude { t, q, north, heading_accuracy_rad } => {
                Reading::Attitude { t, q: q.normalize(), north, heading_accuracy_rad }
            }
            r => r,
        };
        out.push(reading);
    }
    Ok(out)
}

/// Format readings as a sensor trace (the inverse of [`load_sensor_trace`]).
pub fn format_sensor_trace(readings: &[Reading]) -> String {
    let mut s = String::with_capacity(readings.len() * 64);
    s.push_str(SENSOR_TRACE_HEADER);
    s.push('\n');
    for r in readings {
        let name = r.sensor_name();
        let _ = match *r {
            Reading::Accel { t, v } | Reading::Gyro { t, v } | Reading::Mag { t, v } => writeln!(s, "{t},{name},{},{},{},,", v.x, v.y, v.z),
            Reading::Gps(f) => {
                writeln!(s, "{},{name},{},{},{},{},{}", f.t, f.lat_deg, f.lon_deg, f.alt_m, f.vertical_accuracy_m, f.horizontal_accuracy_m)
            }
            Reading::Attitude { t, q, heading_accuracy_rad, .. } => {
                let acc = heading_accuracy_rad.map(|a| a.to_degrees().to_string()).unwrap_or_default();
                writeln!(s, "{t},{name},{},{},{},{},{acc}", q.x, q.y, q.z, q.w)
            }
        };
    }
    s
}

/// Write readings as a sensor trace, atomically.
pub fn write_sensor_trace(path: &Path, readings: &[Reading]) -> Result<()> {
    crate::output::write_atomic(path, format_sensor_trace(readings).as_bytes())
}

/// A [`SensorSource`] replaying a loaded trace.
#[derive(Clone, Debug)]
pub struct ReplaySource {
    name: String,
    readings: Vec<Reading>,
    next: usize,
}

impl ReplaySource {
    pub fn open(path: &Path) -> Result<Self> {
        Ok(ReplaySource { name: path.display().to_string(), readings: load_sensor_trace(path)?, next: 0 })
    }

    /// Replay readings already in memory (they are validated and must be in time order).
    pub fn from_readings(name: &str, readings: Vec<Reading>) -> Result<Self> {
        for (i, r) in readings.iter().enumerate() {
            r.validate().with_context(|| format!("{name}: reading {i}"))?;
        }
        if readings.windows(2).any(|w| w[1].t() < w[0].t()) {
            bail!("{name}: readings are not in time order");
        }
        Ok(ReplaySource { name: name.to_string(), readings, next: 0 })
    }

    /// Time of the last reading.
    pub fn end(&self) -> f64 {
        self.readings.last().map_or(0.0, Reading::t)
    }
}

impl SensorSource for ReplaySource {
    fn poll(&mut self, until: f64, out: &mut Vec<Reading>) -> Result<()> {
        if until.is_nan() {
            bail!("replay {}: poll time is NaN", self.name);
        }
        let n = self.readings[self.next..].partition_point(|r| r.t() <= until);
        out.extend_from_slice(&self.readings[self.next..self.next + n]);
        self.next += n;
        Ok(())
    }

    fn describe(&self) -> String {
        format!("replay of {}", self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::from_heading_pitch_roll;
    use crate::pose::trace::{TruthSample, TruthTrace};
    use crate::sensors::sim::{NoiseLevel, SimSensors};

    fn tmp(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("previz-replay-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn sim_recording_replays_identically() {
        let truth = TruthTrace::new(
            (0..200)
                .map(|i| TruthSample { t: i as f64 * 0.01, q: from_heading_pitch_roll(i as f64 * 0.01, 0.2, 0.0), tap: false })
                .collect(),
        )
        .unwrap();
        let mut sim = SimSensors::new(truth, NoiseLevel::Phone, 9).unwrap();
        let mut recorded = Vec::new();
        sim.poll(f64::INFINITY, &mut recorded).unwrap();
        recorded.push(Reading::Attitude { t: 2.0, q: DQuat::from_rotation_z(0.3), north: North::True, heading_accuracy_rad: Some(0.05) });
        let p = tmp("rec.csv", &format_sensor_trace(&recorded));
        let mut replay = ReplaySource::open(&p).unwrap();
        let mut a = Vec::new();
        replay.poll(1.0, &mut a).unwrap();
        assert!(a.iter().all(|r| r.t() <= 1.0));
        replay.poll(f64::INFINITY, &mut a).unwrap();
        assert_eq!(a.len(), recorded.len());
        for (x, y) in a.iter().zip(&recorded) {
            match (x, y) {
                (Reading::Attitude { q: qa, heading_accuracy_rad: ha, .. }, Reading::Attitude { q: qb, heading_accuracy_rad: hb, .. }) => {
                    assert!((*qa - *qb).length() < 1e-15);
                    assert!((ha.unwrap() - hb.unwrap()).abs() < 1e-15);
                }
                _ => assert_eq!(x, y),
            }
        }
    }

    #[test]
    fn bad_sensor_traces_are_clear_errors() {
        let h = SENSOR_TRACE_HEADER;
        let cases = [
            ("empty.csv", String::new(), "empty file"),
            ("missing.csv", "t,sensor,x,y,z,w\n0,accel,0,0,9.8,\n".to_string(), "missing column(s) accuracy"),
            ("nan.csv", format!("{h}\n0,gyro,0,NaN,0,,\n"), "missing.csv:2"),
            ("back.csv", format!("{h}\n1,gyro,0,0,0,,\n0.5,gyro,0,0,0,,\n"), "backwards"),
            ("quat.csv", format!("{h}\n0,attitude_true,0.5,0.5,0.5,0.9,\n"), "not unit length"),
            ("unknown.csv", format!("{h}\n0,barometer,1,2,3,,\n"), "unknown sensor 'barometer'"),
            ("gps.csv", format!("{h}\n0,gps,95,0,0,15,10\n"), "off the globe"),
            ("cell.csv", format!("{h}\n0,mag,1,,3,,\n"), "column 'y' is empty"),
        ];
        for (name, text, expect) in cases {
            let p = tmp(name, &text);
            let e = format!("{:#}", load_sensor_trace(&p).unwrap_err());
            let expect = expect.replace("missing.csv", name);
            assert!(e.contains(&expect), "{name}: {e}");
            assert!(e.contains(name), "{name}: {e}");
        }
    }

    #[test]
    fn equal_times_are_allowed_across_sensors() {
        let p = tmp("same.csv", &format!("{SENSOR_TRACE_HEADER}\n0,accel,0,0,9.8,,\n0,gyro,0,0,0,,\n0,gps,51.4,-2.6,20,15,10\n"));
        let r = load_sensor_trace(&p).unwrap();
        assert_eq!(r.len(), 3);
        assert!(matches!(r[2], Reading::Gps(GpsFix { horizontal_accuracy_m: 10.0, vertical_accuracy_m: 15.0, .. })));
        assert!(
            ReplaySource::from_readings("mem", vec![Reading::Gyro { t: 1.0, v: DVec3::ZERO }, Reading::Gyro { t: 0.0, v: DVec3::ZERO }])
                .is_err()
        );
    }
}
