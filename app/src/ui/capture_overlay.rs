//! The capture assistant's on-screen guidance, drawn with egui over the camera view: the next
//! target's name, a reticle on it when it is in view or an arrow towards it when not, progress
//! (n/6 faces, shots in stitch mode), "Hold still" when the phone turns too fast, a badge when the
//! heading is gyro-only (compass disturbed) or calibrated against the sun, and thumbnails of the faces taken so far.

use crate::capture::assistant::{Guidance, Phase};
use crate::capture::targets::Face;
use crate::scene::Rgba8Image;
use egui::{Align2, Color32, FontId, Pos2, Rect, Stroke, StrokeKind, Vec2};

/// Thumbnail side in points.
pub const THUMB: f32 = 64.0;

/// Label of the gyro-only badge.
pub const GYRO_ONLY_TEXT: &str = "gyro-only (compass disturbed)";
/// Label of the badge shown while the heading is calibrated against the sun.
pub const SUN_NORTH_TEXT: &str = "north from the sun";
/// Its colour (the sun calibration succeeded).
pub const SUN_NORTH_COLOUR: Color32 = Color32::from_rgb(255, 225, 90);

/// A square thumbnail (centre crop, box-filtered) of an sRGB frame, for [`egui::Context::load_texture`].
pub fn thumbnail(image: &Rgba8Image, side: usize) -> egui::ColorImage {
    let (w, h) = (image.width as usize, image.height as usize);
    let crop = w.min(h);
    let side = side.max(1);
    if crop == 0 {
        return egui::ColorImage::new([side, side], vec![Color32::BLACK; side * side]);
    }
    let (x0, y0) = ((w - crop) / 2, (h - crop) / 2);
    let mut pixels = Vec::with_capacity(side * side);
    for ty in 0..side {
        for tx in 0..side {
            // Box filter over the source pixels this thumbnail pixel covers.
            let (sx0, sx1) = (x0 + tx * crop / side, x0 + ((tx + 1) * crop / side).max(tx * crop / side + 1));
            let (sy0, sy1) = (y0 + ty * crop / side, y0 + ((ty + 1) * crop / side).max(ty * crop / side + 1));
            let mut sum = [0u32; 3];
            let mut n = 0u32;
            for y in sy0..sy1.min(h) {
                for x in sx0..sx1.min(w) {
                    let i = 4 * (y * w + x);
                    for (s, &p) in sum.iter_mut().zip(&image.pixels[i..i + 3]) {
                        *s += u32::from(p);
                    }
                    n += 1;
                }
            }
            let n = n.max(1);
            pixels.push(Color32::from_rgb((sum[0] / n) as u8, (sum[1] / n) as u8, (sum[2] / n) as u8));
        }
    }
    egui::ColorImage::new([side, side], pixels)
}

fn banner(painter: &egui::Painter, centre: Pos2, text: &str, size: f32, fg: Color32, bg: Color32) {
    let galley = painter.layout_no_wrap(text.to_string(), FontId::proportional(size), fg);
    let rect = Rect::from_center_size(centre, galley.size() + Vec2::new(24.0, 10.0));
    painter.rect_filled(rect, 8.0, bg);
    painter.galley(rect.center() - galley.size() * 0.5, galley, fg);
}

/// Draw the guidance over the whole screen. `thumbs` are in [`Face::ALL`] order (front, up,
/// down, right, back, left): a face with content shows while it fills in, framed green once it is
/// done; `None` for faces no shot has seen yet.
pub fn draw_capture_overlay(ctx: &egui::Context, g: &Guidance, thumbs: &[Option<egui::TextureHandle>; 6]) {
    let screen = ctx.content_rect();
    let painter = ctx.layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("capture-overlay")));
    let centre = screen.center();
    let white = Color32::WHITE;
    let shade = Color32::from_black_alpha(150);

    // Fixed reticle: where the camera points.
    let reticle = Stroke::new(2.0, white);
    painter.circle_stroke(centre, 18.0, reticle);
    painter.line_segment([centre - Vec2::X * 28.0, centre - Vec2::X * 10.0], reticle);
    painter.line_segment([centre + Vec2::X * 10.0, centre + Vec2::X * 28.0], reticle);
    painter.line_segment([centre - Vec2::Y * 28.0, centre - Vec2::Y * 10.0], reticle);
    painter.line_segment([centre + Vec2::Y * 10.0, centre + Vec2::Y * 28.0], reticle);

    // The next target: a ring on it when in view, else an arrow towards it.
    if let Some(next) = &g.next {
        let colour = if next.within { Color32::from_rgb(60, 220, 90) } else { Color32::from_rgb(255, 200, 40) };
        let half = screen.size() * 0.5;
        let label_at = match next.on_screen {
            Some(ndc) => {
                let p = centre + Vec2::new(ndc.x * half.x, -ndc.y * half.y);
                painter.circle_stroke(p, 26.0, Stroke::new(4.0, colour));
                painter.line_segment([centre, p], Stroke::new(1.5, colour.gamma_multiply(0.7)));
                p + Vec2::new(0.0, -44.0)
            }
            None => {
                let dir = Vec2::new(next.arrow.x, -next.arrow.y);
                let start = centre + dir * 40.0;
                painter.arrow(start, dir * 80.0, Stroke::new(6.0, colour));
                // Beside the arrow's middle.
                centre + dir * 80.0 + Vec2::new(dir.y, -dir.x) * 75.0
            }
        };
        // Keep the label clear of the top bar and the thumbnail strip.
        let safe = Rect::from_min_max(
            Pos2::new(screen.left() + 80.0, screen.top() + 90.0),
            Pos2::new(screen.right() - 80.0, screen.bottom() - THUMB - 60.0),
        );
        let text = format!("{}  {:.0}°", next.name, next.angle_deg);
        banner(&painter, safe.clamp(label_at), &text, 20.0, colour, shade);
    }

    // What to do (the "Hold still" warning has its own banner), and progress.
    let instruction = match (&g.next, g.phase) {
        (Some(n), Phase::Capturing) if g.hold_still => format!("Turn to {}", n.name),
        _ => g.message.clone(),
    };
    let top = Pos2::new(centre.x, screen.top() + 28.0);
    banner(&painter, top, &instruction, 24.0, white, shade);
    // Progress: a ring of six segments, one per face, filled as the faces come in (and the
    // shot count in stitch mode).
    if g.phase != Phase::WaitingForTap {
        let ring = Pos2::new(screen.right() - 44.0, screen.top() + 44.0);
        draw_progress_ring(&painter, ring, 26.0, &g.face_done);
        if g.shots_total > 6 {
            let text = format!("{}/{} shots", g.shots_done, g.shots_total);
            painter.text(ring + Vec2::new(0.0, 40.0), Align2::CENTER_TOP, text, FontId::proportional(14.0), white);
        }
    }
    if g.hold_still {
        banner(
            &painter,
            Pos2::new(centre.x, centre.y + 70.0),
            "Hold still",
            30.0,
            white,
            Color32::from_rgba_unmultiplied(200, 30, 30, 210),
        );
    }
    if g.gyro_only {
        let galley = painter.layout_no_wrap(GYRO_ONLY_TEXT.to_string(), FontId::proportional(18.0), Color32::BLACK);
        let rect = Rect::from_min_size(screen.left_top() + Vec2::new(14.0, 58.0), galley.size() + Vec2::new(16.0, 8.0));
        painter.rect_filled(rect, 6.0, Color32::from_rgb(255, 190, 40));
        painter.galley(rect.min + Vec2::new(8.0, 4.0), galley, Color32::BLACK);
    }

    // The sun calibration succeeded: the heading comes from the sun (pose::sun_heading), with
    // its 1σ. Same place as the gyro-only badge (the two never show together).
    if !g.gyro_only && g.heading_source == Some(crate::pose::HeadingSource::Sun) {
        let text = match g.heading_accuracy_deg {
            Some(a) => format!("{SUN_NORTH_TEXT} ±{a:.1}°"),
            None => SUN_NORTH_TEXT.to_string(),
        };
        let galley = painter.layout_no_wrap(text, FontId::proportional(18.0), Color32::BLACK);
        let rect = Rect::from_min_size(screen.left_top() + Vec2::new(14.0, 58.0), galley.size() + Vec2::new(16.0, 8.0));
        painter.rect_filled(rect, 6.0, SUN_NORTH_COLOUR);
        painter.galley(rect.min + Vec2::new(8.0, 4.0), galley, Color32::BLACK);
    }
    // Thumbnails of the faces, bottom left.
    let gap = 8.0;
    let y = screen.bottom() - THUMB - 28.0;
    for (i, face) in Face::ALL.iter().enumerate() {
        let rect = Rect::from_min_size(Pos2::new(screen.left() + 14.0 + i as f32 * (THUMB + gap), y), Vec2::splat(THUMB));
        let done = g.face_done[i] || g.phase == Phase::Complete;
        match &thumbs[i] {
            // A face with content shows it; the green frame once the face is done.
            Some(t) => {
                painter.image(t.id(), rect, Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)), Color32::WHITE);
                if done {
                    painter.rect_stroke(rect, 0.0, Stroke::new(2.0, Color32::from_rgb(60, 220, 90)), StrokeKind::Outside);
                } else {
                    painter.rect_stroke(rect, 0.0, Stroke::new(1.5, Color32::from_white_alpha(160)), StrokeKind::Inside);
                }
            }
            None => {
                painter.rect_filled(rect, 0.0, shade);
                painter.rect_stroke(rect, 0.0, Stroke::new(1.5, Color32::from_white_alpha(160)), StrokeKind::Inside);
            }
        }
        painter.text(rect.center_bottom() + Vec2::new(0.0, 3.0), Align2::CENTER_TOP, face.name(), FontId::proportional(14.0), white);
    }
}

/// Colour of a face that is taken (ring segment, thumbnail frame).
pub const DONE: Color32 = Color32::from_rgb(60, 220, 90);

/// A ring of six segments in [`Face::ALL`] order clockwise from the top, filled green for the
/// faces taken, outlined for the others.
pub fn draw_progress_ring(painter: &egui::Painter, centre: Pos2, radius: f32, done: &[bool; 6]) {
    let gap = 0.12;
    for (i, taken) in done.iter().enumerate() {
        let a0 = -std::f32::consts::FRAC_PI_2 + i as f32 * std::f32::consts::TAU / 6.0 + gap * 0.5;
        let a1 = a0 + std::f32::consts::TAU / 6.0 - gap;
        let points: Vec<Pos2> = (0..=12)
            .map(|k| {
                let a = a0 + (a1 - a0) * k as f32 / 12.0;
                centre + radius * Vec2::new(a.cos(), a.sin())
            })
            .collect();
        let stroke = if *taken { Stroke::new(8.0, DONE) } else { Stroke::new(8.0, Color32::from_white_alpha(90)) };
        painter.add(egui::Shape::line(points, stroke));
    }
    let n = done.iter().filter(|d| **d).count();
    painter.text(centre, Align2::CENTER_CENTER, format!("{n}/6"), FontId::proportional(16.0), Color32::WHITE);
}

/// The feedback of a shot `age_s` seconds after it was taken, for `for_s` seconds: a white
/// flash over the screen fading out, and a tick with the target's name.
pub fn draw_shot_feedback(ctx: &egui::Context, name: &str, age_s: f64, for_s: f64) {
    if !(0.0..for_s).contains(&age_s) {
        return;
    }
    let fade = 1.0 - (age_s / for_s) as f32;
    let screen = ctx.content_rect();
    let painter = ctx.layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("shot-feedback")));
    painter.rect_filled(screen, 0.0, Color32::from_white_alpha((150.0 * fade * fade) as u8));
    let c = screen.center() + Vec2::new(0.0, -90.0);
    let tick = [c + Vec2::new(-22.0, 0.0), c + Vec2::new(-6.0, 16.0), c + Vec2::new(24.0, -18.0)];
    painter.add(egui::Shape::line(tick.to_vec(), Stroke::new(8.0, DONE.gamma_multiply(fade.max(0.3)))));
    banner(&painter, c + Vec2::new(0.0, 42.0), &format!("{name} taken"), 20.0, Color32::WHITE, Color32::from_black_alpha(150));
}

/// The faces of a finished capture, large, as an unfolded cube (up above front, down below,
/// right, back and left beside it), with the next step written above.
pub fn draw_faces_preview(ctx: &egui::Context, thumbs: &[Option<egui::TextureHandle>; 6]) {
    let screen = ctx.content_rect();
    // Behind the windows and areas (the buttons), over the camera image.
    let painter = ctx.layer_painter(egui::LayerId::background());
    painter.rect_filled(screen, 0.0, Color32::from_black_alpha(200));
    let side = (screen.width() / 4.0).min(screen.height() / 3.6).floor();
    let origin = screen.center() - Vec2::new(2.0 * side, 1.5 * side);
    // Grid cells (column, row) in Face::ALL order: front, up, down, right, back, left.
    let cells = [(1.0, 1.0), (1.0, 0.0), (1.0, 2.0), (2.0, 1.0), (3.0, 1.0), (0.0, 1.0)];
    for (i, face) in Face::ALL.iter().enumerate() {
        let (cx, cy) = cells[i];
        let rect = Rect::from_min_size(origin + Vec2::new(cx * side, cy * side), Vec2::splat(side)).shrink(1.0);
        match &thumbs[i] {
            Some(t) => {
                painter.image(t.id(), rect, Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)), Color32::WHITE);
            }
            None => {
                painter.rect_filled(rect, 0.0, Color32::from_gray(40));
            }
        }
        painter.text(rect.left_top() + Vec2::new(4.0, 2.0), Align2::LEFT_TOP, face.name(), FontId::proportional(14.0), Color32::WHITE);
    }
    banner(
        &painter,
        Pos2::new(screen.center().x, screen.top() + 24.0),
        "Capture complete: it now lights the model",
        22.0,
        Color32::WHITE,
        Color32::from_black_alpha(150),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thumbnail_is_a_box_filtered_centre_crop() {
        // 4x2 image: left two columns black, right two white -> centre 2x2 crop is columns 1..3,
        // so a 1x1 thumbnail averages black and white: 127.
        let mut pixels = Vec::new();
        for _ in 0..2 {
            for x in 0..4 {
                let v = if x < 2 { 0 } else { 255 };
                pixels.extend_from_slice(&[v, v, v, 255]);
            }
        }
        let img = Rgba8Image { width: 4, height: 2, pixels };
        let t = thumbnail(&img, 1);
        assert_eq!(t.pixels[0], Color32::from_rgb(127, 127, 127));
        let t = thumbnail(&img, 2);
        assert_eq!(t.pixels[0], Color32::from_rgb(0, 0, 0));
        assert_eq!(t.pixels[1], Color32::from_rgb(255, 255, 255));
        let empty = Rgba8Image { width: 0, height: 0, pixels: vec![] };
        assert_eq!(thumbnail(&empty, 3).pixels.len(), 9);
    }
}
