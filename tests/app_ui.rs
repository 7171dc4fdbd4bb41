//! The composite mode's control panel driven by synthetic egui input, as a finger or mouse would
//! drive it: dragging SL to 0 takes the sun out of the frame (no sunlit highlight, no shadow).

use crate::common;

use common::{gpu, inputs, scene};
use previz::render::Layer;
use previz::setup::prepare;
use previz::ui::controls::Controls;

const SCENE: &str = "width = 240\nheight = 160\nenvironment = \"cubemaps/humus_Park2_512\"\nmodel = \"meshes/stanford-bunny.obj\"\n\
[camera]\nheading = 90.0\npitch = -10.0\n[sun]\ndirection = [0.0, 0.9, 0.35]\n";

/// Run one egui pass over the panel with `events`, at 800×600 points, where the app places it.
fn pass(ctx: &egui::Context, controls: &mut Controls, events: Vec<egui::Event>) -> egui::FullOutput {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(800.0, 600.0))),
        events,
        ..Default::default()
    };
    let mut out = ctx.run_pass(input, |ctx| {
        controls.show(ctx, previz::ui::layout::composite_regions(ctx.content_rect()).controls);
    });
    // The font atlas uploads a renderer would take (egui asserts they were taken).
    out.textures_delta.set.drain().for_each(drop);
    out.textures_delta.free.drain().for_each(drop);
    out
}

/// The rectangles of the text shapes in a pass's output whose text is `text`.
fn text_rects(out: &egui::FullOutput, pred: impl Fn(&str) -> bool) -> Vec<egui::Rect> {
    out.shapes
        .iter()
        .filter_map(|s| match &s.shape {
            egui::Shape::Text(t) if pred(t.galley.text()) => Some(t.visual_bounding_rect()),
            _ => None,
        })
        .collect()
}

#[test]
fn dragging_sl_to_zero_removes_the_sun_highlight_and_shadow() {
    let s = scene(SCENE);
    let inp = inputs(&s);
    let (mut compositor, mut params) = prepare(gpu(), &s, &inp).unwrap();
    let sun = params.lighting.sunlight;
    assert!(sun > 0.5, "the scene has sunlight");

    // The panel as the app shows it; find the SL slider's row and its value box, press on the
    // slider rail just left of the value and drag far to the left, as a finger would.
    let ctx = egui::Context::default();
    let mut controls = Controls::from_params(&params);
    // Windows size themselves in their first pass and show from the second.
    pass(&ctx, &mut controls, vec![]);
    let first = pass(&ctx, &mut controls, vec![]);
    let label = text_rects(&first, |t| t == "SL sunlight");
    assert_eq!(label.len(), 1, "one SL label");
    let row = label[0];
    let value = text_rects(&first, |t| t.parse::<f32>().is_ok())
        .into_iter()
        .filter(|r| (r.center().y - row.center().y).abs() < 2.0 && r.right() <= row.left())
        .max_by(|a, b| a.left().total_cmp(&b.left()))
        .expect("the SL value box left of its label");
    let press = egui::pos2(value.left() - 40.0, row.center().y);
    let far_left = egui::pos2(0.0, row.center().y);
    let button =
        |pos, pressed| egui::Event::PointerButton { pos, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() };
    pass(&ctx, &mut controls, vec![egui::Event::PointerMoved(press), button(press, true)]);
    pass(&ctx, &mut controls, vec![egui::Event::PointerMoved(far_left)]);
    pass(&ctx, &mut controls, vec![button(far_left, false)]);
    assert_eq!(controls.sunlight, 0.0, "SL dragged to the left end (label {row:?}, value {value:?}, pressed at {press:?})");
    let untouched = Controls { sunlight: 0.0, ..Controls::from_params(&params) };
    assert_eq!(controls, untouched, "only SL moved");

    // With SL at 0 the sun's direction no longer changes a single pixel of the composite (no
    // sunlit highlight, no cast shadow); at SL 1 it does, and the model casts a shadow: ground
    // pixels outside the model darker than the camera image.
    let render = |params: &previz::render::FrameParams, compositor: &mut previz::render::Compositor, layer| {
        compositor.render(gpu(), params, layer).unwrap().rgba
    };
    let background = render(&params, &mut compositor, Layer::Background);
    let model = render(&params, &mut compositor, Layer::Model);
    let shadowed = |img: &[u8]| {
        (0..img.len() / 4)
            .filter(|&i| model[4 * i + 3] == 0 && (0..3).all(|c| i32::from(img[4 * i + c]) + 6 < i32::from(background[4 * i + c])))
            .count()
    };
    let lit = render(&params, &mut compositor, Layer::Composite);
    let mut turned = params;
    turned.lighting.sun_dir = glam::Vec3::new(-0.6, 0.2, 0.77).normalize();
    let lit_turned = render(&turned, &mut compositor, Layer::Composite);
    assert!(lit != lit_turned, "with sunlight the sun's direction shows");
    assert!(shadowed(&lit) > 100, "the sun casts a shadow: {} ground pixels darker", shadowed(&lit));

    controls.apply(&mut params, sun);
    assert_eq!(params.lighting.sunlight, 0.0);
    let dark = render(&params, &mut compositor, Layer::Composite);
    let mut dark_turned = params;
    dark_turned.lighting.sun_dir = turned.lighting.sun_dir;
    assert!(dark == render(&dark_turned, &mut compositor, Layer::Composite), "SL 0: the sun's direction changes nothing");
    assert_eq!(shadowed(&dark), 0, "SL 0: no ground pixel darker than the camera image");
}
