//! Loading environments as cube maps in linear light: a folder of six face images, or one
//! equirectangular image (.hdr, .exr, or an 8-bit JPEG/PNG) resampled to a cube on the CPU.
//!
//! Conventions (see `docs/assets.md`):
//! - Face files: `posx`/`px` is cube face +X, and so on; with [`super::enu_to_cube`] that makes +X East,
//!   −X West, +Y up (sky), −Y down, +Z North, −Z South. Each face image is stored as the GPU
//!   samples it (see `scene::cubemap`), which is how Humus / three.js cube folders are stored.
//! - Equirectangular: the centre column looks North (true azimuth = `heading_deg`), azimuth
//!   grows to the right (u = 0.75 is East), the top row is the zenith, the bottom row the nadir.
//! - 8-bit images are sRGB-encoded and converted to linear; .hdr/.exr are linear already.
//!   NaN, infinite or absurd (> [`MAX_RADIANCE`]) values are an error naming the file and the
//!   first bad pixel (lighting cannot use them, and replacing them hides a broken file). Negative values, which lossy EXR
//!   compression (DWAA/DWAB) leaves around sharp edges, are set to 0: that repair is the only
//!   one, and it is documented in docs/robustness.md.

use super::{CubeMap, cube_to_enu};
use crate::colour::srgb_to_linear;
use anyhow::{Context, Result, anyhow, bail};
use glam::Vec3;
use image::DynamicImage;
use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

pub use super::cubemap::{cube_dir_to_face_uv, face_uv_to_cube_dir, texel_solid_angle};

/// How to turn an environment file into a cube map.
#[derive(Clone, Debug, Default)]
pub struct EnvOptions {
    /// Cube face size for equirectangular sources; default: a quarter of the image width
    /// rounded up to a power of two (1024×512 → 256), at most 2048. Face folders keep their
    /// own size.
    pub face_size: Option<u32>,
    /// True azimuth (degrees clockwise from North) that the source's front looks at: the
    /// equirect's centre column, or a face folder's +Z face. 0 = the source is North-aligned.
    pub heading_deg: f32,
}

/// Face file names: wgpu face order, long (three.js / Humus `posx`) and short (`px`) forms.
const FACE_STEMS: [[&str; 2]; 6] = [["posx", "px"], ["negx", "nx"], ["posy", "py"], ["negy", "ny"], ["posz", "pz"], ["negz", "nz"]];
const IMAGE_EXTS: [&str; 5] = ["jpg", "jpeg", "png", "hdr", "exr"];
const MAX_FACE_SIZE: u32 = 8192;

/// Load an environment (a folder of six faces, or an equirectangular .hdr/.exr/.jpg/.png).
pub fn load_environment(path: &Path) -> Result<CubeMap> {
    load_environment_with(path, &EnvOptions::default())
}

/// Load an environment with options (face size, heading).
pub fn load_environment_with(path: &Path, options: &EnvOptions) -> Result<CubeMap> {
    if !options.heading_deg.is_finite() {
        bail!("environment heading must be a finite number of degrees, got {}", options.heading_deg);
    }
    if let Some(s) = options.face_size
        && !(1..=MAX_FACE_SIZE).contains(&s)
    {
        bail!("cube face size must be 1..={MAX_FACE_SIZE}, got {s}");
    }
    let heading = options.heading_deg.to_radians();
    if path.is_dir() {
        let cube = load_face_folder(path)?;
        return Ok(if heading == 0.0 { cube } else { rotate_heading(&cube, heading) });
    }
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if !IMAGE_EXTS.contains(&ext.as_str()) {
        if !path.exists() {
            bail!("environment {} does not exist", path.display());
        }
        bail!("{}: unsupported environment (a folder of six faces, or an equirectangular .hdr, .exr, .jpg or .png)", path.display());
    }
    let equirect = load_equirect(path)?;
    Ok(equirect.to_cube(options.face_size.unwrap_or_else(|| equirect.default_face_size()), heading))
}

/// Load an environment as [`load_environment`] does, and keep an equirectangular source (None
/// for a face folder) for the background, which looks it up directly (render::passes::background):
/// the cube map is a second resampling that blurs what the camera sees of the map.
pub fn load_environment_and_equirect(path: &Path) -> Result<(CubeMap, Option<Equirect>)> {
    let image = |e: &std::ffi::OsStr| IMAGE_EXTS.contains(&e.to_string_lossy().to_ascii_lowercase().as_str());
    if path.is_dir() || !path.extension().is_some_and(image) {
        return Ok((load_environment(path)?, None));
    }
    let equirect = load_equirect(path)?;
    Ok((equirect.to_cube(equirect.default_face_size(), 0.0), Some(equirect)))
}

/// Load an equirectangular image (.hdr, .exr, .jpg, .png) in linear light, without resampling.
pub fn load_equirect(path: &Path) -> Result<Equirect> {
    let (width, height, pixels) = read_linear(path)?;
    Equirect::new(width, height, pixels).with_context(|| format!("{} is not an equirectangular image", path.display()))
}

/// Assemble a cube map from six decoded face images in wgpu order (+X, −X, +Y, −Y, +Z, −Z).
/// 8-bit faces are taken as sRGB and converted to linear; float faces as linear.
pub fn cube_from_faces(faces: [DynamicImage; 6]) -> Result<CubeMap> {
    let names = super::FACE_NAMES;
    let size = check_face_sizes(faces.iter().enumerate().map(|(i, f)| (format!("face {}", names[i]), f.width(), f.height())))?;
    Ok(CubeMap { size, faces: faces.map(|f| linear_rgb(&f)) })
}

/// Six faces from a folder, found by name (posx/negx/... or px/nx/..., any case, with a .jpg,
/// .jpeg, .png, .hdr or .exr extension). A face given once as float (.exr/.hdr) and also as
/// 8-bit images loads the float one (an HDR capture folder keeps 8-bit previews beside it).
fn load_face_folder(dir: &Path) -> Result<CubeMap> {
    let files = find_face_files(dir)?;
    // Decode the six faces in parallel; each error names its file.
    let decoded: Vec<Result<LinearImage>> = std::thread::scope(|s| {
        let handles: Vec<_> = files.iter().map(|f| s.spawn(move || read_linear(f))).collect();
        handles.into_iter().map(|h| h.join().unwrap_or_else(|_| Err(anyhow!("face decoder thread panicked")))).collect()
    });
    let mut faces = Vec::with_capacity(6);
    for d in decoded {
        faces.push(d?);
    }
    let size = check_face_sizes(files.iter().zip(&faces).map(|(f, (w, h, _))| (f.display().to_string(), *w, *h)))?;
    let mut it = faces.into_iter().map(|(_, _, p)| p);
    let faces = std::array::from_fn(|_| it.next().unwrap_or_default());
    Ok(CubeMap { size, faces })
}

/// The six face files of a folder in wgpu order; errors name what is missing or ambiguous.
fn find_face_files(dir: &Path) -> Result<[PathBuf; 6]> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("cannot read environment folder {}", dir.display()))?;
    let mut found: [Vec<PathBuf>; 6] = Default::default();
    for entry in entries {
        let path = entry.with_context(|| format!("cannot read environment folder {}", dir.display()))?.path();
        let (Some(stem), Some(ext)) = (path.file_stem(), path.extension()) else { continue };
        let (stem, ext) = (stem.to_string_lossy().to_ascii_lowercase(), ext.to_string_lossy().to_ascii_lowercase());
        if !IMAGE_EXTS.contains(&ext.as_str()) {
            continue;
        }
        if let Some(face) = FACE_STEMS.iter().position(|names| names.contains(&stem.as_str())) {
            found[face].push(path);
        }
    }
    let missing: Vec<String> = (0..6)
        .filter(|&f| found[f].is_empty())
        .map(|f| format!("{} ({} or {})", super::FACE_NAMES[f], FACE_STEMS[f][0], FACE_STEMS[f][1]))
        .collect();
    if !missing.is_empty() {
        bail!(
            "environment folder {} lacks face(s) {}; expected six images named posx/negx/posy/negy/posz/negz or px/nx/py/ny/pz/nz (.jpg, .png, .hdr or .exr)",
            dir.display(),
            missing.join(", ")
        );
    }
    for (f, files) in found.iter_mut().enumerate() {
        // One float face beside 8-bit ones (an HDR capture keeps 8-bit previews): the float one.
        let is_float = |p: &PathBuf| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("hdr"));
        if files.len() > 1 && files.iter().filter(|p| is_float(p)).count() == 1 {
            files.retain(is_float);
        }
        if files.len() > 1 {
            files.sort();
            let names: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
            bail!("environment folder {}: face {} is ambiguous: {}", dir.display(), super::FACE_NAMES[f], names.join(" and "));
        }
    }
    Ok(found.map(|mut v| v.remove(0)))
}

/// All faces square and of one size; returns the size. `faces` yields (name, width, height).
fn check_face_sizes(faces: impl Iterator<Item = (String, u32, u32)>) -> Result<u32> {
    let mut first: Option<(String, u32)> = None;
    for (name, w, h) in faces {
        if w != h {
            bail!("cube face {name} is {w}x{h}; faces must be square");
        }
        if w == 0 || w > MAX_FACE_SIZE {
            bail!("cube face {name} is {w}x{h}; the size must be 1..={MAX_FACE_SIZE}");
        }
        match &first {
            None => first = Some((name, w)),
            Some((first_name, size)) if *size != w => {
                bail!("cube face {name} is {w}x{h} but {first_name} is {size}x{size}; all six faces must be the same size")
            }
            Some(_) => {}
        }
    }
    first.map(|(_, s)| s).ok_or_else(|| anyhow!("no cube faces given"))
}

/// Width, height and linear RGB pixels of a decoded image.
type LinearImage = (u32, u32, Vec<[f32; 3]>);

/// Decode an image file to linear RGB: floats (.hdr, .exr) as they are, 8/16-bit as sRGB.
fn read_linear(path: &Path) -> Result<LinearImage> {
    let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    let image = match super::decode::decode_file(path, &[]) {
        Ok(decoded) => decoded.image,
        Err(e) if is_exr => return Err(exr_error(path, e)),
        Err(e) => return Err(e),
    };
    checked_linear(&image).with_context(|| path.display().to_string())
}

/// An equirectangular image held in memory (any format `scene::decode` reads), in linear
/// light, checked like a file.
pub fn equirect_from_bytes(bytes: &[u8]) -> Result<Equirect> {
    let image = super::decode::decode_bytes(bytes, &[])?.image;
    let (width, height, pixels) = checked_linear(&image)?;
    Equirect::new(width, height, pixels)
}

/// Linear RGB of a decoded image; NaN or infinite values are an error.
fn checked_linear(image: &DynamicImage) -> Result<LinearImage> {
    if let Some((count, x, y)) = non_finite(image) {
        bail!(
            "{count} pixel value(s) are NaN, infinite or above {MAX_RADIANCE:e} (the first at x={x}, y={y}); an environment must hold finite radiance"
        );
    }
    Ok((image.width(), image.height(), linear_rgb(image)))
}

/// The largest radiance an environment may hold: sums over a map (resampling, SH projection,
/// statistics over millions of texels) must stay finite in f32 (max 3.4e38).
pub const MAX_RADIANCE: f32 = 1e20;

/// How many channel values of a float image are NaN, infinite or above [`MAX_RADIANCE`], and
/// the first such pixel.
fn non_finite(image: &DynamicImage) -> Option<(usize, u32, u32)> {
    let (count, first) = match image {
        DynamicImage::ImageRgb32F(b) => count_bad(b.as_raw(), 3, b.width()),
        DynamicImage::ImageRgba32F(b) => count_bad(b.as_raw(), 4, b.width()),
        _ => (0, None),
    };
    first.map(|(x, y)| (count, x, y))
}

fn count_bad(values: &[f32], channels: usize, width: u32) -> (usize, Option<(u32, u32)>) {
    let mut first = None;
    let mut count = 0;
    for (i, v) in values.iter().enumerate() {
        if i % channels < 3 && !(v.is_finite() && *v <= MAX_RADIANCE) {
            count += 1;
            let p = (i / channels) as u32;
            first.get_or_insert((p % width, p / width));
        }
    }
    (count, first)
}

/// Explain an EXR read failure; DWA compression gets a specific hint.
fn exr_error(path: &Path, e: anyhow::Error) -> anyhow::Error {
    let compression = exr::meta::MetaData::read_from_file(path, false).ok().and_then(|m| m.headers.first().map(|h| h.compression));
    match compression {
        Some(c @ (exr::compression::Compression::DWAA(_) | exr::compression::Compression::DWAB(_))) => anyhow!(
            "cannot decode EXR {} ({e:#}); it is {c}-compressed: if the file is intact, re-save it with ZIP or PIZ \
             compression (e.g. `oiiotool in.exr --compression zip -o out.exr`)",
            path.display()
        ),
        _ => e,
    }
}

/// Clamp what lighting must not see: negative values (lossy compression leaves some) and
/// NaN/infinity become 0.
fn clean(v: f32) -> f32 {
    if v.is_finite() { v.max(0.0) } else { 0.0 }
}

/// Pixels of a decoded image as linear RGB, row-major, top row first.
fn linear_rgb(image: &DynamicImage) -> Vec<[f32; 3]> {
    match image {
        DynamicImage::ImageRgb32F(b) => b.pixels().map(|p| p.0.map(clean)).collect(),
        DynamicImage::ImageRgba32F(b) => b.pixels().map(|p| [clean(p.0[0]), clean(p.0[1]), clean(p.0[2])]).collect(),
        DynamicImage::ImageLuma8(_) | DynamicImage::ImageLumaA8(_) | DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) => {
            let lut: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0));
            image.to_rgb8().pixels().map(|p| p.0.map(|c| lut[c as usize])).collect()
        }
        _ => image.to_rgb32f().pixels().map(|p| p.0.map(|c| srgb_to_linear(c.clamp(0.0, 1.0)))).collect(),
    }
}

/// Rotate a cube map about the vertical so that its front (+Z) faces azimuth `heading` (rad).
fn rotate_heading(cube: &CubeMap, heading: f32) -> CubeMap {
    CubeMap::from_fn(cube.size, |d| cube.sample_enu(rotate_azimuth(d, -heading)))
}

/// Turn a direction about the up axis so its azimuth grows by `delta` radians (clockwise seen
/// from above): (x, y) → (x cos δ + y sin δ, y cos δ − x sin δ).
pub fn rotate_azimuth(d: Vec3, delta: f32) -> Vec3 {
    let (s, c) = delta.sin_cos();
    Vec3::new(d.x * c + d.y * s, d.y * c - d.x * s, d.z)
}

/// Equirectangular (u, v) in [0, 1] of an ENU direction, for an image whose centre column
/// faces true azimuth `heading` (radians): u = 0.5 + (azimuth − heading)/2π (wrapped),
/// v = 0.5 − elevation/π. Straight up/down give u = 0.5 − heading/2π (any u is right there).
pub fn enu_to_equirect_uv(d: Vec3, heading: f32) -> (f32, f32) {
    let azimuth = d.x.atan2(d.y);
    let elevation = d.z.atan2(d.x.hypot(d.y));
    ((0.5 + (azimuth - heading) / TAU).rem_euclid(1.0), 0.5 - elevation / PI)
}

/// Unit ENU direction of equirectangular coordinates (u, v): inverse of [`enu_to_equirect_uv`].
pub fn equirect_uv_to_enu(u: f32, v: f32, heading: f32) -> Vec3 {
    let azimuth = (u - 0.5) * TAU + heading;
    let elevation = (0.5 - v) * PI;
    let (se, ce) = elevation.sin_cos();
    let (sa, ca) = azimuth.sin_cos();
    Vec3::new(ce * sa, ce * ca, se)
}

/// An equirectangular image in linear RGB.
pub struct Equirect {
    width: u32,
    height: u32,
    pixels: Vec<[f32; 3]>,
}

impl Equirect {
    /// Wrap pixels (row-major, top row first); the image must be about 2:1.
    pub fn new(width: u32, height: u32, pixels: Vec<[f32; 3]>) -> Result<Equirect> {
        if width < 2 || height < 1 || pixels.len() != (width as usize) * (height as usize) {
            bail!("{width}x{height} with {} pixels is not a usable image", pixels.len());
        }
        // 2:1 within 1% (some exporters round the height).
        if (width as f32 / height as f32 - 2.0).abs() > 0.02 {
            bail!("{width}x{height} is not 2:1 as an equirectangular panorama must be");
        }
        Ok(Equirect { width, height, pixels })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// Linear RGB pixels, row-major, top row (zenith) first.
    pub fn pixels(&self) -> &[[f32; 3]] {
        &self.pixels
    }

    /// Radiance along an ENU direction (bilinear), for an image whose centre column faces
    /// azimuth `heading` (radians).
    pub fn sample_enu(&self, dir: Vec3, heading: f32) -> [f32; 3] {
        let (u, v) = enu_to_equirect_uv(dir, heading);
        self.sample_uv(u, v)
    }

    /// Bilinear sample at (u, v): wraps around horizontally, clamps at the poles.
    pub fn sample_uv(&self, u: f32, v: f32) -> [f32; 3] {
        let (w, h) = (self.width as usize, self.height as usize);
        if !(u.is_finite() && v.is_finite()) {
            return [0.0; 3];
        }
        let x = u * w as f32 - 0.5;
        let y = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        let xf = x.floor();
        let fx = x - xf;
        let x0 = (xf as i64).rem_euclid(w as i64) as usize;
        let x1 = (x0 + 1) % w;
        let y0 = y as usize;
        let y1 = (y0 + 1).min(h - 1);
        let fy = y - y0 as f32;
        let p = |x: usize, y: usize| self.pixels[y * w + x];
        let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
        std::array::from_fn(|i| {
            let top = a[i] + (b[i] - a[i]) * fx;
            let bottom = c[i] + (d[i] - c[i]) * fx;
            top + (bottom - top) * fy
        })
    }

    /// The cube face size an environment of this width gets by default: a quarter of the width
    /// rounded up to a power of two (1024×512 → 256), at most 2048.
    pub fn default_face_size(&self) -> u32 {
        (self.width / 4).max(1).next_power_of_two().min(2048)
    }

    /// Resample to a cube map of `size`×`size` faces. Each texel averages 2×2 bilinear samples
    /// spread over its area, so a small bright source (the sun) keeps its energy. The six
    /// faces are computed in parallel.
    pub fn to_cube(&self, size: u32, heading: f32) -> CubeMap {
        let face = |face: usize| {
            let mut texels = Vec::with_capacity((size * size) as usize);
            for y in 0..size {
                for x in 0..size {
                    let mut sum = [0.0f32; 3];
                    for (ox, oy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                        let (u, v) = ((x as f32 + ox) / size as f32, (y as f32 + oy) / size as f32);
                        let (eu, ev) = enu_to_equirect_uv(cube_to_enu(face_uv_to_cube_dir(face, u, v)), heading);
                        let s = self.sample_uv(eu, ev);
                        sum = std::array::from_fn(|i| sum[i] + s[i]);
                    }
                    texels.push(sum.map(|s| s * 0.25));
                }
            }
            texels
        };
        let mut faces: [Vec<[f32; 3]>; 6] = Default::default();
        std::thread::scope(|s| {
            for (i, slot) in faces.iter_mut().enumerate() {
                s.spawn(move || *slot = face(i));
            }
        });
        CubeMap { size, faces }
    }

    /// Solid angle (sr) of a pixel in row `y`: (2π/W)(sin φ_top − sin φ_bottom), φ = elevation.
    pub fn pixel_solid_angle(&self, y: u32) -> f32 {
        let el = |row: f32| (0.5 - row / self.height as f32) * PI;
        TAU / self.width as f32 * (el(y as f32).sin() - el(y as f32 + 1.0).sin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equirect_convention_by_hand() {
        // Centre column = North, u = 0.75 = East, u = 0.25 = West, u = 0 = South, top = zenith.
        let close = |a: (f32, f32), b: (f32, f32)| (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6;
        assert!(close(enu_to_equirect_uv(Vec3::Y, 0.0), (0.5, 0.5)));
        assert!(close(enu_to_equirect_uv(Vec3::X, 0.0), (0.75, 0.5)));
        assert!(close(enu_to_equirect_uv(-Vec3::X, 0.0), (0.25, 0.5)));
        assert!(close(enu_to_equirect_uv(-Vec3::Y, 0.0), (0.0, 0.5)));
        assert_eq!(enu_to_equirect_uv(Vec3::Z, 0.0).1, 0.0);
        assert_eq!(enu_to_equirect_uv(-Vec3::Z, 0.0).1, 1.0);
        // 30 deg above the horizon towards North-East (azimuth 45 deg): u = 0.5 + 45/360,
        // v = 0.5 − 30/180.
        let d = Vec3::new(30f32.to_radians().cos() * 45f32.to_radians().sin(), 30f32.to_radians().cos() * 45f32.to_radians().cos(), 0.5);
        assert!(close(enu_to_equirect_uv(d, 0.0), (0.625, 1.0 / 3.0)));
        // Heading 90 deg: the centre column looks East.
        assert!(close(enu_to_equirect_uv(Vec3::X, 90f32.to_radians()), (0.5, 0.5)));
        // Wrap: heading 10 deg puts North at u = 0.5 − 10/360.
        assert!(close(enu_to_equirect_uv(Vec3::Y, 10f32.to_radians()), (0.5 - 10.0 / 360.0, 0.5)));
        // No NaN from the poles or the zero vector.
        let (u, v) = enu_to_equirect_uv(Vec3::ZERO, 0.0);
        assert!(u.is_finite() && v.is_finite());
        // Round trip.
        for &(u, v) in &[(0.1, 0.2), (0.6, 0.9), (0.99, 0.5)] {
            let back = enu_to_equirect_uv(equirect_uv_to_enu(u, v, 0.7), 0.7);
            assert!(close(back, (u, v)), "{u},{v} -> {back:?}");
        }
    }

    #[test]
    fn rotate_azimuth_turns_clockwise() {
        // North turned by +90 deg (clockwise seen from above) is East.
        assert!((rotate_azimuth(Vec3::Y, 90f32.to_radians()) - Vec3::X).length() < 1e-6);
        assert!((rotate_azimuth(Vec3::X, 90f32.to_radians()) + Vec3::Y).length() < 1e-6);
        assert_eq!(rotate_azimuth(Vec3::Z, 1.0), Vec3::Z);
    }

    /// An equirect that is red in a 10 deg cap around `target`, dark grey elsewhere.
    fn spot_equirect(w: u32, target: Vec3) -> Equirect {
        let h = w / 2;
        let mut pixels = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let d = equirect_uv_to_enu((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32, 0.0);
                pixels.push(if d.dot(target) > 10f32.to_radians().cos() { [1.0, 0.0, 0.0] } else { [0.1, 0.1, 0.1] });
            }
        }
        Equirect::new(w, h, pixels).unwrap()
    }

    #[test]
    fn synthetic_equirect_lands_on_the_right_cube_directions() {
        for target in [Vec3::X, Vec3::Y, -Vec3::X, -Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::new(1.0, 1.0, 1.0).normalize()] {
            let cube = spot_equirect(256, target).to_cube(32, 0.0);
            assert!(cube.sample_enu(target)[0] > 0.95, "{target}");
            assert!(cube.sample_enu(-target)[0] < 0.15, "{target}");
            // Heading: with the panorama's front at azimuth 90 deg, what it shows at its North
            // is really East.
            let turned = spot_equirect(256, target).to_cube(32, 90f32.to_radians());
            assert!(turned.sample_enu(rotate_azimuth(target, 90f32.to_radians()))[0] > 0.95, "{target}");
        }
    }

    #[test]
    fn pixel_solid_angles_sum_to_four_pi() {
        let e = Equirect::new(64, 32, vec![[0.0; 3]; 64 * 32]).unwrap();
        let total: f32 = (0..32).map(|y| e.pixel_solid_angle(y) * 64.0).sum();
        assert!((total - 4.0 * PI).abs() < 1e-4);
    }

    #[test]
    fn equirect_must_be_two_to_one() {
        assert!(Equirect::new(100, 60, vec![[0.0; 3]; 6000]).is_err());
        assert!(Equirect::new(100, 50, vec![[0.0; 3]; 10]).is_err());
        assert!(Equirect::new(100, 50, vec![[0.0; 3]; 5000]).is_ok());
    }

    #[test]
    fn bad_values_are_cleaned() {
        assert_eq!([-0.004, f32::NAN, f32::INFINITY, 2.5].map(clean), [0.0, 0.0, 0.0, 2.5]);
    }

    #[test]
    fn faces_must_be_square_and_equal() {
        let img = |w, h| DynamicImage::ImageRgb8(image::RgbImage::new(w, h));
        let ok = cube_from_faces(std::array::from_fn(|_| img(4, 4))).unwrap();
        assert_eq!(ok.size, 4);
        let err = cube_from_faces(std::array::from_fn(|i| if i == 3 { img(4, 2) } else { img(4, 4) })).unwrap_err();
        assert!(err.to_string().contains("-Y") && err.to_string().contains("square"), "{err}");
        let err = cube_from_faces(std::array::from_fn(|i| if i == 5 { img(8, 8) } else { img(4, 4) })).unwrap_err();
        assert!(err.to_string().contains("-Z") && err.to_string().contains("same size"), "{err}");
        // 8-bit faces are sRGB: 128 -> 0.2158 linear (IEC 61966-2-1).
        let grey = DynamicImage::ImageRgb8(image::RgbImage::from_pixel(2, 2, image::Rgb([128, 128, 128])));
        let cube = cube_from_faces(std::array::from_fn(|_| grey.clone())).unwrap();
        assert!((cube.face_mean(0)[0] - 0.215_861).abs() < 1e-5);
    }
}
