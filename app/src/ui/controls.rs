//! The composite mode's control panel (seed 000 Fig. 23) and the touch gestures on the model.
//!
//! Panel: DL daylight, SL sunlight, R reflection/refraction, CC colour correction, A/D/S/G
//! ambient/diffuse/specular/gloss, X/Y/Z rotations; the lighting method picker (HL, hemisphere
//! shading, is one of its methods) and reset, in a window that folds away. [`Controls::apply`]
//! writes them into the frame parameters; [`Controls::show`] is the egui panel.
//!
//! Gestures (what phone AR apps do): one finger drags the model across the ground plane
//! ([`drag_on_ground`]: the model follows the ground point under the finger), two fingers pinch
//! to scale and twist to turn it about the vertical ([`pinch_twist`]).

use crate::render::{FrameParams, LightingMethod};
use glam::{Quat, Vec2, Vec3};

/// Below this inner width (points) the panel labels its sliders with the seed's codes alone
/// (DL, SL, ...), so a phone's narrow panel fits a usable slider.
pub const NARROW_PANEL: f32 = 230.0;

/// The panel's values (what the user set), applied to every frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Controls {
    /// The panel is unfolded.
    pub open: bool,
    /// DL: daylight (ambient) intensity l_d.
    pub daylight: f32,
    /// SL: sunlight, 0..1 of the sun's intensity at this place and time.
    pub sunlight: f32,
    /// R: reflection/refraction mix.
    pub reflection: f32,
    /// CC: colour-correction strength.
    pub colour: f32,
    /// A, D, S: ambient, diffuse, specular terms; G: gloss exponent.
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub gloss: f32,
    /// X, Y, Z: the model's rotations, degrees.
    pub rotation_deg: [f32; 3],
    pub method: LightingMethod,
}

impl Controls {
    /// The panel showing what a frame is drawn with (the scene's values); SL at 1.
    pub fn from_params(p: &FrameParams) -> Controls {
        let l = &p.lighting;
        let r = p.placement.rotation;
        Controls {
            open: true,
            daylight: l.daylight,
            sunlight: 1.0,
            reflection: l.reflection,
            colour: p.colour.strength,
            ambient: l.material.ambient,
            diffuse: l.material.diffuse,
            specular: l.material.specular,
            gloss: l.material.gloss.unwrap_or(32.0),
            rotation_deg: [r.x.to_degrees(), r.y.to_degrees(), r.z.to_degrees()],
            method: p.method,
        }
    }

    /// Write the panel into a frame's parameters. `sun_intensity` is the sun's intensity for the
    /// place and time (after the twilight fade); SL scales it.
    pub fn apply(&self, p: &mut FrameParams, sun_intensity: f32) {
        let l = &mut p.lighting;
        l.daylight = self.daylight;
        l.sunlight = self.sunlight * sun_intensity;
        l.reflection = self.reflection;
        l.material.ambient = self.ambient;
        l.material.diffuse = self.diffuse;
        l.material.specular = self.specular;
        l.material.gloss = Some(self.gloss);
        p.colour.strength = self.colour;
        let [x, y, z] = self.rotation_deg;
        p.placement.rotation = Vec3::new(x.to_radians(), y.to_radians(), z.to_radians());
        p.method = self.method;
    }

    /// The panel in `rect` (its contents scroll when the screen is short;
    /// [`crate::ui::layout`]). Returns true when Reset was pressed (the caller restores the
    /// scene's values and the model's placement).
    pub fn show(&mut self, ctx: &egui::Context, rect: egui::Rect) -> bool {
        let mut reset = false;
        egui::Window::new("controls")
            .id(egui::Id::unique(crate::ui::layout::CONTROLS_ID))
            .fixed_rect(rect)
            .vscroll(true)
            .collapsible(true)
            .open(&mut self.open)
            .show(ctx, |ui| {
                // Sliders as wide as the panel allows beside their value and label; a narrow
                // panel (a phone) labels them with the seed's codes alone, the name on hover.
                let narrow = ui.available_width() < NARROW_PANEL;
                let reserved = if narrow { 95.0 } else { 140.0 };
                ui.spacing_mut().slider_width = (ui.available_width() - reserved).clamp(24.0, 160.0);
                let label = |name: &'static str| if narrow { name.split(' ').next().unwrap_or(name) } else { name };
                let slider = |ui: &mut egui::Ui, name: &'static str, v: &mut f32, max: f32| {
                    ui.add(egui::Slider::new(v, 0.0..=max).text(label(name))).on_hover_text(name);
                };
                slider(ui, "DL daylight", &mut self.daylight, 2.0);
                slider(ui, "SL sunlight", &mut self.sunlight, 1.0);
                slider(ui, "R reflection", &mut self.reflection, 1.0);
                slider(ui, "CC colour", &mut self.colour, 1.0);
                ui.separator();
                slider(ui, "A ambient", &mut self.ambient, 2.0);
                slider(ui, "D diffuse", &mut self.diffuse, 2.0);
                slider(ui, "S specular", &mut self.specular, 2.0);
                ui.add(egui::Slider::new(&mut self.gloss, 1.0..=256.0).logarithmic(true).text(label("G gloss"))).on_hover_text("G gloss");
                ui.separator();
                for (v, label) in self.rotation_deg.iter_mut().zip(["X", "Y", "Z"]) {
                    ui.add(egui::Slider::new(v, -180.0..=180.0).suffix("°").text(label));
                }
                egui::ComboBox::from_label("method").selected_text(self.method.name()).show_ui(ui, |ui| {
                    for m in LightingMethod::ALL {
                        ui.selectable_value(&mut self.method, m, m.name());
                    }
                });
                reset = ui.button("reset").clicked();
            });
        if !self.open {
            // Folded away: one button brings it back.
            egui::Area::new(egui::Id::unique("controls-unfold")).fixed_pos(rect.min).show(ctx, |ui| {
                if ui.button("controls").clicked() {
                    self.open = true;
                }
            });
        }
        reset
    }
}

/// The ray from the camera through a screen point (pixels, origin top-left, y down) of an
/// image `size` wide and high with vertical field of view `vfov` (radians), in world axes.
pub fn screen_ray(pose: Quat, vfov: f32, size: Vec2, point: Vec2) -> Vec3 {
    let t = (0.5 * vfov).tan();
    let ndc = Vec2::new(2.0 * point.x / size.x - 1.0, 1.0 - 2.0 * point.y / size.y);
    let dir_cam = Vec3::new(ndc.x * t * size.x / size.y, ndc.y * t, -1.0);
    (pose * dir_cam).normalize()
}

/// Where the ray from `camera` along `dir` meets the horizontal plane z = `ground_z`; None when
/// it points away from it or along it.
pub fn ground_hit(camera: Vec3, dir: Vec3, ground_z: f32) -> Option<Vec3> {
    if dir.z.abs() < 1e-6 {
        return None;
    }
    let s = (ground_z - camera.z) / dir.z;
    (s > 0.0).then(|| camera + s * dir)
}

/// One-finger drag from `from` to `to` (screen pixels): the world displacement that keeps the
/// ground point under the finger under it (the model slides on its ground plane z = `ground_z`).
/// Zero when either point is above the horizon.
pub fn drag_on_ground(p: &FrameParams, size: Vec2, from: Vec2, to: Vec2) -> Vec3 {
    let cam = &p.camera;
    let ground_z = p.placement.position.z;
    let hit = |s| ground_hit(cam.position, screen_ray(cam.pose, cam.vfov, size, s), ground_z);
    match (hit(from), hit(to)) {
        (Some(a), Some(b)) => b - a,
        _ => Vec3::ZERO,
    }
}

/// Two-finger gesture between the finger pairs `(a0, b0)` and `(a1, b1)`: the scale factor
/// (finger distance ratio) and the twist about the vertical, radians (the change of the
/// fingers' angle on screen; counter-clockwise on screen turns the model counter-clockwise seen
/// from above, i.e. positive about +z).
pub fn pinch_twist(a0: Vec2, b0: Vec2, a1: Vec2, b1: Vec2) -> (f32, f32) {
    let (d0, d1) = (b0 - a0, b1 - a1);
    let scale = if d0.length() > 1e-3 { d1.length() / d0.length() } else { 1.0 };
    // Screen y points down: negate to measure counter-clockwise as seen.
    let angle = |d: Vec2| (-d.y).atan2(d.x);
    let mut twist = angle(d1) - angle(d0);
    if twist > std::f32::consts::PI {
        twist -= std::f32::consts::TAU;
    } else if twist < -std::f32::consts::PI {
        twist += std::f32::consts::TAU;
    }
    (scale, twist)
}

/// Apply a drag (world displacement) and a pinch/twist to the model: the drag and the scale
/// move the placement, the twist turns the Z control (kept in −180..=180°) so the panel shows it.
pub fn apply_gesture(p: &mut FrameParams, c: &mut Controls, moved: Vec3, scale: f32, twist: f32) {
    p.placement.position += moved;
    p.placement.scale *= scale.clamp(0.01, 100.0);
    let z = c.rotation_deg[2] + twist.to_degrees();
    c.rotation_deg[2] = (z + 180.0).rem_euclid(360.0) - 180.0;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::view::camera_pose;

    #[test]
    fn a_ray_through_the_centre_is_the_view_direction_and_the_top_edge_is_half_the_fov_up() {
        // Looking North, level: the centre ray is +y; the top edge's ray is pitched up vfov/2.
        let pose = camera_pose(0.0, 0.0, 0.0);
        let size = Vec2::new(400.0, 200.0);
        let c = screen_ray(pose, 60f32.to_radians(), size, Vec2::new(200.0, 100.0));
        assert!((c - Vec3::Y).length() < 1e-6);
        let top = screen_ray(pose, 60f32.to_radians(), size, Vec2::new(200.0, 0.0));
        assert!((top.z.asin().to_degrees() - 30.0).abs() < 1e-4, "{top}");
    }

    #[test]
    fn dragging_the_ground_point_moves_the_model_by_the_ground_distance() {
        // A camera 1.5 m up looking North, pitched down 45°: the image centre hits the ground
        // 1.5 m North. With a 90° vertical field of view, the bottom edge looks straight down
        // (the point below the camera) and the ray 1/3 of the way up from the centre to the top,
        // pitched down 45° − atan(1/3) = 26.565°, hits at 1.5 / tan(26.565°) = 3.0 m.
        let mut p = FrameParams::example();
        p.camera.position = Vec3::new(0.0, 0.0, 1.5);
        p.camera.pose = camera_pose(0.0, -45f32.to_radians(), 0.0);
        p.camera.vfov = 90f32.to_radians();
        let size = Vec2::new(300.0, 300.0);
        let centre = Vec2::new(150.0, 150.0);
        let d = drag_on_ground(&p, size, centre, Vec2::new(150.0, 300.0));
        assert!((d - Vec3::new(0.0, -1.5, 0.0)).length() < 1e-4, "{d}");
        let d = drag_on_ground(&p, size, centre, Vec2::new(150.0, 100.0));
        assert!((d - Vec3::new(0.0, 1.5, 0.0)).length() < 1e-4, "{d}");
        // Above the horizon nothing moves.
        assert_eq!(drag_on_ground(&p, size, centre, Vec2::new(150.0, 0.0)), Vec3::ZERO);
    }

    #[test]
    fn pinch_and_twist_measure_distance_ratio_and_screen_angle() {
        // Fingers 100 px apart, horizontally, then 200 px apart vertically with b above a:
        // scale 2, a quarter turn counter-clockwise as seen (+90° about Up).
        let (s, t) = pinch_twist(Vec2::new(0.0, 0.0), Vec2::new(100.0, 0.0), Vec2::new(0.0, 0.0), Vec2::new(0.0, -200.0));
        assert!((s - 2.0).abs() < 1e-6);
        assert!((t.to_degrees() - 90.0).abs() < 1e-4);
        // Across ±180°: from 170° to −170° is +20°, not −340°.
        let at = |deg: f32| Vec2::new(deg.to_radians().cos(), -deg.to_radians().sin()) * 50.0;
        let (_, t) = pinch_twist(Vec2::ZERO, at(170.0), Vec2::ZERO, at(-170.0));
        assert!((t.to_degrees() - 20.0).abs() < 1e-3, "{}", t.to_degrees());
    }

    #[test]
    fn gestures_move_scale_and_turn_the_model() {
        let mut p = FrameParams::example();
        let mut c = Controls::from_params(&p);
        c.rotation_deg[2] = 170.0;
        apply_gesture(&mut p, &mut c, Vec3::new(1.0, 2.0, 0.0), 2.0, 20f32.to_radians());
        assert_eq!(p.placement.position, Vec3::new(1.0, 2.0, 0.0));
        assert_eq!(p.placement.scale, 2.0);
        assert!((c.rotation_deg[2] + 170.0).abs() < 1e-3, "170° + 20° wraps to −170°, got {}", c.rotation_deg[2]);
        c.apply(&mut p, 1.0);
        assert!((p.placement.rotation.z.to_degrees() + 170.0).abs() < 1e-3);
    }

    #[test]
    fn controls_round_trip_and_sl_scales_the_sun() {
        let mut p = FrameParams::example();
        let mut c = Controls::from_params(&p);
        c.sunlight = 0.0;
        c.rotation_deg = [0.0, 0.0, 90.0];
        c.apply(&mut p, 2.5);
        assert_eq!(p.lighting.sunlight, 0.0);
        assert!((p.placement.rotation.z - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        c.sunlight = 0.4;
        c.apply(&mut p, 2.5);
        assert!((p.lighting.sunlight - 1.0).abs() < 1e-6);
    }

    /// Each of the panel's values lands in the frame term it names (seed 000 Fig. 23: DL, SL,
    /// R, CC, A, D, S, G, X/Y/Z; the method).
    #[test]
    fn every_slider_writes_the_term_it_names() {
        let mut p = FrameParams::example();
        let c = Controls {
            open: true,
            daylight: 1.25,
            sunlight: 0.5,
            reflection: 0.75,
            colour: 0.25,
            ambient: 1.5,
            diffuse: 0.5,
            specular: 1.75,
            gloss: 64.0,
            rotation_deg: [10.0, -20.0, 30.0],
            method: LightingMethod::Sh9Ggx,
        };
        c.apply(&mut p, 4.0);
        let l = &p.lighting;
        assert_eq!((l.daylight, l.sunlight, l.reflection, p.colour.strength), (1.25, 2.0, 0.75, 0.25));
        assert_eq!((l.material.ambient, l.material.diffuse, l.material.specular, l.material.gloss), (1.5, 0.5, 1.75, Some(64.0)));
        let r = p.placement.rotation;
        assert!((r - Vec3::new(10f32.to_radians(), -20f32.to_radians(), 30f32.to_radians())).abs().max_element() < 1e-6, "{r}");
        assert_eq!(p.method, LightingMethod::Sh9Ggx);
        // And the panel read back from those parameters shows the same values (SL at 1; the
        // angles through radians and back, to float rounding).
        let back = Controls::from_params(&p);
        assert!(back.rotation_deg.iter().zip(c.rotation_deg).all(|(a, b)| (a - b).abs() < 1e-4), "{:?}", back.rotation_deg);
        assert_eq!(Controls { sunlight: 0.5, rotation_deg: c.rotation_deg, ..back }, c);
    }

    /// Folded away, the panel draws no slider, only the button that brings it back; a click on
    /// that button (synthetic egui input) unfolds it; the method picker picks what is clicked.
    #[test]
    fn the_panel_folds_away_and_its_button_brings_it_back_and_its_method_picker_picks() {
        let ctx = egui::Context::default();
        ctx.all_styles_mut(|s| s.animation_time = 0.0);
        let rect = egui::Rect::from_min_size(egui::pos2(400.0, 0.0), egui::vec2(300.0, 600.0));
        let mut c = Controls { open: false, ..Controls::from_params(&FrameParams::example()) };
        let pass = |c: &mut Controls, events: Vec<egui::Event>| {
            let input = egui::RawInput {
                screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 600.0))),
                events,
                ..Default::default()
            };
            let mut out = ctx.run_pass(input, |ctx| {
                c.show(ctx, rect);
            });
            out.textures_delta.set.drain().for_each(drop);
            out.textures_delta.free.drain().for_each(drop);
            let texts: Vec<(String, egui::Rect)> = out
                .shapes
                .iter()
                .filter_map(|s| match &s.shape {
                    egui::Shape::Text(t) => Some((t.galley.text().to_string(), t.visual_bounding_rect())),
                    _ => None,
                })
                .collect();
            texts
        };
        pass(&mut c, vec![]);
        let folded = pass(&mut c, vec![]);
        assert!(!folded.iter().any(|(t, _)| t.contains("SL")), "a folded panel shows no slider: {folded:?}");
        let at = folded.iter().find(|(t, _)| t == "controls").expect("the unfold button").1.center();
        let button =
            |pressed| egui::Event::PointerButton { pos: at, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() };
        pass(&mut c, vec![egui::Event::PointerMoved(at), button(true)]);
        pass(&mut c, vec![button(false)]);
        assert!(c.open, "the button unfolds the panel");
        // (A window appearing is laid out, unseen, in its first pass.)
        pass(&mut c, vec![]);
        let unfolded = pass(&mut c, vec![]);
        assert!(unfolded.iter().any(|(t, _)| t.contains("SL")), "the unfolded panel shows its sliders: {unfolded:?}");

        // The method picker: a click on the method shown opens the list, a click on another
        // method picks it.
        let click = |c: &mut Controls, label: &str, texts: &[(String, egui::Rect)]| {
            let at = texts.iter().rfind(|(t, _)| t == label).unwrap_or_else(|| panic!("no {label:?} on screen")).1.center();
            let button = |pressed| egui::Event::PointerButton {
                pos: at,
                button: egui::PointerButton::Primary,
                pressed,
                modifiers: Default::default(),
            };
            pass(c, vec![egui::Event::PointerMoved(at), button(true)]);
            pass(c, vec![button(false)]);
            pass(c, vec![]);
            pass(c, vec![])
        };
        assert_eq!(c.method, LightingMethod::BlinnPhong);
        let listed = click(&mut c, LightingMethod::BlinnPhong.name(), &unfolded);
        click(&mut c, LightingMethod::Sh9Ggx.name(), &listed);
        assert_eq!(c.method, LightingMethod::Sh9Ggx, "picked from the list");
    }
}
