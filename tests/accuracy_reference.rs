//! The default lighting method against committed path-traced references (issue 9):
//! tests/reference/images/NAME.png were rendered by tests/reference/render_reference.py (Mitsuba
//! 3, 256 spp; command in tests/reference/README.md) from the scenes in tests/reference/scenes.
//! A change that makes the default method's mean FLIP in the region of interest (model + its
//! shadow) worse than measured turns this red. The bounds are today's measurements plus 0.01
//! (docs/accuracy.md), NOT the goal of 0.06: the default method does not reach it yet.
//! The model's mean luminance is held near the reference's too.
//! Light comes from the environment (setup::light: the map's sun, SH9 sky, measured shadow).

use crate::common;

use previz::bench::accuracy::{load_reference, score};
use previz::cli::composite::{SceneArgs, scene_from_args};
use previz::render::Layer;
use previz::setup::load_inputs;
use std::path::Path;

/// (scene, largest allowed mean FLIP over the region of interest, largest allowed error of the
/// model's mean luminance against the reference's as a fraction).
/// Measured 2026-11-30 with the default `sh9-ggx` method (the scenes declare the references'
/// Lambertian material): ROI FLIP 0.180, 0.118, 0.211, 0.159 and luminance ratios 0.99, 1.03,
/// 1.44, 1.03 (the dragon lacks self-occlusion); bounds = measured + 0.01 FLIP and + 0.03 on
/// the luminance error. With per-vertex ambient occlusion (scene::occlusion, multi-bounce fit
/// for the material's albedo): 0.180, 0.121, 0.200, 0.156 and 0.97, 0.99, 1.32, 1.02 (plain AO
/// without the fit: 0.183, 0.130, 0.188, 0.152 and 0.95, 0.93, 1.14, 1.00); the dragon's bounds
/// tightened to 0.21 and 0.35. With the ground's sky occlusion drawn (2026-12-01, contact
/// shadows): 0.170, 0.106, 0.191, 0.127 and 0.97, 0.98, 1.32, 1.02; bounds tightened to the
/// measurement plus 0.01 FLIP and plus 0.03 on the luminance error, never loosened. The textured
/// scene quarry_truck (added 2026-12-01): 0.151 and 1.05. Fifth session (2026-12-01): the ground's
/// shadow in colour (each channel loses its own share) and the lower hemisphere bounded by what
/// its sky can light: 0.139, 0.106, 0.176, 0.122, 0.140 and 0.97, 0.98, 1.26, 1.02, 1.05; bounds =
/// measured + 0.01 FLIP (three decimals) and the dragon's luminance error measured + 0.03. Before:
/// `hemisphere` 0.237, 0.146, 0.281, 0.279 (constant light: 0.469, 0.209, 0.264, 0.361).
/// Sixth session (2026-12-01): the ground's sky occlusion weighted by the sky's radiance (a
/// directional sky is hidden by the light the model hides, by the sky's nine harmonics then): 0.133, 0.093,
/// 0.152, 0.106, 0.134 and 0.97, 0.99, 1.26, 1.02, 1.04; bounds = measured + 0.01 FLIP, the
/// truck's luminance error measured + 0.03.
/// Seventh session (2026-12-01): the model lit from below by the references' ground (a uniform
/// plane of the map's mean ground radiance, shadowed by the model, scene::occlusion::
/// model_sky_ground) instead of the map's lower hemisphere: 0.129, 0.090, 0.128, 0.098, 0.137 and
/// 0.96, 0.96, 1.06, 1.01, 1.00; bounds = measured + 0.01 FLIP (quarry_truck's 0.137 + 0.01 would
/// loosen its 0.144: kept), luminance errors measured + 0.03 where that tightens them (dragon
/// 0.29 → 0.09, truck 0.07 → 0.04; the bunny's 0.036 and blouberg's 0.041 keep 0.04 and 0.05).
/// Eighth session (2026-12-01, s8-bg): the background looked up in the equirect, not through the
/// cube map: ROI 0.1285, 0.0904, 0.1282, 0.0980, 0.1361 (unchanged within 0.0003; the frame's FLIP
/// 0.039, 0.018, 0.053, 0.031, 0.044 → 0.0299, 0.0171, 0.0400, 0.0193, 0.0360) and luminance
/// 0.964, 0.959, 1.059, 1.013, 1.001; bounds = measured + 0.01 rounded up to three decimals:
/// city_spot 0.109 → 0.108, the others as they were.
/// Eighth session (2026-12-01): large triangles sampled inside, each vertex the hat-weighted mean
/// of its triangles' light (scene::occlusion::model_sky_ground): quarry_truck 0.137 → 0.128 and
/// luminance 1.00 → 1.03, the others unchanged; the truck's bound 0.144 → 0.138 (its luminance
/// error's 0.04 kept: measured + 0.03 would loosen it). Then the sky looked up along each
/// vertex's bent normal (the mean direction of its rays that pass the model): 0.128, 0.090,
/// 0.125, 0.092, 0.126 and 0.97, 0.97, 1.00, 0.99, 1.03; bounds = measured + 0.01 FLIP, the
/// dragon's and Spot's luminance errors 0.09 → 0.04 and 0.05 → 0.04 (measured 0.002 and 0.006,
/// plus 0.03, rounded up).
/// Eighth session (2026-12-01, s8-shadow, measured on its own branch): the ground gets the light
/// the model reflects onto it (render::passes::ground::bounce_light): 0.102, 0.082, 0.126, 0.098, 0.125, luminance unchanged;
/// bounds = measured + 0.01 FLIP.
/// Merged main (2026-12-01 17:25 UTC, s8-bg + s8-model + s8-shadow + s8-raster + s8-shade): ROI
/// 0.1010, 0.0819, 0.1217, 0.0913, 0.1140 (mean 0.102), luminance 0.969, 0.971, 1.005, 0.994,
/// 1.027; bounds = measured + 0.01 rounded up to three decimals (luminance errors kept where
/// measured + 0.03 would loosen them).
/// Ninth session (2026-12-01 19:17 UTC, s9-diffuse): the ground's sky visibility under the model
/// weighted by the sky's radiance in 256 bins (light::sh9::SkyRadiance) instead of its nine
/// harmonics, 256 rays a texel instead of 64: ROI 0.0878, 0.0572, 0.0934, 0.0803, 0.1090 (mean
/// 0.086, was 0.102), luminance 0.969, 0.971, 1.005, 0.994, 1.027 (unchanged: the model is not
/// touched); bounds = measured + 0.01 rounded up to three decimals.
/// Tenth session (2026-12-01 22:37 UTC, s10-ground): the ground's rays one in each of the sky's
/// 256 bins (scene::occlusion::sky_rays) instead of 256 cosine-distributed ones: ROI 0.08642,
/// 0.05584, 0.09226, 0.08001, 0.1089 (mean 0.0847, was 0.0855), frame and luminance unchanged
/// within 0.0005; bounds = measured + 0.01 rounded up to three decimals where that is tighter
/// (quarry_bunny 0.098 → 0.097, blouberg_teapot 0.068 → 0.066, courtyard_dragon 0.104 → 0.103;
/// city_spot's 0.09001 and quarry_truck's 0.1189 keep 0.091 and 0.119).
/// Tenth session (2026-12-01 22:05 UTC, s10-model): `sh9-ggx` draws the model as loaded, not the
/// level of detail the half-pixel rule picks (its diffuse light follows the interpolated normals,
/// which the rule does not bound; render::LightingMethod::draws_as_loaded): ROI 0.0781, 0.0510,
/// 0.0933, 0.0632, 0.0831 (mean 0.074, was 0.086), luminance 0.983, 1.007, 1.016, 1.008, 0.988;
/// bounds = measured + 0.01 rounded up to three decimals (the dragon's 0.104 as it was),
/// blouberg_teapot's luminance error 0.05 → 0.04 (measured 0.007 + 0.03, rounded up).
/// The same session (22:54 UTC, s10-model) replaced drawing as loaded by the level rule that draws
/// the finest level within half a pixel whose triangles cover 2 px² or more
/// (scene::lod::finest_worth_drawing): the truck and the teapot at level 0, Spot at level 1, the
/// bunny and the dragon at main's level 5: ROI 0.0878, 0.0510, 0.0934, 0.0693, 0.0831 (mean
/// 0.077), luminance 0.969, 1.007, 1.005, 1.008, 0.988; every bound above still holds and is
/// kept.
/// Merged main of the tenth session (23:11 UTC: s10-ground + s10-sun-cost + s10-clip + s10-model):
/// ROI 0.0864, 0.0497, 0.0923, 0.0689, 0.0828 (mean 0.076), luminance 0.969, 1.007, 1.005, 1.008,
/// 0.988; bounds = measured + 0.01 rounded up to three decimals.
/// Eleventh session (s11-selfshadow, 2026-12-02, debug: the soft sun lookup's blocker search
/// counts only blockers inside the sun's cone on the model's own surface, so a surface the sun
/// grazes no longer shadows itself): ROI 0.0863, 0.0497, 0.0923, 0.0688, 0.0701 (mean 0.0734, was
/// 0.0760), luminance 0.969, 1.007, 1.005, 1.008, 1.015; quarry_truck's bound 0.093 → 0.081
/// (measured + 0.01 rounded up; its luminance error's 0.04 kept: measured + 0.03 would loosen it),
/// the others as they were.
/// Twelfth session (s12-penumbra, 2026-12-02, debug: the soft lookup's filter spreads an edge
/// as the sun's disc does, 0.61 penumbrae between taps instead of 0.83): ROI 0.08588, 0.04966,
/// 0.09225, 0.06861, 0.06964 (mean 0.07321, was 0.07343), luminance 0.9695, 1.0072, 1.0053,
/// 1.0082, 1.0145; quarry_bunny's bound 0.097 → 0.096 and quarry_truck's 0.081 → 0.080
/// (measured + 0.01 rounded up), the others as they were.
/// Twelfth session (2026-12-02 05:40 UTC, s12-mip on main ef8f19d, debug): the model's
/// textures with their mip chain, sampled at a bias of -1.5 levels (shaders/model.wgsl): ROI
/// 0.0863, 0.0497, 0.0923, 0.0688, 0.0699 (the truck's was 0.0701), luminance 0.969, 1.007,
/// 1.005, 1.008, 1.016 (the truck's was 1.015); the truck's bound 0.081 -> 0.080 (measured + 0.01
/// rounded up), the others kept.
/// Twelfth session (s12-skybounce, 2026-12-02 05:22 UTC, debug): the model's sky from each
/// vertex's own open rays weighted by the sky's binned radiance, plus the light of that sky the
/// model's own surfaces reflect onto it, measured from what the rays meet (scene::occlusion::
/// ModelRays::sky), instead of SH9 along the bent normal × the sky share and the multi-bounce fit:
/// ROI 0.0843, 0.0469, 0.0896, 0.0579, 0.0698 (mean 0.0697, was 0.0734), luminance 0.967, 1.000,
/// 1.002, 0.999, 0.984; bounds = measured + 0.01 rounded up to three decimals; luminance errors
/// measured + 0.03 rounded up where that tightens them (blouberg_teapot 0.031, courtyard_dragon
/// 0.033, city_spot 0.032).
/// Twelfth session, merged main (s12-penumbra, s12-mip and s12-skybounce together, 2026-12-02
/// 06:33 UTC, debug): ROI 0.0838, 0.0469, 0.0896, 0.0577, 0.0691 (mean 0.0694), luminance 0.967,
/// 1.000, 1.002, 0.998, 0.983; quarry_bunny's bound 0.095 -> 0.094 (measured + 0.01 rounded up),
/// the others as s12-skybounce set them (each within measured + 0.01).
/// Thirteenth session (2026-12-02 08:35 UTC, debug): a still draws triangles down to a pixel
/// (render::Detail::Still: the bunny's level 4 instead of 5, the dragon's 4 instead of 5, Spot's
/// 0 instead of 1), and sh9-ggx's sky colour fades to the mean sky's where SH9 rings: ROI
/// 0.07416, 0.04676, 0.08612, 0.05106, 0.06911 (mean 0.0654, was 0.0694), luminance 0.979,
/// 1.000, 0.993, 0.997, 0.983; bounds = measured + 0.01 rounded up to three decimals
/// (quarry_bunny 0.094 -> 0.085, courtyard_dragon 0.100 -> 0.097, city_spot 0.068 -> 0.062),
/// luminance errors kept (measured + 0.03 would loosen each). Then an unclipped sun's aureole
/// lit and shadowed as the sun (light::sun_finder::aureole; 08:55 UTC): ROI 0.06971, 0.04676,
/// 0.08641, 0.05098, 0.06619 (mean 0.0640), luminance 0.977, 1.000, 0.992, 0.996, 0.981; bounds
/// measured + 0.01 (quarry_bunny 0.080, city_spot 0.061, quarry_truck 0.077).
/// Fourteenth session (2026-12-02 11:50 UTC, debug): a still supersampled 3 × 3, one sample
/// each, and box-filtered in linear light, as the references integrate a pixel
/// (render::supersample): ROI 0.06100, 0.04629, 0.08520, 0.04910, 0.05606 (mean 0.0595),
/// luminance 0.979, 1.002, 0.978, 1.000, 0.975; bounds measured + 0.01 rounded up (quarry_bunny
/// 0.071, courtyard_dragon 0.096, city_spot 0.060, quarry_truck 0.067), luminance errors kept.
/// Fifteenth session (2026-12-02 14:15 UTC, debug): the ground loses the sky's light per colour
/// channel, each channel's rays weighted by that channel of the sky's bins (SkyRadiance::tint,
/// GroundTransfer::map): ROI 0.04997, 0.03014, 0.06462, 0.04804, 0.05038 (mean 0.0486),
/// luminance 0.979, 1.002, 0.978, 1.000, 0.975 (unchanged: the model is not drawn differently);
/// bounds measured + 0.01 rounded up (quarry_bunny 0.060, blouberg_teapot 0.041,
/// courtyard_dragon 0.075, city_spot 0.059, quarry_truck 0.061), luminance errors kept. Then the
/// model's sky in the colour of its own rays (pipelines::Vertex::tint, ModelRays::sky_channels;
/// 15:20 UTC): ROI 0.04974, 0.02960, 0.05928, 0.04920, 0.05144 (mean 0.0479), luminance 0.979,
/// 1.002, 0.978, 1.000, 0.975; blouberg_teapot's bound 0.041 -> 0.040 and courtyard_dragon's
/// 0.075 -> 0.070 (measured + 0.01 rounded up); city_spot's 0.059 and quarry_truck's 0.061 are
/// kept (measured + 0.0098 and + 0.0096: Spot 0.0012 and the truck 0.0011 worse than with the
/// sky's SH9 colour).
const BOUNDS: [(&str, f32, f32); 5] = [
    ("quarry_bunny", 0.060, 0.04),
    ("blouberg_teapot", 0.040, 0.031),
    ("courtyard_dragon", 0.070, 0.033),
    ("city_spot", 0.059, 0.032),
    ("quarry_truck", 0.061, 0.04),
];

/// (scene, largest allowed mean FLIP over the whole frame): most of the frame is the background,
/// so this holds the background's agreement with the references' (eighth session, 2026-12-01:
/// the background looked up in the equirect, frame FLIP 0.039, 0.018, 0.053, 0.031, 0.044 through
/// the cube map → 0.0299, 0.0171, 0.0400, 0.0193, 0.0360; bounds = measured + 0.01 rounded up to
/// three decimals, one thousandth more for courtyard_dragon and quarry_truck, whose sums land on a
/// thousandth within the unprinted fifth decimal). The cube-map background fails city_spot and
/// courtyard_dragon. Merged main (the ground's bounce too): 0.0273, 0.0174, 0.0371, 0.0214, 0.0353;
/// tightened to measured + 0.01 where that is tighter. Ninth session (the ground's rays weighted
/// by the sky's binned radiance): 0.0255, 0.0153, 0.0317, 0.0194, 0.0308; tightened the same way.
/// Tenth session (sh9-ggx draws the model as loaded): 0.0246, 0.0149, 0.0316, 0.0181, 0.0263;
/// tightened the same way (the dragon's 0.042 as it was). The level rule (same session): 0.0255,
/// 0.0149, 0.0317, 0.0186, 0.0263; the bounds above hold and are kept. Eleventh session (the
/// model's own surface not a blocker of itself): 0.0253, 0.0148, 0.0313, 0.0182, 0.0241; the
/// truck's tightened to 0.035, the others kept. Twelfth session (the model's sky and its bounce
/// from its own rays): 0.0251, 0.0146, 0.0309, 0.0174, 0.0240; the dragon's tightened to 0.041
/// and Spot's to 0.028, the others kept. Thirteenth session (a still draws triangles down to a
/// pixel): 0.0241, 0.0146, 0.0303, 0.0169, 0.0239; quarry_truck's tightened to 0.034, city_spot's
/// to 0.027. Fourteenth session (a supersampled still): 0.0227, 0.0146, 0.0306, 0.0165, 0.0214;
/// quarry_bunny's tightened to 0.033, quarry_truck's to 0.032, the others kept. Fifteenth session
/// (the ground's sky lost per channel): 0.0212, 0.0134, 0.0268, 0.0164, 0.0203; each tightened to
/// measured + 0.01 rounded up (Spot's 0.027 as it was). The model's sky in its rays' colour:
/// 0.0212, 0.0134, 0.0260, 0.0165, 0.0205; the dragon's tightened to 0.036, the others kept.
const FRAME_BOUNDS: [(&str, f32); 5] =
    [("quarry_bunny", 0.032), ("blouberg_teapot", 0.024), ("courtyard_dragon", 0.036), ("city_spot", 0.027), ("quarry_truck", 0.031)];

#[test]
fn default_method_against_path_traced_references() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference");
    for (name, bound, luminance_error) in BOUNDS {
        let reference = load_reference(&root.join("images"), name).unwrap();
        let args = SceneArgs { scene: Some(root.join("scenes").join(format!("{name}.toml"))), ..Default::default() };
        let (scene, demo) = scene_from_args(&args, None).unwrap();
        let inputs = load_inputs(&scene, demo).unwrap();
        let image = common::render_with(&scene, &inputs, Layer::Composite);
        let rgb: Vec<u8> = image.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        let (frame, roi, luminance) = score(&reference, &rgb).unwrap();
        eprintln!("{name}: {}: FLIP frame {frame:.4}, ROI {roi:.5}, model luminance / reference {luminance:.4}", scene.method.name());
        assert!(roi <= bound, "{name}: mean FLIP in the model + shadow {roi:.3} > {bound}");
        let frame_bound = FRAME_BOUNDS.iter().find(|(n, _)| *n == name).map(|(_, b)| *b).unwrap();
        assert!(frame <= frame_bound, "{name}: mean FLIP over the frame {frame:.3} > {frame_bound}");
        assert!(
            (luminance - 1.0).abs() <= luminance_error,
            "{name}: model luminance / reference {luminance:.2}, off by more than {luminance_error}"
        );
    }
}

/// Clipped-map recovery (issue 9's goal: within mean FLIP 0.10 of the full map's reference):
/// quarry_bunny with quarry_01 scaled by 0.25 and clipped at 1.0 (as tests/reference/clip_hdr.py
/// writes it, without its RGBE rounding), at the full map's exposure / 0.25, against the full
/// map's path-traced reference. The restore (light::measure) sees a map whose values are all
/// at most 1, so an 8-bit one, and restores its sun: centred on the aureole around the saturated
/// blob (light::aureole), its share of the ground's light from the sand's colours
/// (light::ground_split) in the colour of the beam through the atmosphere that has the ground's
/// direct-to-diffuse ratio (light::measure::beam_turbidity), the real sun's angular size.
/// Measured 2026-12-01 (tenth session): ROI FLIP 0.0930 (`previz bench accuracy` on the
/// clip_hdr.py map: 0.093), luminance 0.983; before (merged main, ninth session): 0.1107. The
/// full map itself scores 0.0878. Bound: the goal, 0.10 (measured + 0.01 would be 0.103).
/// Thirteenth session (a still draws triangles down to a pixel): 0.08135, luminance 0.993;
/// bound measured + 0.01 rounded up, 0.092. Fourteenth session (a supersampled still): 0.07312,
/// luminance 0.995; bound 0.084. Fifteenth session (the ground's sky lost per channel): 0.06375,
/// luminance 0.995; bound 0.074. The model's sky in its rays' colour: 0.06364, luminance 0.995.
#[test]
fn a_clipped_map_lights_the_model_within_the_goal_of_the_full_maps_reference() {
    use previz::scene::environment::Equirect;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference");
    let name = "quarry_bunny";
    let reference = load_reference(&root.join("images"), name).unwrap();
    let args = SceneArgs { scene: Some(root.join("scenes").join(format!("{name}.toml"))), ..Default::default() };
    let (mut scene, demo) = scene_from_args(&args, None).unwrap();
    let mut inputs = load_inputs(&scene, demo).unwrap();
    let scale = 0.25f32;
    let full = inputs.env_equirect.clone().expect("quarry_bunny's map is an equirect");
    let clipped: Vec<[f32; 3]> = full.pixels().iter().map(|p| p.map(|c| (c * scale).min(1.0))).collect();
    let clipped = Equirect::new(full.width(), full.height(), clipped).unwrap();
    scene.env.exposure = Some(f64::from(previz::setup::exposure(&scene, &inputs.env) / scale));
    inputs.env = clipped.to_cube(clipped.default_face_size(), 0.0);
    inputs.env_equirect = Some(std::sync::Arc::new(clipped));
    let light = previz::setup::measure_environment(&scene, &inputs.env).unwrap();
    assert_eq!(light.source, previz::light::measure::SunSource::Restored, "the clipped sun is restored");
    let image = common::render_with(&scene, &inputs, Layer::Composite);
    let rgb: Vec<u8> = image.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    let (frame, roi, luminance) = score(&reference, &rgb).unwrap();
    eprintln!(
        "{name} clipped: FLIP frame {frame:.4}, ROI {roi:.5}, model luminance / reference {luminance:.4}, beam turbidity {:?}",
        light.beam_turbidity
    );
    assert!(roi <= 0.074, "clipped {name}: mean FLIP in the model + shadow {roi:.4} > 0.074");
    assert!((luminance - 1.0).abs() <= 0.04, "clipped {name}: model luminance / reference {luminance:.3}");
}
