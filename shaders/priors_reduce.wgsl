// Colour priors by compute-shader reduction (the live path: a new environment or camera frame).
// Concatenated after colour_correct.wgsl (uses colour_srgb_to_linear, colour_luminance,
// colour_rgb_to_lab). CPU reference: previz::colour::stats::ColourStats::from_linear; a test
// checks both agree to 1e-3.
//
// Input: `pixels`, one of two formats (params.format):
//   0: 4 words per pixel, f32 linear R, G, B, weight (0 = skip, 1 = use)   (HDR cube maps)
//   1: 1 word per pixel, RGBA8 sRGB-encoded; alpha 0 = skip, else use      (textures, frames)
// Regions (pixel index ranges): main (full statistics), up and down (mean colour only).
// Inputs bigger than one storage binding come in chunks: the per-pixel passes run once per chunk
// (ranges relative to the chunk), writing GROUPS partial rows each from partial_base.
//
// Six dispatches, in order:
//   first_moments  (GROUPS workgroups) per-group sums: count, rgb, log lab, Y, min Y, max Y; up/down sums
//   finish_first   (1 workgroup)       -> result[0..18]: count, means, min, max, up/down count + means
//   second_moments (GROUPS)            per-group centred products (rgb 6, lab 6) + coarse log2(Y) histogram
//   finish_second  (1)                 -> result[18..30]: covariances; find the coarse bins of ranks k_lo, k_hi
//   fine_histogram (GROUPS)            fine histograms inside those two coarse bins
//   finish_fine    (1)                 -> result[30], result[31]: the two percentiles
// Percentiles are order statistics (rank k, 0-based, computed on the CPU with the same rule as the
// reference) located in a two-level histogram of log2(max(Y, lum_floor)) over [min Y, max Y]:
// BINS * BINS bins in all, so the value is exact to half a fine bin.

struct ReduceParams {
    main_begin: u32,
    main_end: u32,
    up_begin: u32,
    up_end: u32,
    down_begin: u32,
    down_end: u32,
    format: u32,
    // 0-based ranks of the low and high percentiles among the main region's used pixels.
    k_lo: u32,
    k_hi: u32,
    // Luminances below this are histogrammed as this value (log2 of 0 is -inf).
    lum_floor: f32,
    // Inputs larger than one storage binding are split into chunks, one dispatch of the
    // per-pixel passes each: this chunk's first row in `partials`, and the rows of all chunks.
    partial_base: u32,
    partial_rows: u32,
}

@group(0) @binding(0) var<uniform> params: ReduceParams;
@group(0) @binding(1) var<storage, read> pixels: array<u32>;
@group(0) @binding(2) var<storage, read_write> partials: array<f32>;
@group(0) @binding(3) var<storage, read_write> result: array<f32>;
// [0, BINS): coarse histogram; [BINS, 2 BINS): fine (low); [2 BINS, 3 BINS): fine (high);
// then SCAN_SLOTS words: bin_lo, cum_before_lo, bin_hi, cum_before_hi, n.
@group(0) @binding(4) var<storage, read_write> hist: array<atomic<u32>>;

const WG: u32 = 64u;
const GROUPS: u32 = 256u;
const BINS: u32 = 1024u;
const ACC: u32 = 18u;
const SCAN: u32 = 3072u; // 3u * BINS
const BIG: f32 = 3.0e38;

// Shared by all passes (12 KiB in total, within the 16 KiB default limit).
var<workgroup> wg_acc: array<array<f32, 18>, 64>;
var<workgroup> wg_hist: array<atomic<u32>, 2048>;

// Pixel i as (linear rgb, weight).
fn load_pixel(i: u32) -> vec4<f32> {
    if (params.format == 0u) {
        let b = i * 4u;
        return vec4<f32>(bitcast<f32>(pixels[b]), bitcast<f32>(pixels[b + 1u]), bitcast<f32>(pixels[b + 2u]), bitcast<f32>(pixels[b + 3u]));
    }
    let p = unpack4x8unorm(pixels[i]);
    return vec4<f32>(colour_srgb_to_linear(p.xyz), select(0.0, 1.0, p.w > 0.0));
}

fn log_lum(y: f32) -> f32 {
    return log2(max(y, params.lum_floor));
}

// Histogram range in log2 luminance, from the first pass's min and max.
fn hist_range() -> vec2<f32> {
    return vec2<f32>(log_lum(result[8]), log_lum(result[9]));
}

// Position of y in the histogram range, in coarse-bin units (0..BINS).
fn hist_pos(y: f32) -> f32 {
    let r = hist_range();
    let width = r.y - r.x;
    if (width <= 0.0) {
        return 0.0;
    }
    return clamp((log_lum(y) - r.x) / width, 0.0, 1.0) * f32(BINS);
}

fn coarse_bin(pos: f32) -> u32 {
    return min(u32(pos), BINS - 1u);
}

fn fine_bin(pos: f32, coarse: u32) -> u32 {
    return min(u32(max(pos - f32(coarse), 0.0) * f32(BINS)), BINS - 1u);
}

// Tree reduction of wg_acc[*][0..count] into wg_acc[0]; entries 8 and 9 are min and max when
// minmax is true. Must be called by all invocations of the workgroup.
fn reduce_shared(li: u32, count: u32, minmax: bool) {
    workgroupBarrier();
    for (var s = WG / 2u; s > 0u; s = s >> 1u) {
        if (li < s) {
            for (var k = 0u; k < count; k++) {
                let a = wg_acc[li][k];
                let b = wg_acc[li + s][k];
                if (minmax && k == 8u) {
                    wg_acc[li][k] = min(a, b);
                } else if (minmax && k == 9u) {
                    wg_acc[li][k] = max(a, b);
                } else {
                    wg_acc[li][k] = a + b;
                }
            }
        }
        workgroupBarrier();
    }
}

@compute @workgroup_size(64)
fn first_moments(@builtin(local_invocation_index) li: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    var acc: array<f32, 18>;
    for (var k = 0u; k < ACC; k++) {
        acc[k] = 0.0;
    }
    acc[8] = BIG;
    acc[9] = -BIG;
    let stride = GROUPS * WG;
    let first = wid.x * WG + li;
    for (var i = params.main_begin + first; i < params.main_end; i += stride) {
        let p = load_pixel(i);
        if (p.w > 0.0) {
            let lab = colour_rgb_to_lab(p.xyz, true);
            let y = colour_luminance(p.xyz);
            acc[0] += 1.0;
            acc[1] += p.x;
            acc[2] += p.y;
            acc[3] += p.z;
            acc[4] += lab.x;
            acc[5] += lab.y;
            acc[6] += lab.z;
            acc[7] += y;
            acc[8] = min(acc[8], y);
            acc[9] = max(acc[9], y);
        }
    }
    for (var i = params.up_begin + first; i < params.up_end; i += stride) {
        let p = load_pixel(i);
        if (p.w > 0.0) {
            acc[10] += 1.0;
            acc[11] += p.x;
            acc[12] += p.y;
            acc[13] += p.z;
        }
    }
    for (var i = params.down_begin + first; i < params.down_end; i += stride) {
        let p = load_pixel(i);
        if (p.w > 0.0) {
            acc[14] += 1.0;
            acc[15] += p.x;
            acc[16] += p.y;
            acc[17] += p.z;
        }
    }
    wg_acc[li] = acc;
    reduce_shared(li, ACC, true);
    if (li == 0u) {
        for (var k = 0u; k < ACC; k++) {
            partials[(params.partial_base + wid.x) * ACC + k] = wg_acc[0][k];
        }
    }
}

// Sum the partial rows (GROUPS per chunk) of `count` values into wg_acc[0] (min/max for 8, 9 if minmax).
fn gather_partials(li: u32, count: u32, minmax: bool) {
    var acc: array<f32, 18>;
    for (var k = 0u; k < ACC; k++) {
        acc[k] = 0.0;
    }
    if (minmax) {
        acc[8] = BIG;
        acc[9] = -BIG;
    }
    for (var g = li; g < params.partial_rows; g += WG) {
        for (var k = 0u; k < count; k++) {
            let v = partials[g * ACC + k];
            if (minmax && k == 8u) {
                acc[k] = min(acc[k], v);
            } else if (minmax && k == 9u) {
                acc[k] = max(acc[k], v);
            } else {
                acc[k] += v;
            }
        }
    }
    wg_acc[li] = acc;
    reduce_shared(li, count, minmax);
}

@compute @workgroup_size(64)
fn finish_first(@builtin(local_invocation_index) li: u32) {
    gather_partials(li, ACC, true);
    if (li == 0u) {
        let t = wg_acc[0];
        let n = max(t[0], 1.0);
        let nu = max(t[10], 1.0);
        let nd = max(t[14], 1.0);
        result[0] = t[0];
        for (var k = 1u; k < 8u; k++) {
            result[k] = t[k] / n;
        }
        result[8] = t[8];
        result[9] = t[9];
        result[10] = t[10];
        result[11] = t[11] / nu;
        result[12] = t[12] / nu;
        result[13] = t[13] / nu;
        result[14] = t[14];
        result[15] = t[15] / nd;
        result[16] = t[16] / nd;
        result[17] = t[17] / nd;
    }
}

// Zero the workgroup histogram (2 BINS entries).
fn clear_wg_hist(li: u32) {
    for (var b = li; b < 2u * BINS; b += WG) {
        atomicStore(&wg_hist[b], 0u);
    }
    workgroupBarrier();
}

// Add the workgroup histogram entries [0, count) to the global one at `base`.
fn flush_wg_hist(li: u32, count: u32, base: u32) {
    workgroupBarrier();
    for (var b = li; b < count; b += WG) {
        let v = atomicLoad(&wg_hist[b]);
        if (v > 0u) {
            atomicAdd(&hist[base + b], v);
        }
    }
}

@compute @workgroup_size(64)
fn second_moments(@builtin(local_invocation_index) li: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    clear_wg_hist(li);
    let mean_rgb = vec3<f32>(result[1], result[2], result[3]);
    let mean_lab = vec3<f32>(result[4], result[5], result[6]);
    var acc: array<f32, 18>;
    for (var k = 0u; k < ACC; k++) {
        acc[k] = 0.0;
    }
    let stride = GROUPS * WG;
    for (var i = params.main_begin + wid.x * WG + li; i < params.main_end; i += stride) {
        let p = load_pixel(i);
        if (p.w > 0.0) {
            let d = p.xyz - mean_rgb;
            let e = colour_rgb_to_lab(p.xyz, true) - mean_lab;
            acc[0] += d.x * d.x;
            acc[1] += d.x * d.y;
            acc[2] += d.x * d.z;
            acc[3] += d.y * d.y;
            acc[4] += d.y * d.z;
            acc[5] += d.z * d.z;
            acc[6] += e.x * e.x;
            acc[7] += e.x * e.y;
            acc[8] += e.x * e.z;
            acc[9] += e.y * e.y;
            acc[10] += e.y * e.z;
            acc[11] += e.z * e.z;
            atomicAdd(&wg_hist[coarse_bin(hist_pos(colour_luminance(p.xyz)))], 1u);
        }
    }
    wg_acc[li] = acc;
    reduce_shared(li, 12u, false);
    if (li == 0u) {
        for (var k = 0u; k < 12u; k++) {
            partials[(params.partial_base + wid.x) * ACC + k] = wg_acc[0][k];
        }
    }
    flush_wg_hist(li, BINS, 0u);
}

// The bin of `hist[base..base+BINS]` holding rank k (0-based) given `cum` ranks before it;
// returns (bin, ranks before that bin).
fn find_rank(base: u32, k: u32, cum_in: u32) -> vec2<u32> {
    var cum = cum_in;
    for (var b = 0u; b < BINS; b++) {
        let c = atomicLoad(&hist[base + b]);
        if (cum + c > k) {
            return vec2<u32>(b, cum);
        }
        cum += c;
    }
    return vec2<u32>(BINS - 1u, cum);
}

@compute @workgroup_size(64)
fn finish_second(@builtin(local_invocation_index) li: u32) {
    gather_partials(li, 12u, false);
    if (li == 0u) {
        let t = wg_acc[0];
        let n = max(result[0], 1.0);
        for (var k = 0u; k < 12u; k++) {
            result[18u + k] = t[k] / n;
        }
        let lo = find_rank(0u, params.k_lo, 0u);
        let hi = find_rank(0u, params.k_hi, 0u);
        atomicStore(&hist[SCAN], lo.x);
        atomicStore(&hist[SCAN + 1u], lo.y);
        atomicStore(&hist[SCAN + 2u], hi.x);
        atomicStore(&hist[SCAN + 3u], hi.y);
        var total = 0u;
        for (var b = 0u; b < BINS; b++) {
            total += atomicLoad(&hist[b]);
        }
        atomicStore(&hist[SCAN + 4u], total);
    }
}

@compute @workgroup_size(64)
fn fine_histogram(@builtin(local_invocation_index) li: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    clear_wg_hist(li);
    let bin_lo = atomicLoad(&hist[SCAN]);
    let bin_hi = atomicLoad(&hist[SCAN + 2u]);
    let stride = GROUPS * WG;
    for (var i = params.main_begin + wid.x * WG + li; i < params.main_end; i += stride) {
        let p = load_pixel(i);
        if (p.w > 0.0) {
            let pos = hist_pos(colour_luminance(p.xyz));
            let c = coarse_bin(pos);
            if (c == bin_lo) {
                atomicAdd(&wg_hist[fine_bin(pos, c)], 1u);
            }
            if (c == bin_hi) {
                atomicAdd(&wg_hist[BINS + fine_bin(pos, c)], 1u);
            }
        }
    }
    flush_wg_hist(li, 2u * BINS, BINS);
}

// Luminance at the centre of fine bin `fine` inside coarse bin `coarse`.
fn bin_value(coarse: u32, fine: u32) -> f32 {
    let r = hist_range();
    if (r.y - r.x <= 0.0) {
        return result[8];
    }
    let pos = (f32(coarse) + (f32(fine) + 0.5) / f32(BINS)) / f32(BINS);
    return exp2(r.x + pos * (r.y - r.x));
}

@compute @workgroup_size(64)
fn finish_fine(@builtin(local_invocation_index) li: u32) {
    if (li == 0u) {
        let lo = find_rank(BINS, params.k_lo, atomicLoad(&hist[SCAN + 1u]));
        let hi = find_rank(2u * BINS, params.k_hi, atomicLoad(&hist[SCAN + 3u]));
        result[30] = bin_value(atomicLoad(&hist[SCAN]), lo.x);
        result[31] = bin_value(atomicLoad(&hist[SCAN + 2u]), hi.x);
    }
}
