// Post-process antialiasing (FXAA-style, after T. Lottes, "FXAA", NVIDIA white paper 2009): the
// single-sampled frame is read back once and each pixel on a luma edge is re-sampled part of a
// pixel across the edge, by how far it sits from the edge's ends (edge search) or by how much it
// stands out from its neighbourhood (sub-pixel aliasing), whichever is larger.

@group(0) @binding(0) var aa_src: texture_2d<f32>;
@group(0) @binding(1) var aa_smp: sampler;

// Local contrast below this fraction of the brightest neighbour is not an edge...
const EDGE_THRESHOLD: f32 = 0.125;
// ...nor below this absolute contrast (dark areas).
const EDGE_THRESHOLD_MIN: f32 = 0.0312;
// How much sub-pixel aliasing is removed (0 none, 1 full blur of isolated pixels).
const SUBPIXEL: f32 = 0.75;
// One-pixel steps searched along the edge in each direction.
const SEARCH_STEPS: i32 = 12;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> FullScreen {
    return full_screen(index);
}

// Perceptual luma of a linear colour (the square root stands in for the sRGB curve).
fn luma(c: vec4<f32>) -> f32 {
    return sqrt(dot(c.rgb, vec3<f32>(0.299, 0.587, 0.114)));
}

fn at(uv: vec2<f32>) -> vec4<f32> {
    return textureSampleLevel(aa_src, aa_smp, uv, 0.0);
}

fn luma_at(uv: vec2<f32>) -> f32 {
    return luma(at(uv));
}

@fragment
fn fs_main(in: FullScreen) -> @location(0) vec4<f32> {
    let px = 1.0 / vec2<f32>(textureDimensions(aa_src));
    // The pixel's centre (the fragment position is at pixel centres).
    let uv = in.clip.xy * px;
    let centre = at(uv);
    let m = luma(centre);
    // Image rows go down: "n" is the row above.
    let n = luma_at(uv + vec2<f32>(0.0, -px.y));
    let s = luma_at(uv + vec2<f32>(0.0, px.y));
    let e = luma_at(uv + vec2<f32>(px.x, 0.0));
    let w = luma_at(uv + vec2<f32>(-px.x, 0.0));
    let lo = min(m, min(min(n, s), min(e, w)));
    let hi = max(m, max(max(n, s), max(e, w)));
    let range = hi - lo;
    if range < max(EDGE_THRESHOLD_MIN, hi * EDGE_THRESHOLD) {
        return centre;
    }
    let nw = luma_at(uv - px);
    let se = luma_at(uv + px);
    let ne = luma_at(uv + vec2<f32>(px.x, -px.y));
    let sw = luma_at(uv + vec2<f32>(-px.x, px.y));

    // Sub-pixel aliasing: how far the centre is from its neighbourhood's weighted mean.
    let mean = (2.0 * (n + s + e + w) + nw + ne + sw + se) / 12.0;
    let sub = smoothstep(0.0, 1.0, clamp(abs(mean - m) / range, 0.0, 1.0));
    let sub_offset = sub * sub * SUBPIXEL;

    // Orientation: an edge running along the rows has large second differences down the columns.
    let along_rows = abs(nw + sw - 2.0 * w) + 2.0 * abs(n + s - 2.0 * m) + abs(ne + se - 2.0 * e);
    let along_columns = abs(nw + ne - 2.0 * n) + 2.0 * abs(w + e - 2.0 * m) + abs(sw + se - 2.0 * s);
    let horizontal = along_rows >= along_columns;
    // Across the edge: towards the neighbour with the steeper step.
    var across = select(vec2<f32>(px.x, 0.0), vec2<f32>(0.0, px.y), horizontal);
    let before = select(w, n, horizontal);
    let after = select(e, s, horizontal);
    let steeper_before = abs(before - m) >= abs(after - m);
    let other = select(after, before, steeper_before);
    if steeper_before {
        across = -across;
    }
    let gradient = 0.25 * max(abs(before - m), abs(after - m));
    let edge_luma = 0.5 * (m + other);

    // Search along the edge (on the boundary between the two pixels) for its ends: where the
    // luma there leaves the edge's mean by a quarter of the step.
    let along = select(vec2<f32>(0.0, px.y), vec2<f32>(px.x, 0.0), horizontal);
    let edge = uv + 0.5 * across;
    var uv_neg = edge - along;
    var uv_pos = edge + along;
    var d_neg = luma_at(uv_neg) - edge_luma;
    var d_pos = luma_at(uv_pos) - edge_luma;
    for (var i = 1; i < SEARCH_STEPS; i++) {
        let done_neg = abs(d_neg) >= gradient;
        let done_pos = abs(d_pos) >= gradient;
        if done_neg && done_pos {
            break;
        }
        if !done_neg {
            uv_neg -= along;
            d_neg = luma_at(uv_neg) - edge_luma;
        }
        if !done_pos {
            uv_pos += along;
            d_pos = luma_at(uv_pos) - edge_luma;
        }
    }
    let dist_neg = select(uv.y - uv_neg.y, uv.x - uv_neg.x, horizontal);
    let dist_pos = select(uv_pos.y - uv.y, uv_pos.x - uv.x, horizontal);
    let nearer_neg = dist_neg < dist_pos;
    let dist = min(dist_neg, dist_pos);
    let edge_offset = 0.5 - dist / (dist_neg + dist_pos);
    // Only blend when the nearer end turns the way the centre does (else this pixel lies on the
    // far side of the end's step and stays as it is).
    let end_delta = select(d_pos, d_neg, nearer_neg);
    let blend_edge = select(0.0, edge_offset, (end_delta < 0.0) != (m < edge_luma));
    return at(uv + max(blend_edge, sub_offset) * across);
}
