// Colour correction of the model, per fragment: FUNCTIONS ONLY (no bindings, no entry points).
// The model shader (and priors_reduce.wgsl) concatenate this file in front of their own code.
//
// Everything here works on LINEAR-LIGHT RGB. Mirrors the CPU reference in app/src/colour/
// (lab.rs, intensity.rs, correction.rs); tests run both on the same colours and compare.

// The uniform. Mirrored once in Rust: previz::colour::correction::ColourCorrection (layout
// checked against naga's reflection of this struct in a test). Built on the CPU from the
// environment and model priors: the transfer methods are reduced to one affine map in lαβ.
struct ColourCorrection {
    // lab' = transfer * lab + offset, in log lαβ (methods 2, 4) or lαβ without log (method 3).
    transfer: mat3x3<f32>,
    offset: vec3<f32>,
    // 0 none, 1 brightness-contrast, 2 reinhard, 3 cielab-approx, 4 mkl.
    method: u32,
    // 0..1: mix(input, corrected, strength) in linear RGB (the seed's CC slider).
    strength: f32,
    // Environment luminance levels, linear BT.709 Y (method 1): low <= mean <= high.
    lum_low: f32,
    lum_mean: f32,
    lum_high: f32,
}

// Reinhard et al. 2001 RGB -> LMS (with 0.1228 for (S,G), see app/src/colour/lab.rs), columns.
const COLOUR_RGB_TO_LMS: mat3x3<f32> = mat3x3<f32>(
    vec3<f32>(0.3811, 0.1967, 0.0241),
    vec3<f32>(0.5783, 0.7244, 0.1228),
    vec3<f32>(0.0402, 0.0782, 0.8444),
);
// Its exact inverse.
const COLOUR_LMS_TO_RGB: mat3x3<f32> = mat3x3<f32>(
    vec3<f32>(4.467795416157, -1.218527611928, 0.049693653737),
    vec3<f32>(-3.586967404271, 2.380764808674, -0.243855997231),
    vec3<f32>(0.119487772720, -0.162471575129, 1.204490589890),
);
// diag(1/sqrt3, 1/sqrt6, 1/sqrt2) * [[1,1,1],[1,1,-2],[1,-1,0]], columns; its inverse is its transpose.
const COLOUR_LMS_TO_LAB: mat3x3<f32> = mat3x3<f32>(
    vec3<f32>(0.5773502692, 0.4082482905, 0.7071067812),
    vec3<f32>(0.5773502692, 0.4082482905, -0.7071067812),
    vec3<f32>(0.5773502692, -0.8164965809, 0.0),
);
// Offset before the log (app/src/colour/lab.rs LOG_OFFSET): black -> -3, not -inf.
const COLOUR_LOG_OFFSET: f32 = 1e-3;
const COLOUR_LOG10_2: f32 = 0.30102999566;
const COLOUR_LOG2_10: f32 = 3.32192809489;
// Below this luminance a pixel is black (no chromaticity).
const COLOUR_BLACK: f32 = 1e-6;
// Smallest luminance range treated as non-degenerate.
const COLOUR_MIN_RANGE: f32 = 1e-6;

// sRGB-encoded -> linear light (IEC 61966-2-1).
fn colour_srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// BT.709 relative luminance of linear RGB.
fn colour_luminance(rgb: vec3<f32>) -> f32 {
    return dot(rgb, vec3<f32>(0.2126, 0.7152, 0.0722));
}

// Linear RGB -> lab (log lαβ when use_log, else lαβ without the log).
fn colour_rgb_to_lab(rgb: vec3<f32>, use_log: bool) -> vec3<f32> {
    let lms = COLOUR_RGB_TO_LMS * rgb;
    let logged = log2(max(lms, vec3<f32>(0.0)) + COLOUR_LOG_OFFSET) * COLOUR_LOG10_2;
    return COLOUR_LMS_TO_LAB * select(lms, logged, use_log);
}

// Inverse of colour_rgb_to_lab (not clamped).
fn colour_lab_to_rgb(lab: vec3<f32>, use_log: bool) -> vec3<f32> {
    let lms = transpose(COLOUR_LMS_TO_LAB) * lab;
    let unlogged = exp2(lms * COLOUR_LOG2_10) - COLOUR_LOG_OFFSET;
    return COLOUR_LMS_TO_RGB * select(lms, unlogged, use_log);
}

// smoothstep that is a step at e0 when e1 - e0 < COLOUR_MIN_RANGE (WGSL leaves that undefined).
fn colour_smoothstep_safe(e0: f32, e1: f32, x: f32) -> f32 {
    let t = clamp((x - e0) / max(e1 - e0, COLOUR_MIN_RANGE), 0.0, 1.0);
    return select(t * t * (3.0 - 2.0 * t), select(0.0, 1.0, x >= e0), e1 - e0 < COLOUR_MIN_RANGE);
}

// Output luminance of the brightness/contrast correction (app/src/colour/intensity.rs).
fn colour_fit_luminance(y: f32, low: f32, mean: f32, high: f32) -> f32 {
    let t = colour_smoothstep_safe(low, high, y);
    let brightness = mix(low, high, t);
    var contrast: f32;
    if (t < 0.5) {
        contrast = mix(low, mean, 2.0 * t);
    } else {
        contrast = mix(mean, high, 2.0 * t - 1.0);
    }
    return 0.5 * (brightness + contrast);
}

// Brightness/contrast at strength 1: luminance mapped into the environment's levels,
// chromaticity kept.
fn colour_correct_intensity(rgb_in: vec3<f32>, cc: ColourCorrection) -> vec3<f32> {
    let rgb = max(rgb_in, vec3<f32>(0.0));
    let y = colour_luminance(rgb);
    let y_out = colour_fit_luminance(y, cc.lum_low, cc.lum_mean, cc.lum_high);
    if (y > COLOUR_BLACK) {
        return rgb * (y_out / y);
    }
    return vec3<f32>(y_out);
}

// The correction before clamping and strength. Every method's result is computed and the
// method's chosen with select: lavapipe recompiles a shader that branches on uniform values
// alone at each bind (gpu::uniform_branches), several milliseconds a frame.
fn colour_correct_unclipped(rgb: vec3<f32>, cc: ColourCorrection) -> vec3<f32> {
    let use_log = cc.method != 3u;
    let transferred = colour_lab_to_rgb(cc.transfer * colour_rgb_to_lab(rgb, use_log) + cc.offset, use_log);
    let intensity = colour_correct_intensity(rgb, cc);
    let lab_method = (cc.method >= 2u) & (cc.method <= 4u);
    return select(select(rgb, intensity, cc.method == 1u), transferred, lab_method);
}

// The model's colour correction: linear RGB in, linear RGB out. Negative results (out of
// gamut) are clamped to 0; values above 1 are kept (HDR; the target format clamps or the tone
// mapper compresses). Then mixed with the input by strength.
fn colour_correct(rgb_linear: vec3<f32>, cc: ColourCorrection) -> vec3<f32> {
    let corrected = max(colour_correct_unclipped(rgb_linear, cc), vec3<f32>(0.0));
    return mix(rgb_linear, corrected, clamp(cc.strength, 0.0, 1.0));
}
