//! The app's lifecycle on the host: suspend → resume → suspend cycles of a live session stop the
//! camera and the sensors while suspended (no frame captured, no reading polled, no frame
//! advanced), keep the scene (placement, controls, the filter's attitude), and allocate no GPU
//! resources across the cycles (wgpu's counters, as tests/allocation.rs). Alone in its own test
//! binary: the counters are per device and other tests would allocate.
//!
//! The camera and the sensors are test doubles that log every call, so a callback reaching them
//! while the session is suspended shows in the log. The environment folded from the camera frame
//! is refreshed without allocating either. The window's surface dropped and recreated through
//! winit's events: tests/app_window.rs (under Xvfb).

mod common;

use common::{FRAME_RESOURCES, assert_unchanged, gpu, scene, settled_counters, triangle};
use previz::camera::{Frame, FrameSource};
use previz::live::{LiveConfig, LiveSession, Sources};
use previz::pose::DisplayRotation;
use previz::scene::{CubeMap, Rgba8Image};
use previz::sensors::sim::NoiseLevel;
use previz::sensors::{Reading, SensorSource};
use std::sync::{Arc, Mutex};

type Log = Arc<Mutex<Vec<&'static str>>>;

/// A camera delivering grey frames at 30 Hz; it refuses to deliver while paused.
struct Camera {
    log: Log,
    size: (u32, u32),
    k: u32,
    paused: bool,
}

impl FrameSource for Camera {
    fn next_frame(&mut self) -> anyhow::Result<Option<Frame>> {
        self.log.lock().unwrap().push("frame");
        anyhow::ensure!(!self.paused, "a frame was asked of a paused camera");
        let (w, h) = self.size;
        let image = Rgba8Image { width: w, height: h, pixels: vec![128; (4 * w * h) as usize] };
        self.k += 1;
        Ok(Some(Frame { image, t: f64::from(self.k) / 30.0 }))
    }

    fn pause(&mut self) -> anyhow::Result<()> {
        self.log.lock().unwrap().push("camera pause");
        self.paused = true;
        Ok(())
    }

    fn resume(&mut self) -> anyhow::Result<()> {
        self.log.lock().unwrap().push("camera resume");
        self.paused = false;
        Ok(())
    }
}

/// Sensors delivering one accelerometer and one magnetometer reading per poll: the device lies
/// face-up, its top towards magnetic north (a field of 49 µT dipping 66°, about Bristol's).
struct Sensors {
    log: Log,
    paused: bool,
}

impl SensorSource for Sensors {
    fn poll(&mut self, until: f64, out: &mut Vec<Reading>) -> anyhow::Result<()> {
        self.log.lock().unwrap().push("poll");
        anyhow::ensure!(!self.paused, "paused sensors were polled");
        out.push(Reading::Accel { t: until, v: glam::DVec3::new(0.0, 0.0, 9.81) });
        out.push(Reading::Mag { t: until, v: glam::DVec3::new(0.0, 19.5, -44.6) });
        Ok(())
    }

    fn describe(&self) -> String {
        "test double".into()
    }

    fn pause(&mut self) -> anyhow::Result<()> {
        self.log.lock().unwrap().push("sensors pause");
        self.paused = true;
        Ok(())
    }

    fn resume(&mut self) -> anyhow::Result<()> {
        self.log.lock().unwrap().push("sensors resume");
        self.paused = false;
        Ok(())
    }
}

#[test]
fn suspend_resume_cycles_stop_camera_and_sensors_keep_the_scene_and_allocate_nothing() {
    let s = scene("width = 160\nheight = 120\n");
    let env = CubeMap { size: 4, faces: std::array::from_fn(|_| vec![[0.5; 3]; 16]) };
    let log: Log = Arc::default();
    let sources = Sources {
        camera: Box::new(Camera { log: log.clone(), size: (s.width, s.height), k: 0, paused: false }),
        sensors: Box::new(Sensors { log: log.clone(), paused: false }),
        rotation: DisplayRotation::default(),
        truth: None,
    };
    let cfg = LiveConfig {
        lat_deg: 51.4545,
        lon_deg: -2.5879,
        start: chrono::DateTime::parse_from_rfc3339("2026-06-21T12:00:00Z").unwrap().with_timezone(&chrono::Utc),
        frame_hz: 30.0,
        duration_s: 60.0,
        noise: NoiseLevel::Phone,
        seed: 1,
    };
    let mut session = LiveSession::new(gpu(), &env, &triangle(), &s, cfg, sources).unwrap();
    // A few frames so the filter has an attitude and every pipeline and target exists.
    for _ in 0..3 {
        session.advance(gpu()).unwrap().expect("a frame");
        session.draw(gpu()).unwrap();
    }
    let first = session.advance(gpu()).unwrap().expect("a frame");
    assert!(first.pose.is_some(), "the filter settled on the test attitude");
    session.draw(gpu()).unwrap();
    // The user moved the model before switching apps.
    session.params_mut().placement.position += glam::Vec3::new(0.5, -0.25, 0.0);
    let placement = session.params().placement;
    let before = settled_counters();

    let mut last_t = first.t;
    for cycle in 0..3 {
        log.lock().unwrap().clear();
        session.suspend().unwrap();
        session.suspend().unwrap(); // twice is once
        assert!(session.is_suspended());
        let err = session.advance(gpu()).expect_err("no frame while suspended");
        assert!(format!("{err:#}").contains("suspended"), "{err:#}");
        assert_eq!(*log.lock().unwrap(), ["camera pause", "sensors pause"], "cycle {cycle}: only the pauses while suspended");

        log.lock().unwrap().clear();
        session.resume().unwrap();
        assert!(!session.is_suspended());
        assert_eq!(session.params().placement, placement, "cycle {cycle}: the model's placement survives");
        let frame = session.advance(gpu()).unwrap().expect("frames again after resume");
        assert!(frame.t > last_t, "cycle {cycle}: time moves on");
        assert!(frame.pose.is_some(), "cycle {cycle}: the attitude survives");
        last_t = frame.t;
        session.draw(gpu()).unwrap();
        assert_eq!(*log.lock().unwrap(), ["sensors resume", "camera resume", "frame", "poll"], "cycle {cycle}");
    }

    let after = settled_counters();
    assert_unchanged(&before, &after, &FRAME_RESOURCES, "suspend/resume cycles");
    fold_refreshes_allocate_nothing(&mut session);
}

/// Called from the one test (the counters are per device): the camera frame folded into the
/// environment (what the app does before a capture) is refreshed into the fold's cube texture
/// and the compositor's environment textures made at the first fold: later refreshes allocate
/// nothing.
fn fold_refreshes_allocate_nothing(session: &mut LiveSession) {
    session.fold_camera_into_environment();
    let writes = session.compositor().environment_writes();
    session.advance(gpu()).unwrap().expect("a frame");
    session.finish_fold(gpu()).unwrap();
    session.draw(gpu()).unwrap();
    assert_eq!(session.fold_refreshes().map(|r| r.0), Some(1), "folded at the first frame with a pose");
    assert_eq!(session.compositor().environment_writes(), writes + 1);
    let before = settled_counters();
    // The camera double holds still: the fold is refreshed every FOLD_REFRESH_S of its 30 Hz frames.
    let frames = (2.0 * previz::live::FOLD_REFRESH_S * 30.0).ceil() as usize + 1;
    for _ in 0..frames {
        session.advance(gpu()).unwrap().expect("a frame");
        session.finish_fold(gpu()).unwrap();
        session.draw(gpu()).unwrap();
    }
    assert_eq!(session.fold_refreshes().map(|r| r.0), Some(3), "refreshed every {} s", previz::live::FOLD_REFRESH_S);
    assert_eq!(session.compositor().environment_writes(), writes + 3);
    let after = settled_counters();
    assert_unchanged(&before, &after, &FRAME_RESOURCES, "fold refreshes");
}
