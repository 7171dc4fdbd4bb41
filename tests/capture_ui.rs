//! The capture assistant's guidance drawn headless (egui + egui-wgpu on lavapipe) over a
//! virtual-phone frame, kept as golden images and compared with NVIDIA FLIP.

use crate::common;

use previz::camera::exposure::ExposureMode;
use previz::camera::sim::{SimSettings, VirtualPhone};
use previz::capture::Mode;
use previz::capture::assistant::{Assistant, AssistantConfig};
use previz::capture::projection::Pinhole;
use previz::capture::targets::Face;
use previz::pose::frames::from_heading_pitch_roll;
use previz::pose::{HeadingSource, Pose};
use previz::render::{Rendered, Timings};
use previz::scene::Rgba8Image;
use previz::scene::environment::load_environment;
use previz::ui::capture_overlay::{draw_capture_overlay, thumbnail};
use previz::ui::headless::HeadlessUi;
use std::sync::Arc;

const W: u32 = 640;
const H: u32 = 480;

fn pose(h: f64, p: f64, source: HeadingSource) -> Pose {
    Pose {
        t: 0.0,
        q: from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.0).as_quat(),
        accuracy_deg: 1.0,
        heading_accuracy_deg: 1.0,
        tilt_accuracy_deg: 0.5,
        heading_source: source,
        magnetic_disturbance: source == HeadingSource::GyroOnly,
    }
}

struct Scene {
    phone: VirtualPhone,
    assistant: Assistant,
    t: f64,
}

impl Scene {
    fn new() -> Scene {
        let env = Arc::new(load_environment(&common::data("hdri/polyhaven_1k/quarry_01_1k.hdr")).unwrap());
        let phone =
            VirtualPhone::new(env, &SimSettings { width: W, height: H, vfov_deg: 50.0, exposure: ExposureMode::Fixed(1.0) }).unwrap();
        let mut cfg = AssistantConfig::new(Mode::Stretch, Pinhole::from_vfov(W, H, 50.0).unwrap());
        cfg.face_size = 64;
        Scene { phone, assistant: Assistant::new(cfg).unwrap(), t: 0.0 }
    }

    fn frame(&self, p: &Pose) -> Rgba8Image {
        // A fixed exposure keeps the golden independent of metering details.
        self.phone.render_with_exposure(p.q, 0.5).unwrap()
    }

    /// Hold `p` until the assistant takes a shot.
    fn take(&mut self, p: Pose) {
        let frame = Arc::new(self.frame(&p));
        for _ in 0..30 {
            self.t += 1.0 / 30.0;
            if self.assistant.feed(&frame, &p, self.t, false).unwrap().is_some() {
                return;
            }
        }
        panic!("no shot taken");
    }

    fn thumbs(&self, ui: &HeadlessUi) -> [Option<egui::TextureHandle>; 6] {
        let targets = self.assistant.targets();
        Face::ALL.map(|face| {
            let i = targets.iter().position(|t| t.primary && t.face == face)?;
            let shot = self.assistant.shot(i)?;
            Some(ui.context().load_texture(face.name(), thumbnail(&shot.image, 64), egui::TextureOptions::LINEAR))
        })
    }

    fn draw(&mut self, ui: &mut HeadlessUi, p: &Pose) -> Rendered {
        let background = self.frame(p);
        let thumbs = self.thumbs(ui);
        let g = self.assistant.guidance();
        let img = ui.render(common::gpu(), &background, |ctx| draw_capture_overlay(ctx, &g, &thumbs)).unwrap();
        Rendered { width: img.width, height: img.height, rgba: img.pixels, timings: Timings::default() }
    }
}

#[test]
fn capture_guidance_golden_images() {
    let mut s = Scene::new();
    let mut ui = HeadlessUi::new(common::gpu(), W, H, 1.0).unwrap();
    // The tour (targets::short_tour) from the front: up, left, back, right, down.
    let tour: Vec<&str> = s.assistant.targets().iter().map(|t| t.name.as_str()).collect();
    assert_eq!(tour, ["front", "up", "left", "back", "right", "down"]);
    // Tap facing 200° (towards the quarry's sun side), then take up and left (110°).
    let front = pose(200.0, 0.0, HeadingSource::Magnetometer);
    let frame = Arc::new(s.frame(&front));
    s.assistant.tap(0.0, &front, frame).unwrap();
    s.take(pose(200.0, 89.5, HeadingSource::Magnetometer));
    s.take(pose(109.5, 0.5, HeadingSource::Magnetometer));
    assert_eq!(s.assistant.guidance().faces_done, 3);

    // 1: turning quickly towards back (20°), which is in view 18° to the right; the compass is
    // disturbed. Expect: "Hold still", the ring on the target, 3/6, three thumbnails, the badge.
    s.t += 1.0 / 30.0;
    s.assistant.observe(s.t, &pose(354.0, 2.0, HeadingSource::GyroOnly)).unwrap();
    s.t += 1.0 / 30.0;
    let p = pose(2.0, 2.0, HeadingSource::GyroOnly);
    s.assistant.observe(s.t, &p).unwrap();
    let g = s.assistant.guidance();
    assert!(g.hold_still && g.gyro_only, "{g:?}");
    let next = g.next.as_ref().unwrap();
    assert_eq!(next.name, "back");
    assert!(next.on_screen.is_some_and(|n| n.x > 0.3 && n.x < 0.8), "{next:?}");
    let in_view = s.draw(&mut ui, &p);
    common::assert_golden("capture_overlay_in_view", &in_view);

    // 2: after back and right, held still looking 40° down at 300°: the last target (down, 50°
    // away) is out of view; an arrow points down. The heading is calibrated against the sun:
    // the yellow "north from the sun" badge instead of the gyro-only one, no "Hold still".
    s.take(pose(20.0, -0.5, HeadingSource::Magnetometer));
    s.take(pose(290.5, 0.5, HeadingSource::Magnetometer));
    let p = pose(300.0, -40.0, HeadingSource::Sun);
    for _ in 0..6 {
        s.t += 1.0 / 30.0;
        s.assistant.observe(s.t, &p).unwrap();
    }
    let g = s.assistant.guidance();
    assert!(!g.hold_still && !g.gyro_only);
    let next = g.next.as_ref().unwrap();
    assert_eq!(next.name, "down");
    assert!(next.on_screen.is_none() && next.arrow.y < -0.99, "{next:?}");
    assert_eq!(g.message, "Turn to down");
    let r = s.draw(&mut ui, &p);
    common::assert_golden("capture_overlay_arrow", &r);
    // The gyro-only badge (amber #FFBE28, top left at (14, 58)) is drawn while the compass is
    // disturbed and only then: its left margin, before the text starts, is amber in the first
    // image and not in the second.
    let amber = |img: &Rendered| {
        (17..21).all(|x| (62..70).all(|y| common::pixel(img, x, y)[..3].iter().zip([255u8, 190, 40]).all(|(a, b)| a.abs_diff(b) <= 6)))
    };
    assert!(amber(&in_view), "no gyro-only badge while the compass is disturbed: {:?}", common::pixel(&in_view, 18, 64));
    assert!(!amber(&r), "a gyro-only badge with the compass fine");
    let sun_badge = |img: &Rendered| {
        (17..21).all(|x| (62..70).all(|y| common::pixel(img, x, y)[..3].iter().zip([255u8, 225, 90]).all(|(a, b)| a.abs_diff(b) <= 6)))
    };
    assert!(sun_badge(&r), "no sun badge with the heading from the sun: {:?}", common::pixel(&r, 18, 64));
    assert!(!sun_badge(&in_view), "a sun badge while gyro-only");
}
