//! The virtual phone and the file frame source against real environments and photos.

use crate::common;

use common::data;
use glam::{Mat3, Quat, Vec3};
use previz::camera::FrameSource;
use previz::camera::exposure::{ExposureMode, tone_to_srgb8};
use previz::camera::file::ImageFiles;
use previz::camera::sim::{SimSettings, VirtualPhone};
use previz::scene::environment::load_environment;
use std::sync::Arc;

/// Camera → ENU rotation from the image's right and up directions (the camera looks along
/// right × up).
fn pose(right: Vec3, up: Vec3) -> Quat {
    Quat::from_mat3(&Mat3::from_cols(right, up, right.cross(up)))
}

#[test]
fn a_90_degree_square_view_reproduces_each_cube_face() {
    // Looking at the centre of each face with a 90° square view puts the pixel centres exactly
    // on the face's texel centres, so the frame is the face itself, exposed and tone-mapped.
    // The image right/up per face follow the Vulkan face table (scene::cubemap) through
    // enu_to_cube: e.g. +X (East) has −z_cube (South) to the right and +y_cube (up) up.
    let cube = Arc::new(load_environment(&data("cubemaps/humus_Park2_512")).unwrap());
    let (e, s, u) = (Vec3::X, Vec3::Y, Vec3::Z); // East, North, Up
    let views = [(-s, u), (s, u), (e, -s), (e, s), (e, u), (-e, u)];
    let exposure = 0.6;
    let settings = SimSettings { width: 512, height: 512, vfov_deg: 90.0, exposure: ExposureMode::Fixed(exposure) };
    let phone = VirtualPhone::new(cube.clone(), &settings).unwrap();
    for (face, (right, up)) in views.into_iter().enumerate() {
        let img = phone.render_with_exposure(pose(right, up), exposure).unwrap();
        let mut worst = 0;
        for (i, texel) in cube.faces[face].iter().enumerate() {
            for (c, value) in texel.iter().enumerate() {
                let want = tone_to_srgb8(value * exposure) as i32;
                worst = worst.max((img.pixels[i * 4 + c] as i32 - want).abs());
            }
        }
        assert!(worst <= 1, "face {face}: off by {worst} code values");
    }
}

#[test]
fn auto_exposed_outdoor_view_is_well_exposed() {
    let cube = Arc::new(load_environment(&data("cubemaps/humus_Bridge2")).unwrap());
    let mut phone = VirtualPhone::new(cube, &SimSettings { width: 160, height: 120, ..Default::default() }).unwrap();
    // Level, looking North-East.
    let q = Quat::from_rotation_z(-45f32.to_radians()) * Quat::from_rotation_x(90f32.to_radians());
    let frame = phone.render(q, 0.0).unwrap();
    let n = (frame.image.pixels.len() / 4) as f32;
    let mean = frame.image.pixels.chunks(4).map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0).sum::<f32>() / n;
    assert!((70.0..190.0).contains(&mean), "mean sRGB code {mean}");
    let clipped = frame.image.pixels.chunks(4).filter(|p| p[..3].iter().all(|c| *c == 255)).count() as f32 / n;
    assert!(clipped < 0.2, "{clipped} of the frame is white");
}

#[test]
fn photo_folder_as_a_sequence() {
    // Natural order puts 87_OSError.jpg (1488x2240) first; the 160x120 arezzo_*.jpg photos that
    // follow do not match its size, which is reported with the file's name.
    let mut seq = ImageFiles::open(&data("photos/exif_gps"), 30.0).unwrap();
    assert_eq!(seq.len(), 10);
    let first = seq.next_frame().unwrap().unwrap();
    assert_eq!((first.image.width, first.image.height), (1488, 2240));
    let err = seq.next_frame().unwrap_err().to_string();
    assert!(err.contains("arezzo_0010.jpg") && err.contains("1488x2240"), "{err}");
}

/// Frames per second of the virtual phone at 960x640, with the alternatives side by side.
/// Not a check (no timed assertions); run with
/// `cargo test --release --test integration camera:: -- --ignored --nocapture bench_virtual_phone`.
#[test]
#[ignore]
fn bench_virtual_phone() {
    use previz::scene::environment::load_equirect;
    use std::time::Instant;
    let path = data("hdri/polyhaven_1k/quarry_01_1k.hdr");
    let cube = Arc::new(load_environment(&path).unwrap());
    let equirect = load_equirect(&path).unwrap();
    let settings = SimSettings { width: 960, height: 640, vfov_deg: 50.0, exposure: ExposureMode::default() };
    let mut phone = VirtualPhone::new(cube.clone(), &settings).unwrap();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let poses: Vec<Quat> = (0..60).map(|i| Quat::from_rotation_z(i as f32 * 0.1) * Quat::from_rotation_x(1.3)).collect();
    // Wall time and this process's CPU time (user + system, /proc/self/stat, USER_HZ = 100):
    // on a shared machine the CPU time of a one-thread variant is the steadier number.
    let cpu_seconds = || {
        let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
        let after = stat.rsplit(')').next().unwrap_or_default();
        let f: Vec<f64> = after.split_whitespace().map(|x| x.parse().unwrap_or(0.0)).collect();
        (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) / 100.0
    };
    let time = |f: &mut dyn FnMut(Quat)| {
        f(poses[0]); // warm-up
        let (t0, c0) = (Instant::now(), cpu_seconds());
        for q in &poses {
            f(*q);
        }
        let n = poses.len() as f64;
        (t0.elapsed().as_secs_f64() / n, (cpu_seconds() - c0) / n)
    };
    let mut t = 0.0;
    let mut rows = Vec::new();
    phone.set_threads(cores);
    rows.push((
        format!("render (meter + adapt + draw), {cores} threads"),
        time(&mut |q| {
            t += 1.0 / 30.0;
            phone.render(q, t).unwrap();
        }),
    ));
    phone.set_threads(1);
    rows.push((
        "render (meter + adapt + draw), 1 thread".to_string(),
        time(&mut |q| {
            t += 1.0 / 30.0;
            phone.render(q, t).unwrap();
        }),
    ));
    rows.push((
        "draw only at fixed exposure, 1 thread".to_string(),
        time(&mut |q| {
            phone.render_with_exposure(q, 1.0).unwrap();
        }),
    ));
    // Alternative: the exact tone curve (powf per channel) instead of the lookup table.
    let (w, h) = (960usize, 640usize);
    let tan_v = (25f32).to_radians().tan();
    let tan_h = tan_v * 1.5;
    let mut out = vec![0u8; w * h * 4];
    let mut naive = |q: Quat, sample: &dyn Fn(Vec3) -> [f32; 3]| {
        let r = Mat3::from_quat(q);
        for y in 0..h {
            let ny = (1.0 - 2.0 * (y as f32 + 0.5) / h as f32) * tan_v;
            for x in 0..w {
                let nx = (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * tan_h;
                let c = sample(r.x_axis * nx + r.y_axis * ny - r.z_axis);
                let px = &mut out[(y * w + x) * 4..][..4];
                px.copy_from_slice(&[tone_to_srgb8(c[0]), tone_to_srgb8(c[1]), tone_to_srgb8(c[2]), 255]);
            }
        }
    };
    rows.push(("draw, exact tone curve instead of LUT, 1 thread".to_string(), time(&mut |q| naive(q, &|d| cube.sample_enu(d)))));
    rows.push((
        "draw, exact tone curve, sampling the equirect instead of the cube, 1 thread".to_string(),
        time(&mut |q| naive(q, &|d| equirect.sample_enu(d, 0.0))),
    ));
    let base = rows[1].1.1;
    println!(
        "| variant (960x640, quarry_01_1k.hdr, 256 px faces, 60 frames) | wall ms/frame | frames/s (wall) | CPU ms/frame | CPU time vs 1-thread render |"
    );
    println!("|---|---|---|---|---|");
    for (name, (wall, cpu)) in rows {
        println!("| {name} | {:.1} | {:.1} | {:.1} | {:.2} |", wall * 1e3, 1.0 / wall, cpu * 1e3, cpu / base);
    }
}

/// A phone camera double: YUV frames (the planes of a photo, padded rows) lent through
/// `lend_next_frame` with a turn, as `camera::android::Camera2` lends its images.
struct YuvCamera {
    yuv: previz::camera::yuv::OwnedYuv,
    quarter_turns: u32,
    k: u32,
}

impl FrameSource for YuvCamera {
    fn next_frame(&mut self) -> anyhow::Result<Option<previz::camera::Frame>> {
        anyhow::bail!("the live session must take the YUV planes, not a CPU image")
    }

    fn lend_next_frame(&mut self, sink: &mut previz::camera::FrameSink<'_>) -> anyhow::Result<bool> {
        self.k += 1;
        sink(f64::from(self.k) / 30.0, previz::camera::FrameImage::Yuv { frame: self.yuv.frame(), quarter_turns: self.quarter_turns })?;
        Ok(true)
    }
}

struct NoSensors;

impl previz::sensors::SensorSource for NoSensors {
    fn poll(&mut self, _until: f64, _out: &mut Vec<previz::sensors::Reading>) -> anyhow::Result<()> {
        Ok(())
    }

    fn describe(&self) -> String {
        "none".into()
    }
}

fn live_session_on(camera: YuvCamera, (width, height): (u32, u32)) -> anyhow::Result<previz::live::LiveSession> {
    use previz::live::{LiveConfig, LiveSession, Sources};
    let s = common::scene(&format!("width = {width}\nheight = {height}\n"));
    let env = previz::scene::CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) };
    let sources = Sources { camera: Box::new(camera), sensors: Box::new(NoSensors), rotation: Default::default(), truth: None };
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T12:00:00Z").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 30.0,
        duration_s: 60.0,
        noise: previz::sensors::sim::NoiseLevel::Phone,
        seed: 1,
    };
    LiveSession::new(common::gpu(), &env, &common::triangle(), &s, cfg, sources)
}

#[test]
fn a_yuv_camera_feeds_the_live_session_through_the_gpu_turned_upright() {
    use previz::camera::yuv::{Layout, YuvMatrix, YuvRange, from_rgba, to_rgba_cpu, turn_image};
    use previz::render::Layer;
    let gpu = common::gpu();
    let photo = image::open(data("photos/colour_transfer/coffee.png")).unwrap().to_rgba8();
    let (w, h) = (161, 97); // odd sizes: the chroma planes round up
    let crop = image::imageops::crop_imm(&photo, 40, 30, w, h).to_image();
    let img = previz::scene::Rgba8Image { width: w, height: h, pixels: crop.into_raw() };
    // Android's usual layout (NV21, pixel stride 2), rows padded by 7 bytes, the camera's
    // BT.601 full range; every turn a camera mounted at an angle to the screen needs.
    let yuv = from_rgba(&img, Layout::Nv21, YuvMatrix::Bt601, YuvRange::Full, 7).unwrap();
    for quarter_turns in 0..4 {
        let want = turn_image(&to_rgba_cpu(&yuv.frame()).unwrap(), quarter_turns);
        let camera = YuvCamera { yuv: yuv.clone(), quarter_turns, k: 0 };
        let mut session = live_session_on(camera, (want.width, want.height)).unwrap();
        let frame = session.advance(gpu).unwrap().expect("a frame");
        assert!(frame.pose.is_none(), "no sensor readings: the frame is the camera image alone");
        assert!(session.camera_image().is_none(), "the YUV frame stays on the GPU");
        // The converted frame read back equals the CPU reference (f32 vs f64: one code).
        let camera_rgb = session.camera_frame(gpu).unwrap();
        assert_eq!((camera_rgb.width, camera_rgb.height), (want.width, want.height));
        let d = camera_rgb.pixels.iter().zip(&want.pixels).map(|(a, b)| (i32::from(*a) - i32::from(*b)).abs()).max().unwrap();
        assert!(d <= 1, "{quarter_turns} turns: the GPU conversion differs from the CPU reference by {d}");
        // The composite's background is that image: decoded to linear light and encoded again
        // through the sRGB target (one more code of rounding).
        let background = session.render_layer(gpu, Layer::Background).unwrap();
        assert_eq!((background.width, background.height), (want.width, want.height));
        let d = background.rgba.iter().zip(&want.pixels).map(|(a, b)| (i32::from(*a) - i32::from(*b)).abs()).max().unwrap();
        assert!(d <= 2, "{quarter_turns} turns: the background differs from the CPU reference by {d}");
    }
}

#[test]
fn a_yuv_frame_of_the_wrong_size_is_a_clear_error() {
    use previz::camera::yuv::{Layout, YuvMatrix, YuvRange, from_rgba};
    let img = previz::scene::Rgba8Image { width: 64, height: 48, pixels: vec![128; 64 * 48 * 4] };
    let yuv = from_rgba(&img, Layout::Nv12, YuvMatrix::Bt709, YuvRange::Limited, 0).unwrap();
    // A quarter turn makes the 64x48 image 48x64; the session's output is 64x48.
    let mut session = live_session_on(YuvCamera { yuv, quarter_turns: 1, k: 0 }, (64, 48)).unwrap();
    let err = format!("{:#}", session.advance(common::gpu()).unwrap_err());
    assert!(err.contains("48x64") && err.contains("64x48"), "{err}");
}
