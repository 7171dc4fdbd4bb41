//! Where the composite mode's panels go on a screen of any size, so that none covers another
//! (phones in portrait and landscape, the desktop window): a pure function of the screen's
//! rectangle, tested on its own; the app gives each window its rectangle (fixed, contents
//! scrolled) and the tests measure the windows egui actually drew.
//!
//! - Landscape (width ≥ height): a left column (the status above the model picker), the control
//!   panel as a right column, the camera view between them, the shutter bar along the bottom.
//! - Portrait: the status and the model picker side by side at the top, the control panel above
//!   the shutter bar at the bottom, the camera view between them.

use egui::{Rect, pos2, vec2};

/// Margin from the screen's edges and between panels (points).
pub const GAP: f32 = 8.0;
/// Height of the shutter bar (one row of buttons).
pub const BAR_H: f32 = 30.0;

/// The egui ids of the composite mode's windows (tests find them in egui's memory).
pub const STATUS_ID: &str = "previz-status";
pub const MODEL_ID: &str = "previz-model";
pub const CONTROLS_ID: &str = "previz-controls";
pub const BAR_ID: &str = "previz-bar";

/// The composite mode's panels on one screen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Regions {
    /// Frame rate, sensors, pose, sun, environment.
    pub status: Rect,
    /// The model picker (and the manual place and time when location is refused).
    pub model: Rect,
    /// The control panel (seed 000 Fig. 23).
    pub controls: Rect,
    /// The capture and shutter buttons and the status message.
    pub bar: Rect,
    /// What is left for the camera view, uncovered.
    pub view: Rect,
}

/// Split `screen` (points) into the composite mode's panels (module docs). Every rectangle lies
/// inside the screen and none overlaps another: `GAP` lies between neighbours.
pub fn composite_regions(screen: Rect) -> Regions {
    let s = screen.shrink(GAP);
    let bar = Rect::from_min_max(pos2(s.min.x, s.max.y - BAR_H), s.max);
    let above = Rect::from_min_max(s.min, pos2(s.max.x, bar.min.y - GAP));
    if screen.width() >= screen.height() {
        let left_w = (0.3 * screen.width()).clamp(150.0, 280.0);
        let right_w = (0.34 * screen.width()).clamp(170.0, 300.0);
        let left = Rect::from_min_size(above.min, vec2(left_w, above.height()));
        let status_h = (0.45 * left.height()).clamp(60.0, 150.0);
        let status = Rect::from_min_size(left.min, vec2(left_w, status_h));
        let model = Rect::from_min_max(pos2(left.min.x, status.max.y + GAP), left.max);
        let controls = Rect::from_min_max(pos2(above.max.x - right_w, above.min.y), above.max);
        let view = Rect::from_min_max(pos2(left.max.x + GAP, above.min.y), pos2(controls.min.x - GAP, above.max.y));
        Regions { status, model, controls, bar, view }
    } else {
        let top_h = (0.2 * screen.height()).clamp(90.0, 170.0);
        let half = 0.5 * (above.width() - GAP);
        let status = Rect::from_min_size(above.min, vec2(half, top_h));
        let model = Rect::from_min_max(pos2(status.max.x + GAP, above.min.y), pos2(above.max.x, above.min.y + top_h));
        let controls_h = (0.4 * screen.height()).clamp(120.0, 420.0);
        let controls = Rect::from_min_max(pos2(above.min.x, above.max.y - controls_h), above.max);
        let view = Rect::from_min_max(pos2(above.min.x, status.max.y + GAP), pos2(above.max.x, controls.min.y - GAP));
        Regions { status, model, controls, bar, view }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Phone screens in points (portrait and landscape) and the desktop's default window.
    const SCREENS: [(f32, f32); 8] =
        [(360.0, 640.0), (640.0, 360.0), (390.0, 844.0), (844.0, 390.0), (480.0, 320.0), (320.0, 480.0), (960.0, 640.0), (1280.0, 800.0)];

    #[test]
    fn panels_lie_inside_the_screen_and_never_overlap() {
        for (w, h) in SCREENS {
            let screen = Rect::from_min_size(pos2(0.0, 0.0), vec2(w, h));
            let r = composite_regions(screen);
            let all = [("status", r.status), ("model", r.model), ("controls", r.controls), ("bar", r.bar), ("view", r.view)];
            for (name, rect) in all {
                assert!(screen.contains_rect(rect), "{w}x{h}: {name} {rect:?} leaves the screen");
                assert!(rect.width() > 0.0 && rect.height() > 0.0, "{w}x{h}: {name} is empty");
            }
            for (i, (a, ra)) in all.iter().enumerate() {
                for (b, rb) in &all[i + 1..] {
                    assert!(!ra.intersects(*rb), "{w}x{h}: {a} {ra:?} overlaps {b} {rb:?}");
                }
            }
            // The camera view keeps a useful share of the screen (a quarter of the smaller side
            // at least, each way).
            let side = w.min(h) * 0.25;
            assert!(r.view.width() >= side && r.view.height() >= side, "{w}x{h}: view {:?}", r.view);
        }
    }

    #[test]
    fn landscape_puts_the_controls_on_the_right_and_portrait_at_the_bottom() {
        let land = composite_regions(Rect::from_min_size(pos2(0.0, 0.0), vec2(844.0, 390.0)));
        assert!(land.controls.min.x > land.view.max.x && land.status.max.x < land.view.min.x);
        let port = composite_regions(Rect::from_min_size(pos2(0.0, 0.0), vec2(390.0, 844.0)));
        assert!(port.controls.min.y > port.view.max.y && port.status.max.y < port.view.min.y);
        assert!(port.bar.min.y > port.controls.max.y);
    }
}
