//! Where and when a photo was taken, from its EXIF tags (kamadak-exif), for `previz sun
//! --from-photo`.
//!
//! Which clock to trust: the GPS time stamp (GPSDateStamp + GPSTimeStamp) is UTC from the
//! satellites; the camera clock (DateTimeOriginal) is set by hand, drifts, is often in the wrong
//! zone, and before EXIF 2.31 carries no UTC offset. So the order is: GPS time; else
//! DateTimeOriginal with OffsetTimeOriginal; else DateTimeOriginal with an offset the user
//! supplies; else an error. When camera and GPS clocks disagree by more than any time-zone
//! offset can explain (UTC−12..UTC+14), a warning says so; the Nikon photos in
//! tests/data/photos/exif_gps/ (tags of the DSCN photos) differ by a day (camera 22 Oct, GPS 23 Oct 2008).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use anyhow::{Context, Result, bail};
use chrono::{DateTime, FixedOffset, NaiveDate, NaiveDateTime, TimeZone, Utc};
use exif::{Exif, In, Tag, Value};

/// What a photo says about its place and time.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotoInfo {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    /// GPS altitude above sea level, metres (negative below), if recorded.
    pub altitude_m: Option<f64>,
    /// GPSDateStamp + GPSTimeStamp (UTC), if both are recorded.
    pub gps_time: Option<DateTime<Utc>>,
    /// DateTimeOriginal (camera clock), without zone.
    pub camera_time: Option<NaiveDateTime>,
    /// OffsetTimeOriginal, if recorded.
    pub camera_offset: Option<FixedOffset>,
}

/// Which clock an instant came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeSource {
    Gps,
    CameraWithRecordedOffset,
    CameraWithGivenOffset,
}

impl TimeSource {
    pub fn describe(self) -> &'static str {
        match self {
            TimeSource::Gps => "GPS time stamp (UTC)",
            TimeSource::CameraWithRecordedOffset => "camera clock with its recorded UTC offset",
            TimeSource::CameraWithGivenOffset => "camera clock with the UTC offset given on the command line",
        }
    }
}

fn rationals(exif: &Exif, tag: Tag) -> Option<Vec<f64>> {
    match &exif.get_field(tag, In::PRIMARY)?.value {
        Value::Rational(v) => Some(v.iter().map(|r| r.to_f64()).collect()),
        _ => None,
    }
}

fn ascii(exif: &Exif, tag: Tag) -> Option<String> {
    match &exif.get_field(tag, In::PRIMARY)?.value {
        Value::Ascii(v) => v.first().map(|b| String::from_utf8_lossy(b).trim().to_string()),
        _ => None,
    }
}

/// Degrees from EXIF's (degrees, minutes, seconds) rationals and the N/S or E/W reference.
fn coordinate(exif: &Exif, value: Tag, reference: Tag, refs: [&str; 2], limit: f64) -> Result<f64> {
    let dms = rationals(exif, value).with_context(|| format!("no {value} tag"))?;
    let r = ascii(exif, reference).with_context(|| format!("no {reference} tag"))?;
    dms_to_degrees(&dms, &r, refs, limit).with_context(|| format!("{value} {dms:?} {reference} {r:?}"))
}

/// Signed degrees from (degrees, minutes, seconds) and a reference letter: `refs` is the
/// positive and the negative one (["N", "S"] or ["E", "W"], EXIF 2.32 GPSLatitudeRef /
/// GPSLongitudeRef). Minutes and seconds must be in 0..60, the result at most `limit` degrees;
/// any other reference is an error.
pub fn dms_to_degrees(dms: &[f64], reference: &str, refs: [&str; 2], limit: f64) -> Result<f64> {
    let [d, m, s] = dms[..] else {
        bail!("{} values, expected 3 (degrees, minutes, seconds)", dms.len());
    };
    if !(d.is_finite() && d >= 0.0) {
        bail!("degrees {d} must be a finite number ≥ 0");
    }
    for (name, v) in [("minutes", m), ("seconds", s)] {
        if !(v.is_finite() && (0.0..60.0).contains(&v)) {
            bail!("{name} {v} must be in 0..60");
        }
    }
    let magnitude = d + m / 60.0 + s / 3600.0;
    if magnitude > limit {
        bail!("{magnitude}° is beyond {limit}°");
    }
    if reference.eq_ignore_ascii_case(refs[0]) {
        Ok(magnitude)
    } else if reference.eq_ignore_ascii_case(refs[1]) {
        Ok(-magnitude)
    } else {
        bail!("reference {reference:?} is neither {} nor {}", refs[0], refs[1])
    }
}

fn gps_time(exif: &Exif) -> Result<Option<DateTime<Utc>>> {
    let (Some(date), Some(hms)) = (ascii(exif, Tag::GPSDateStamp), rationals(exif, Tag::GPSTimeStamp)) else {
        return Ok(None);
    };
    let day = NaiveDate::parse_from_str(&date, "%Y:%m:%d").with_context(|| format!("GPSDateStamp {date:?} is not YYYY:MM:DD"))?;
    let [h, m, s] = hms[..] else {
        bail!("GPSTimeStamp has {} values, expected 3", hms.len());
    };
    let seconds = h * 3600.0 + m * 60.0 + s;
    if !(0.0..86_401.0).contains(&seconds) {
        bail!("GPSTimeStamp {h}:{m}:{s} is not a time of day");
    }
    let midnight = Utc.from_utc_datetime(&day.and_time(chrono::NaiveTime::MIN));
    Ok(Some(midnight + chrono::Duration::microseconds((seconds * 1e6).round() as i64)))
}

fn camera_time(exif: &Exif) -> Result<(Option<NaiveDateTime>, Option<FixedOffset>)> {
    let Some(text) = ascii(exif, Tag::DateTimeOriginal) else {
        return Ok((None, None));
    };
    let t = NaiveDateTime::parse_from_str(&text, "%Y:%m:%d %H:%M:%S")
        .with_context(|| format!("DateTimeOriginal {text:?} is not YYYY:MM:DD HH:MM:SS"))?;
    let offset = match ascii(exif, Tag::OffsetTimeOriginal) {
        Some(o) => Some(parse_offset(&o).with_context(|| format!("OffsetTimeOriginal {o:?}"))?),
        None => None,
    };
    Ok((Some(t), offset))
}

/// A UTC offset written `+HH:MM` or `-HH:MM` (EXIF OffsetTime* and `--photo-utc-offset`).
pub fn parse_offset(text: &str) -> Result<FixedOffset> {
    let t = text.trim();
    let (sign, rest) = match t.as_bytes().first() {
        Some(b'+') => (1, &t[1..]),
        Some(b'-') => (-1, &t[1..]),
        _ => bail!("{t:?} is not a UTC offset like +02:00"),
    };
    let (h, m) = rest.split_once(':').with_context(|| format!("{t:?} is not a UTC offset like +02:00"))?;
    let (h, m): (i32, i32) = (h.parse()?, m.parse()?);
    if !(0..=14).contains(&h) || !(0..60).contains(&m) {
        bail!("{t:?} is outside UTC−14:00..UTC+14:00");
    }
    FixedOffset::east_opt(sign * (h * 3600 + m * 60)).with_context(|| format!("{t:?} is not a valid offset"))
}

impl PhotoInfo {
    /// Read the GPS position, altitude and times of a JPEG/TIFF/HEIF/PNG/WebP file.
    pub fn read(path: &Path) -> Result<PhotoInfo> {
        let file = File::open(path).with_context(|| format!("--from-photo: cannot open {}", path.display()))?;
        let exif = exif::Reader::new()
            .read_from_container(&mut BufReader::new(file))
            .with_context(|| format!("--from-photo: no readable EXIF data in {}", path.display()))?;
        let context = || format!("--from-photo: {} has no usable GPS position", path.display());
        let latitude_deg = coordinate(&exif, Tag::GPSLatitude, Tag::GPSLatitudeRef, ["N", "S"], 90.0).with_context(context)?;
        let longitude_deg = coordinate(&exif, Tag::GPSLongitude, Tag::GPSLongitudeRef, ["E", "W"], 180.0).with_context(context)?;
        let altitude_m = rationals(&exif, Tag::GPSAltitude).and_then(|v| v.first().copied()).map(|a| {
            let below = matches!(
                exif.get_field(Tag::GPSAltitudeRef, In::PRIMARY).map(|f| &f.value),
                Some(Value::Byte(b)) if b.first() == Some(&1)
            );
            if below { -a } else { a }
        });
        let gps_time = gps_time(&exif).with_context(|| format!("--from-photo: {}", path.display()))?;
        let (camera_time, camera_offset) = camera_time(&exif).with_context(|| format!("--from-photo: {}", path.display()))?;
        Ok(PhotoInfo { latitude_deg, longitude_deg, altitude_m, gps_time, camera_time, camera_offset })
    }

    /// The instant the photo was taken, the clock it came from, and a warning when the camera
    /// and GPS clocks disagree beyond any time zone. `given_offset` is the camera clock's UTC
    /// offset from the command line, used only when the photo records neither GPS time nor an
    /// offset.
    pub fn instant(&self, given_offset: Option<FixedOffset>) -> Result<(DateTime<Utc>, TimeSource, Option<String>)> {
        if let Some(gps) = self.gps_time {
            let warning = self.camera_time.and_then(|cam| {
                let hours = (cam - gps.naive_utc()).num_seconds() as f64 / 3600.0;
                let explained = match self.camera_offset {
                    Some(o) => (hours - f64::from(o.local_minus_utc()) / 3600.0).abs() < 0.5,
                    None => (-12.5..=14.5).contains(&hours),
                };
                (!explained).then(|| {
                    format!(
                        "camera clock {cam} and GPS time {gps} differ by {hours:.2} h, more than a \
                         time-zone offset explains; using the GPS time"
                    )
                })
            });
            return Ok((gps, TimeSource::Gps, warning));
        }
        let Some(cam) = self.camera_time else {
            bail!("--from-photo: the photo records no GPS time and no DateTimeOriginal; give --time");
        };
        let (offset, source) = match (self.camera_offset, given_offset) {
            (Some(o), _) => (o, TimeSource::CameraWithRecordedOffset),
            (None, Some(o)) => (o, TimeSource::CameraWithGivenOffset),
            (None, None) => bail!(
                "--from-photo: the photo has no GPS time and its camera clock ({cam}) has no UTC \
                 offset; give --photo-utc-offset (e.g. +01:00) or --time"
            ),
        };
        let local = offset.from_local_datetime(&cam).single().with_context(|| format!("--from-photo: camera time {cam} at {offset}"))?;
        Ok((local.with_timezone(&Utc), source, None))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degrees_minutes_seconds() {
        // 43° 28' 1.76" N = 43 + 28/60 + 1.76/3600 = 43.467156° (by hand).
        let lat = dms_to_degrees(&[43.0, 28.0, 1.76], "N", ["N", "S"], 90.0).unwrap();
        assert!((lat - 43.467_155_6).abs() < 1e-6, "{lat}");
        assert_eq!(dms_to_degrees(&[11.0, 30.0, 0.0], "w", ["E", "W"], 180.0).unwrap(), -11.5);
        for (dms, r, needle) in [
            (&[10.0, 75.0, 0.0][..], "N", "minutes 75"),
            (&[10.0, 5.0, 60.0][..], "N", "seconds 60"),
            (&[10.0, 5.0, 0.0][..], "X", "reference \"X\""),
            (&[91.0, 0.0, 0.0][..], "N", "beyond 90"),
            (&[-1.0, 0.0, 0.0][..], "S", "degrees -1"),
            (&[f64::NAN, 0.0, 0.0][..], "N", "degrees NaN"),
            (&[1.0, 2.0][..], "N", "2 values"),
        ] {
            let err = dms_to_degrees(dms, r, ["N", "S"], 90.0).unwrap_err().to_string();
            assert!(err.contains(needle), "{dms:?} {r}: {err}");
        }
    }

    #[test]
    fn offsets() {
        assert_eq!(parse_offset("+02:00").unwrap().local_minus_utc(), 7200);
        assert_eq!(parse_offset("-05:30").unwrap().local_minus_utc(), -19_800);
        for bad in ["02:00", "+2", "+15:00", "+01:60", ""] {
            assert!(parse_offset(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn clock_choice() {
        let gps = Utc.with_ymd_and_hms(2008, 10, 23, 14, 27, 7).unwrap();
        let cam = NaiveDate::from_ymd_opt(2008, 10, 22).unwrap().and_hms_opt(16, 28, 39).unwrap();
        let mut info = PhotoInfo {
            latitude_deg: 43.0,
            longitude_deg: 11.0,
            altitude_m: None,
            gps_time: Some(gps),
            camera_time: Some(cam),
            camera_offset: None,
        };
        let (t, src, warning) = info.instant(None).unwrap();
        assert_eq!((t, src), (gps, TimeSource::Gps));
        assert!(warning.unwrap().contains("-21.97 h"));
        // Same day: a 2 h difference is a time zone, no warning.
        info.camera_time = Some(cam + chrono::Duration::days(1));
        assert!(info.instant(None).unwrap().2.is_none());
        // No GPS time: the camera clock needs an offset.
        info.gps_time = None;
        assert!(info.instant(None).unwrap_err().to_string().contains("--photo-utc-offset"));
        let (t, src, _) = info.instant(Some(parse_offset("+02:00").unwrap())).unwrap();
        assert_eq!(src, TimeSource::CameraWithGivenOffset);
        assert_eq!(t, Utc.with_ymd_and_hms(2008, 10, 23, 14, 28, 39).unwrap());
        info.camera_offset = Some(parse_offset("+01:00").unwrap());
        assert_eq!(info.instant(None).unwrap().1, TimeSource::CameraWithRecordedOffset);
    }
}
