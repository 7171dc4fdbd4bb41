//! A capture on disk: a folder with the six faces as PNG (posx.png … negz.png, the capture
//! convention of [`super`]: +Z = front = reference heading), for an HDR capture also as float
//! OpenEXR (posx.exr … negz.exr: scene radiance, [`super::hdr`]), and `capture.json` with the
//! metadata (reference heading, poses, timestamps, location, time). See docs/capture.md.
//!
//! Saving never leaves a half-written capture: everything is written into a temporary sibling
//! folder that is renamed into place at the end (an existing capture at the destination is
//! replaced only then).

use super::Mode;
use super::assistant::AssistantConfig;
use super::reproject::{FaceImage, Shot};
use super::targets::{Face, Target};
use crate::output::{write_atomic, write_exr_f32, write_png_rgb8};
use crate::pose::HeadingSource;
use crate::pose::frames::heading_pitch_roll;
use crate::scene::CubeMap;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// Name of the metadata file in a capture folder.
pub const META_FILE: &str = "capture.json";
/// Value of the `format` field.
pub const FORMAT: &str = "previz-capture";

fn heading_source_name(s: Option<HeadingSource>) -> String {
    match s {
        Some(HeadingSource::Magnetometer) => "compass",
        Some(HeadingSource::GyroOnly) => "gyro-only",
        Some(HeadingSource::Sun) => "sun",
        Some(HeadingSource::Platform) => "platform",
        Some(HeadingSource::Unknown) | None => "unknown",
    }
    .to_string()
}

/// Where a capture was taken.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Location {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

/// The phone camera of the capture.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CameraMeta {
    pub width: u32,
    pub height: u32,
    pub vfov_deg: f32,
}

/// One face: which shot it is centred on and how much of it was observed.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FaceMeta {
    pub face: Face,
    pub file: String,
    /// Time (s, the sensors' clock) of the face's own shot.
    pub t: f64,
    /// Estimated camera pose (camera → ENU) of that shot, as w, x, y, z.
    pub pose_wxyz: [f64; 4],
    pub heading_deg: f64,
    pub pitch_deg: f64,
    pub roll_deg: f64,
    /// "compass", "sun", "gyro-only", "platform" or "unknown".
    pub heading_source: String,
    /// The pose filter's own 1σ accuracy estimate (degrees); null when not known.
    pub accuracy_deg: Option<f32>,
    /// Fraction of the face's pixels some shot actually observed.
    pub coverage: f32,
}

fn wxyz(q: glam::Quat) -> [f64; 4] {
    [q.w as f64, q.x as f64, q.y as f64, q.z as f64]
}

impl FaceMeta {
    pub fn new(face: Face, shot: &Shot, source: Option<HeadingSource>, accuracy_deg: f32, coverage: f32) -> Self {
        let hpr = heading_pitch_roll(shot.pose.as_dquat());
        FaceMeta {
            face,
            file: face.file_name().into(),
            t: shot.t,
            pose_wxyz: wxyz(shot.pose),
            heading_deg: hpr.heading.to_degrees(),
            pitch_deg: hpr.pitch.to_degrees(),
            roll_deg: hpr.roll.to_degrees(),
            heading_source: heading_source_name(source),
            accuracy_deg: accuracy_deg.is_finite().then_some(accuracy_deg),
            coverage,
        }
    }
}

/// Every shot taken (stretch mode: one per face; stitch mode: also the extra targets).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShotMeta {
    pub target: String,
    pub face: Face,
    pub t: f64,
    pub pose_wxyz: [f64; 4],
    pub heading_source: String,
    /// Turn about the vertical (degrees) the image alignment applied to the sensor pose
    /// (`pose_wxyz` is after it); null when the shots were not aligned.
    #[serde(default)]
    pub alignment_turn_deg: Option<f64>,
    /// The camera's exposure (multiplier on scene radiance) for this shot, when known.
    #[serde(default)]
    pub exposure: Option<f32>,
    /// The camera's white balance gains (R, G, B) for this shot, when known.
    #[serde(default)]
    pub white_balance: Option<[f32; 3]>,
    /// Gain (R, G, B) applied to this shot's light before blending, estimated from the
    /// overlaps ([`super::gain`]); null when not estimated.
    #[serde(default)]
    pub gain: Option<[f32; 3]>,
}

/// What the alignment from the images did ([`super::align`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AlignmentMeta {
    /// Overlapping shot pairs matched and used.
    pub pairs: usize,
    /// Pairs dropped as disagreeing with the joint solution.
    pub dropped_pairs: usize,
    /// The tilt (degrees) taken off the whole capture by the accelerometer held at the shots
    /// ([`super::gravity`]), and how many shots held it; null / 0 when too few did (the vertical
    /// is then the mean of the sensor tilts) and in folders written before it.
    #[serde(default)]
    pub vertical_correction_deg: Option<f64>,
    #[serde(default)]
    pub vertical_shots: usize,
}

impl ShotMeta {
    pub fn new(target: &Target, shot: &Shot, source: Option<HeadingSource>) -> Self {
        ShotMeta {
            target: target.name.clone(),
            face: target.face,
            t: shot.t,
            pose_wxyz: wxyz(shot.pose),
            heading_source: heading_source_name(source),
            alignment_turn_deg: None,
            exposure: None,
            white_balance: None,
            gain: None,
        }
    }
}

/// The contents of `capture.json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CaptureMeta {
    pub format: String,
    pub version: u32,
    pub mode: Mode,
    pub face_size: u32,
    /// Heading (degrees clockwise from true North) of the front face (+Z).
    pub reference_heading_deg: f64,
    pub tolerance_deg: f64,
    pub camera: CameraMeta,
    /// Exposure (multiplier on scene radiance) of the front shot, when known: the faces'
    /// exposure (the other shots are locked to it, or compensated to it).
    pub exposure: Option<f32>,
    /// White balance gains (R, G, B) of the front shot, when known (null in older folders).
    #[serde(default)]
    pub white_balance: Option<[f32; 3]>,
    /// Whether exposure and white balance were locked at the tap; null when not known.
    #[serde(default)]
    pub exposure_locked: Option<bool>,
    pub location: Option<Location>,
    /// When the capture was taken (RFC 3339, UTC), when known.
    pub time_utc: Option<String>,
    /// In cube-layer order (+X, −X, +Y, −Y, +Z, −Z).
    pub faces: Vec<FaceMeta>,
    pub shots: Vec<ShotMeta>,
    /// Stitch mode: the alignment of the shots from their overlaps; null when not aligned.
    #[serde(default)]
    pub alignment: Option<AlignmentMeta>,
    /// Where the reference heading comes from and its 1σ; null in folders written before it.
    #[serde(default)]
    pub heading: Option<HeadingMeta>,
    /// An HDR capture (exposure brackets merged): its float faces; null for 8-bit only.
    #[serde(default)]
    pub hdr: Option<HdrMeta>,
}

/// The float faces of an HDR capture ([`super::hdr`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HdrMeta {
    /// The bracket taken per view (stops relative to each shot's exposure).
    pub brackets_ev: Vec<f32>,
    /// Per channel (R, G, B): the radiance above which every bracket clipped (the sun's disc);
    /// such texels hold this value, a lower bound.
    pub clip_radiance: [f32; 3],
    /// The face files, cube-layer order (`posx.exr` … `negz.exr`): 32-bit float R, G, B in
    /// the environment's radiance units (the exposure and white balance divided out).
    pub files: Vec<String>,
}

/// The float face file of a face (`posx.exr` …).
pub fn hdr_file_name(face: Face) -> String {
    face.file_name().replace(".png", ".exr")
}

/// The reference heading's source ([`CubeCapture::calibrate_north_with_sun`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeadingMeta {
    /// "magnetometer", "sun" or "gyro-only" (the front shot's pose was gyro-only).
    pub source: String,
    /// 1σ of the reference heading (degrees): the front shot's filter estimate, or the sun
    /// measurement's.
    pub accuracy_deg: Option<f64>,
    /// The turn the sun calibration applied to the reference heading and every pose (degrees,
    /// clockwise); null when the sun was not used.
    pub sun_correction_deg: Option<f64>,
    /// Why the sun was or was not used, for people.
    pub note: String,
}

impl CaptureMeta {
    pub fn new(cfg: &AssistantConfig, reference_heading_deg: f64, faces: Vec<FaceMeta>, shots: Vec<ShotMeta>) -> Self {
        CaptureMeta {
            format: FORMAT.into(),
            version: 1,
            mode: cfg.mode,
            face_size: cfg.face_size,
            reference_heading_deg,
            tolerance_deg: cfg.tolerance_deg,
            camera: CameraMeta { width: cfg.camera.width, height: cfg.camera.height, vfov_deg: cfg.camera.vfov_deg() },
            exposure: None,
            white_balance: None,
            exposure_locked: None,
            location: None,
            time_utc: None,
            alignment: None,
            hdr: None,
            heading: Some(HeadingMeta {
                source: match faces.iter().find(|f| f.face == Face::Front).map(|f| f.heading_source.as_str()) {
                    Some("gyro-only") => "gyro-only",
                    _ => "magnetometer",
                }
                .into(),
                accuracy_deg: faces.iter().find(|f| f.face == Face::Front).and_then(|f| f.accuracy_deg).map(f64::from),
                sun_correction_deg: None,
                note: "sun not looked for".into(),
            }),
            faces,
            shots,
        }
    }

    pub fn face(&self, face: Face) -> Option<&FaceMeta> {
        self.faces.iter().find(|f| f.face == face)
    }
}

/// A complete capture: metadata and the six faces in cube-layer order.
#[derive(Clone, Debug, PartialEq)]
pub struct CubeCapture {
    pub meta: CaptureMeta,
    /// Index = cube layer (wgpu order +X, −X, +Y, −Y, +Z, −Z).
    pub faces: Vec<FaceImage>,
    /// An HDR capture's float faces (radiance, cube-layer order, `face_size`² texels each,
    /// top row first); None for an 8-bit capture.
    pub hdr: Option<Vec<Vec<[f32; 3]>>>,
}

impl CubeCapture {
    /// Check and order the faces (one per face, all the metadata's size).
    pub fn new(mut meta: CaptureMeta, faces: Vec<FaceImage>) -> Result<Self> {
        let mut ordered: Vec<Option<FaceImage>> = vec![None; 6];
        for f in faces {
            if f.size != meta.face_size || f.rgb.len() != (f.size * f.size * 3) as usize {
                bail!("face {} is {} px with {} bytes, expected {} px", f.face.name(), f.size, f.rgb.len(), meta.face_size);
            }
            let slot = &mut ordered[f.face.layer()];
            if slot.is_some() {
                bail!("face {} given twice", f.face.name());
            }
            *slot = Some(f);
        }
        let missing: Vec<&str> = Face::ALL.iter().filter(|f| ordered[f.layer()].is_none()).map(|f| f.name()).collect();
        if !missing.is_empty() {
            bail!("capture is missing face(s): {}", missing.join(", "));
        }
        meta.faces.sort_by_key(|f| f.face.layer());
        Ok(CubeCapture { meta, faces: ordered.into_iter().flatten().collect(), hdr: None })
    }

    /// Make it an HDR capture: six float faces (cube-layer order) and their metadata.
    pub fn set_hdr(&mut self, faces: Vec<Vec<[f32; 3]>>, brackets_ev: &[f32], clip_radiance: [f32; 3]) -> Result<()> {
        let n = (self.meta.face_size * self.meta.face_size) as usize;
        if faces.len() != 6 || faces.iter().any(|f| f.len() != n) {
            bail!("an HDR capture needs six float faces of {0}x{0} texels", self.meta.face_size);
        }
        if faces.iter().flatten().flatten().any(|v| !(v.is_finite() && *v >= 0.0)) {
            bail!("an HDR face holds a negative or non-finite radiance");
        }
        self.meta.hdr = Some(HdrMeta {
            brackets_ev: brackets_ev.to_vec(),
            clip_radiance,
            files: (0..6).filter_map(|layer| Face::ALL.iter().find(|f| f.layer() == layer)).map(|f| hdr_file_name(*f)).collect(),
        });
        self.hdr = Some(faces);
        Ok(())
    }

    pub fn face(&self, face: Face) -> &FaceImage {
        &self.faces[face.layer()]
    }

    /// True north from the sun: take the heading error measured on the shots' short-exposure
    /// frames (`from_frames`, [`crate::pose::sun_heading`]; the shots' poses place the faces), or
    /// else find the sun in the faces (works when they are not clipped around the sun) and
    /// compare its azimuth (through the reference heading) with `sun_enu` (SPA's direction for
    /// the capture's place and time; None when either is unknown); then turn the reference
    /// heading and every recorded pose by the measured error. The metadata's
    /// `heading` says what happened: source "sun" with the measurement's 1σ, or the magnetic
    /// heading kept and why. Returns the correction applied (degrees, clockwise).
    pub fn calibrate_north_with_sun(
        &mut self,
        sun_enu: Option<glam::Vec3>,
        from_frames: Option<crate::pose::sun_heading::HeadingMeasurement>,
    ) -> Option<f64> {
        use crate::pose::sun_heading::{heading_measurement, sight_sun_in_capture};
        let kept = self.meta.heading.clone().unwrap_or(HeadingMeta {
            source: "magnetometer".into(),
            accuracy_deg: None,
            sun_correction_deg: None,
            note: String::new(),
        });
        let keep = |meta: &mut CaptureMeta, note: &str| {
            meta.heading = Some(HeadingMeta { note: format!("{note}: magnetic heading kept"), sun_correction_deg: None, ..kept.clone() });
            None
        };
        let Some(sun) = sun_enu else { return keep(&mut self.meta, "no sun position (location or time unknown)") };
        if sun.z <= 0.0 {
            return keep(&mut self.meta, "the sun is below the horizon");
        }
        let (m, seen_in) = match from_frames {
            Some(m) => (m, "the shots' short-exposure frames"),
            None => {
                let clip = self.meta.hdr.as_ref().filter(|_| self.hdr.is_some()).map_or([1.0; 3], |h| h.clip_radiance);
                let Some(seen) = sight_sun_in_capture(&self.to_cube_map(), self.meta.reference_heading_deg.to_radians(), clip) else {
                    return keep(&mut self.meta, "no sun in the capture (clouds, or not in view)");
                };
                // The faces are levelled by the accelerometer: its 0.5° floor is the tilt 1σ.
                let Some(m) = heading_measurement(&seen, sun, 0.5f64.to_radians()) else {
                    return keep(&mut self.meta, "the brightest spot is not where the sun is");
                };
                (m, "the faces")
            }
        };
        let turn = -m.error.to_degrees();
        self.meta.reference_heading_deg = (self.meta.reference_heading_deg + turn).rem_euclid(360.0);
        let rot = glam::DQuat::from_rotation_z(m.error);
        let turned = |p: [f64; 4]| {
            let q = rot * glam::DQuat::from_xyzw(p[1], p[2], p[3], p[0]);
            [q.w, q.x, q.y, q.z]
        };
        for f in &mut self.meta.faces {
            f.pose_wxyz = turned(f.pose_wxyz);
            f.heading_deg = (f.heading_deg + turn).rem_euclid(360.0);
        }
        for s in &mut self.meta.shots {
            s.pose_wxyz = turned(s.pose_wxyz);
        }
        self.meta.heading = Some(HeadingMeta {
            source: "sun".into(),
            accuracy_deg: Some(m.sigma.to_degrees()),
            sun_correction_deg: Some(turn),
            note: format!(
                "sun seen in {seen_in} {:.2}° from SPA's azimuth (elevation {:+.2}°)",
                m.error.to_degrees(),
                m.elevation_difference.to_degrees()
            ),
        });
        Some(turn)
    }

    /// The faces as a cube map in linear light, in the capture's own frame: front = +Z: an HDR
    /// capture's float faces (radiance), else the 8-bit faces sRGB-decoded (the camera's tone
    /// curve is not undone). Render it with the reference heading as the map's heading
    /// ([`crate::render::Compositor::set_environment`]).
    pub fn to_cube_map(&self) -> CubeMap {
        if let Some(hdr) = &self.hdr {
            return CubeMap { size: self.meta.face_size, faces: std::array::from_fn(|layer| hdr[layer].clone()) };
        }
        let lut: [f32; 256] = std::array::from_fn(|i| crate::colour::srgb_to_linear(i as f32 / 255.0));
        let faces = std::array::from_fn(|layer| {
            self.faces[layer].rgb.chunks_exact(3).map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]]).collect()
        });
        CubeMap { size: self.meta.face_size, faces }
    }
}

fn sibling(path: &Path, tag: &str) -> Result<PathBuf> {
    let name = path.file_name().with_context(|| format!("{} is not a folder name", path.display()))?;
    Ok(path.with_file_name(format!(".{}.{tag}-{}", name.to_string_lossy(), std::process::id())))
}

/// Write a capture to `dir` (created; an existing capture folder there is replaced, any other
/// non-empty folder is refused). Nothing is left half-written on failure.
pub fn save_capture(capture: &CubeCapture, dir: &Path) -> Result<()> {
    if dir.exists() {
        let is_capture = dir.join(META_FILE).is_file();
        let empty = std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?.next().is_none();
        if !is_capture && !empty {
            bail!("{} exists and is not a capture folder; refusing to overwrite it", dir.display());
        }
    }
    let tmp = sibling(dir, "partial")?;
    let result = (|| -> Result<()> {
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).with_context(|| format!("cannot clear {}", tmp.display()))?;
        }
        std::fs::create_dir_all(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
        for f in &capture.faces {
            write_png_rgb8(&tmp.join(f.face.file_name()), f.size, f.size, &f.rgb)?;
        }
        if let Some(hdr) = &capture.hdr {
            let size = capture.meta.face_size;
            for face in Face::ALL {
                let texels = &hdr[face.layer()];
                let plane = |c: usize| texels.iter().map(|t| t[c]).collect::<Vec<f32>>();
                write_exr_f32(&tmp.join(hdr_file_name(face)), size, size, vec![("R", plane(0)), ("G", plane(1)), ("B", plane(2))])?;
            }
        }
        let json = serde_json::to_string_pretty(&capture.meta).context("cannot encode the capture metadata")?;
        write_atomic(&tmp.join(META_FILE), json.as_bytes())?;
        if dir.exists() {
            let old = sibling(dir, "old")?;
            std::fs::rename(dir, &old).with_context(|| format!("cannot move the old {} aside", dir.display()))?;
            std::fs::rename(&tmp, dir).with_context(|| format!("cannot move the capture into {}", dir.display()))?;
            let _ = std::fs::remove_dir_all(&old);
        } else {
            std::fs::rename(&tmp, dir).with_context(|| format!("cannot move the capture into {}", dir.display()))?;
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

/// A capture folder's metadata ([`META_FILE`]), parsed; errors name the file. [`load_capture`]
/// checks it further.
pub fn read_meta(dir: &Path) -> Result<CaptureMeta> {
    let meta_path = dir.join(META_FILE);
    let text = std::fs::read_to_string(&meta_path).with_context(|| format!("cannot read the capture metadata {}", meta_path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not valid capture metadata", meta_path.display()))
}

/// Read a capture folder written by [`save_capture`]. A missing or unreadable face, a face of
/// the wrong size or bad metadata is an error naming the file.
pub fn load_capture(dir: &Path) -> Result<CubeCapture> {
    let meta_path = dir.join(META_FILE);
    let meta = read_meta(dir)?;
    if meta.format != FORMAT {
        bail!("{}: format is {:?}, expected {FORMAT:?}", meta_path.display(), meta.format);
    }
    if !meta.reference_heading_deg.is_finite() {
        bail!("{}: reference heading is not a number", meta_path.display());
    }
    let missing: Vec<String> =
        Face::ALL.iter().filter(|f| !dir.join(f.file_name()).is_file()).map(|f| format!("{} ({})", f.file_name(), f.name())).collect();
    if !missing.is_empty() {
        bail!("capture folder {} is missing face(s): {}", dir.display(), missing.join(", "));
    }
    let mut faces = Vec::with_capacity(6);
    for face in Face::ALL {
        let path = dir.join(face.file_name());
        let img = crate::scene::decode::decode_file(&path, &[]).with_context(|| format!("capture face {}", face.name()))?.image.to_rgb8();
        if img.width() != meta.face_size || img.height() != meta.face_size {
            bail!("{} is {}x{}, the metadata says {} px faces", path.display(), img.width(), img.height(), meta.face_size);
        }
        let coverage = meta.face(face).map_or(f32::NAN, |m| m.coverage);
        faces.push(FaceImage { face, size: meta.face_size, rgb: img.into_raw(), coverage });
    }
    let hdr = match &meta.hdr {
        None => None,
        Some(_) => {
            let mut hdr = vec![Vec::new(); 6];
            for face in Face::ALL {
                let path = dir.join(hdr_file_name(face));
                let img = crate::scene::decode::decode_file(&path, &[])
                    .with_context(|| format!("HDR capture face {} ({})", face.name(), path.display()))?
                    .image
                    .to_rgb32f();
                if img.width() != meta.face_size || img.height() != meta.face_size {
                    bail!("{} is {}x{}, the metadata says {} px faces", path.display(), img.width(), img.height(), meta.face_size);
                }
                hdr[face.layer()] = img.pixels().map(|p| p.0).collect::<Vec<[f32; 3]>>();
            }
            Some(hdr)
        }
    };
    let mut capture = CubeCapture::new(meta, faces).with_context(|| format!("capture folder {}", dir.display()))?;
    capture.hdr = hdr;
    if let Some(h) = &capture.hdr
        && h.iter().flatten().flatten().any(|v| !(v.is_finite() && *v >= 0.0))
    {
        bail!("capture folder {}: an HDR face holds a negative or non-finite radiance", dir.display());
    }
    Ok(capture)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::projection::Pinhole;

    fn capture(size: u32) -> CubeCapture {
        let cfg = AssistantConfig { face_size: size, ..AssistantConfig::new(Mode::Stretch, Pinhole::from_vfov(64, 48, 50.0).unwrap()) };
        let mut meta = CaptureMeta::new(&cfg, 359.5, Vec::new(), Vec::new());
        meta.location = Some(Location { lat_deg: 51.45, lon_deg: -2.59, alt_m: 20.0 });
        let faces = Face::ALL
            .iter()
            .map(|&face| FaceImage { face, size, rgb: vec![face.layer() as u8 * 40; (size * size * 3) as usize], coverage: 1.0 })
            .collect();
        CubeCapture::new(meta, faces).unwrap()
    }

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("previz-capture-folder-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn round_trip_and_replace() {
        let dir = tmp("rt");
        let c = capture(16);
        save_capture(&c, &dir).unwrap();
        for f in Face::ALL {
            assert!(dir.join(f.file_name()).is_file());
        }
        let back = load_capture(&dir).unwrap();
        assert_eq!(back.meta.reference_heading_deg, 359.5);
        assert_eq!(back.meta.location, c.meta.location);
        // posz.png is the front (layer 4): its pixels carry the layer number.
        assert_eq!(back.face(Face::Front).rgb[0], 4 * 40);
        assert_eq!(back.faces.iter().map(|f| f.rgb.clone()).collect::<Vec<_>>(), c.faces.iter().map(|f| f.rgb.clone()).collect::<Vec<_>>());
        // Saving again over a capture replaces it, leaving no temporary folders behind.
        save_capture(&capture(32), &dir).unwrap();
        assert_eq!(load_capture(&dir).unwrap().meta.face_size, 32);
        let parent = dir.parent().unwrap();
        let leftovers = std::fs::read_dir(parent)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(&format!("previz-capture-folder-{}-rt.", std::process::id())))
            .count();
        assert_eq!(leftovers, 0);
        // The linear cube map decodes sRGB: 160 -> 0.3515 (IEC 61966-2-1).
        let cube = back.to_cube_map();
        assert!((cube.faces[4][0][0] - crate::colour::srgb_to_linear(160.0 / 255.0)).abs() < 1e-6);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_hdr_capture_round_trips_its_float_faces() {
        let dir = tmp("hdr");
        let mut c = capture(8);
        let faces: Vec<Vec<[f32; 3]>> = (0..6).map(|l| (0..64).map(|i| [l as f32 * 1000.0 + i as f32, 0.125, 3.5e4]).collect()).collect();
        c.set_hdr(faces.clone(), &[-4.0, 0.0, 4.0], [4e4, 5e4, 6e4]).unwrap();
        save_capture(&c, &dir).unwrap();
        assert!(dir.join("posz.exr").is_file() && dir.join("posz.png").is_file());
        let back = load_capture(&dir).unwrap();
        assert_eq!(back.hdr.as_ref().unwrap(), &faces, "32-bit floats round-trip exactly");
        assert_eq!(back.meta.hdr.as_ref().unwrap().clip_radiance, [4e4, 5e4, 6e4]);
        assert_eq!(back.meta.hdr.as_ref().unwrap().files, ["posx.exr", "negx.exr", "posy.exr", "negy.exr", "posz.exr", "negz.exr"]);
        // The cube map is the radiance (texel 9 of the front face: layer 4).
        assert_eq!(back.to_cube_map().faces[4][9], [4009.0, 0.125, 3.5e4]);
        // As an environment folder, the float faces win over the 8-bit previews.
        let env = crate::scene::environment::load_environment(&dir).unwrap();
        assert_eq!(env.faces[4][9], [4009.0, 0.125, 3.5e4]);
        // A missing float face is named.
        std::fs::remove_file(dir.join("negy.exr")).unwrap();
        let e = format!("{:#}", load_capture(&dir).unwrap_err());
        assert!(e.contains("negy.exr"), "{e}");
        assert!(c.clone().set_hdr(vec![vec![[1.0; 3]; 64]; 5], &[0.0], [1.0; 3]).is_err());
        assert!(c.set_hdr(vec![vec![[f32::NAN; 3]; 64]; 6], &[0.0], [1.0; 3]).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn missing_face_and_bad_folders_are_clear_errors() {
        let dir = tmp("missing");
        save_capture(&capture(16), &dir).unwrap();
        std::fs::remove_file(dir.join("negy.png")).unwrap();
        let e = format!("{:#}", load_capture(&dir).unwrap_err());
        assert!(e.contains("missing face(s): negy.png (down)"), "{e}");
        // Wrong size.
        image::save_buffer(dir.join("negy.png"), &[0u8; 8 * 8 * 3], 8, 8, image::ExtendedColorType::Rgb8).unwrap();
        assert!(format!("{:#}", load_capture(&dir).unwrap_err()).contains("negy.png is 8x8"));
        std::fs::write(dir.join(META_FILE), "{").unwrap();
        assert!(format!("{:#}", load_capture(&dir).unwrap_err()).contains("not valid capture metadata"));
        assert!(load_capture(&dir.join("nope")).unwrap_err().to_string().contains("capture.json"));
        // A folder with other files is not overwritten.
        let other = tmp("other");
        std::fs::create_dir_all(&other).unwrap();
        std::fs::write(other.join("notes.txt"), "keep").unwrap();
        assert!(save_capture(&capture(16), &other).unwrap_err().to_string().contains("refusing"));
        assert_eq!(std::fs::read_to_string(other.join("notes.txt")).unwrap(), "keep");
        std::fs::remove_dir_all(&dir).unwrap();
        std::fs::remove_dir_all(&other).unwrap();
    }
}
