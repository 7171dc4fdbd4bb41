//! Cost at equal error (issue 9: "at least 1000× faster than the reference at equal error"): the
//! samples per pixel the path tracer needs to match a method's error in the region of interest,
//! read off its 1/4/16/64-spp ladder, and that many samples' time per frame over the method's
//! (both per frame: previz's GPU time, the path tracer's lit renders without its start-up;
//! bench::accuracy::AccuracyRow::ms). previz's wall clock per image including readback is
//! carried beside it as a second ratio, never in place of it.
//!
//! Between two rungs the error is interpolated linearly in log–log (Monte-Carlo error falls as a
//! power of the sample count) and the time linearly in the sample count (a frame's time is a
//! fixed part plus a part proportional to its samples: exact for that model, where log–log
//! interpolation overstates the time between rungs, by 4 % at 2 spp on the ladder of
//! 2026-12-01). A method worse than the 1-spp rung is matched by at most one sample: the 1-spp
//! time, and the ratio is an upper bound. A method better than the last rung extrapolates the
//! last segment.

use super::accuracy::AccuracyRow;

/// One rung of the path tracer's ladder on one scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rung {
    pub spp: f64,
    /// Mean FLIP in the region of interest against the high-sample reference.
    pub flip_roi: f64,
    /// Time per frame, ms.
    pub ms: f64,
}

/// Where a method's error falls on the ladder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bracket {
    /// Between two rungs.
    Between,
    /// Worse than the first rung: one sample per pixel already matches it (the ratio is at most
    /// the one given).
    BelowFirst,
    /// Better than the last rung: extrapolated along the last segment.
    PastLast,
}

/// The path tracer at a method's error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtEqualError {
    pub spp: f64,
    pub tracer_ms: f64,
    pub bracket: Bracket,
}

/// Linear interpolation of `y` at `x` through (x0, y0), (x1, y1) in log–log.
fn log_lerp(x: f64, (x0, y0): (f64, f64), (x1, y1): (f64, f64)) -> f64 {
    let t = (x.ln() - x0.ln()) / (x1.ln() - x0.ln());
    (y0.ln() + t * (y1.ln() - y0.ln())).exp()
}

/// Linear interpolation of `y` at `x` through (x0, y0), (x1, y1).
fn lerp(x: f64, (x0, y0): (f64, f64), (x1, y1): (f64, f64)) -> f64 {
    y0 + (x - x0) / (x1 - x0) * (y1 - y0)
}

/// The samples per pixel and time per frame at which the path tracer's ROI error equals
/// `flip_roi`, from `ladder` (rungs of increasing spp, error falling); None with fewer than two
/// rungs or values that are not positive.
pub fn at_equal_error(ladder: &[Rung], flip_roi: f64) -> Option<AtEqualError> {
    if ladder.len() < 2 || flip_roi <= 0.0 || ladder.iter().any(|r| r.spp <= 0.0 || r.flip_roi <= 0.0 || r.ms <= 0.0) {
        return None;
    }
    let first = ladder[0];
    if flip_roi > first.flip_roi {
        return Some(AtEqualError { spp: first.spp, tracer_ms: first.ms, bracket: Bracket::BelowFirst });
    }
    let (a, b, bracket) = match ladder.windows(2).find(|w| flip_roi >= w[1].flip_roi) {
        Some(w) => (w[0], w[1], Bracket::Between),
        None => (ladder[ladder.len() - 2], ladder[ladder.len() - 1], Bracket::PastLast),
    };
    // spp as a function of error on the segment, then the time at that spp.
    let spp = log_lerp(flip_roi, (a.flip_roi, a.spp), (b.flip_roi, b.spp));
    let tracer_ms = lerp(spp, (a.spp, a.ms), (b.spp, b.ms));
    if tracer_ms <= 0.0 {
        return None;
    }
    Some(AtEqualError { spp, tracer_ms, bracket })
}

/// One scene's comparison of `method` with the path tracer.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneRatio {
    pub scene: String,
    pub method: String,
    pub flip_roi: f64,
    pub ms: f64,
    /// The method's wall clock per image including readback (None where the row has none).
    pub wall_ms: Option<f64>,
    pub at: AtEqualError,
    /// The path tracer's time at equal error over the method's time per frame.
    pub ratio: f64,
    /// The same over the method's wall clock per image.
    pub ratio_wall: Option<f64>,
}

/// The samples per pixel of a path tracer's row (`path tracer N spp`), `None` for a method.
pub fn spp_of(method: &str) -> Option<f64> {
    method.strip_prefix("path tracer ")?.strip_suffix(" spp")?.parse().ok()
}

/// The path tracer's rows (`path tracer N spp`) of `scene` as a ladder, by spp.
pub fn ladder_of(rows: &[AccuracyRow], scene: &str) -> Vec<Rung> {
    let mut ladder: Vec<Rung> = rows
        .iter()
        .filter(|r| r.scene == scene)
        .filter_map(|r| Some(Rung { spp: spp_of(&r.method)?, flip_roi: f64::from(r.flip_roi), ms: r.ms }))
        .collect();
    ladder.sort_by(|a, b| a.spp.total_cmp(&b.spp));
    ladder
}

/// Each scene's ratio for `method` (scenes with the method and a ladder of two rungs or more).
pub fn scene_ratios(rows: &[AccuracyRow], method: &str) -> Vec<SceneRatio> {
    rows.iter()
        .filter(|r| r.method == method)
        .filter_map(|r| {
            let at = at_equal_error(&ladder_of(rows, &r.scene), f64::from(r.flip_roi))?;
            Some(SceneRatio {
                scene: r.scene.clone(),
                method: method.into(),
                flip_roi: f64::from(r.flip_roi),
                ms: r.ms,
                wall_ms: r.wall_ms,
                at,
                ratio: at.tracer_ms / r.ms,
                ratio_wall: r.wall_ms.map(|w| at.tracer_ms / w),
            })
        })
        .collect()
}

/// Geometric mean of positive values (NaN for none).
pub fn geometric_mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    (values.iter().map(|v| v.ln()).sum::<f64>() / values.len() as f64).exp()
}

/// Markdown table of the ratios, then their geometric means: per frame (the goal's measure) and
/// over the wall clock per image.
pub fn markdown(ratios: &[SceneRatio]) -> String {
    let mut s = String::from(
        "| scene | method | FLIP ROI | ms per frame (GPU) | wall ms per image incl. readback | path tracer spp at that error | its ms per frame | ratio per frame | ratio to the wall clock |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in ratios {
        let (spp, bound) = match r.at.bracket {
            Bracket::Between => (format!("{:.1}", r.at.spp), ""),
            Bracket::BelowFirst => (format!("≤ {:.0} (worse than {:.0} spp)", r.at.spp, r.at.spp), "≤ "),
            Bracket::PastLast => (format!("{:.0} (extrapolated)", r.at.spp), ""),
        };
        let wall = r.wall_ms.map_or("–".into(), |w| format!("{w:.1}"));
        let ratio_wall = r.ratio_wall.map_or("–".into(), |v| format!("{bound}{v:.0}×"));
        s += &format!(
            "| {} | {} | {:.3} | {:.2} | {wall} | {spp} | {:.0} | {bound}{:.0}× | {ratio_wall} |\n",
            r.scene, r.method, r.flip_roi, r.ms, r.at.tracer_ms, r.ratio
        );
    }
    if !ratios.is_empty() {
        let g = geometric_mean(&ratios.iter().map(|r| r.ratio).collect::<Vec<_>>());
        s += &format!(
            "\ngeometric mean over {} scenes: {g:.0}× per frame (goal ≥ 1000×: {})",
            ratios.len(),
            if g >= 1000.0 { "met" } else { "not met" }
        );
        let walls: Option<Vec<f64>> = ratios.iter().map(|r| r.ratio_wall).collect();
        if let Some(w) = walls {
            s += &format!("; {:.0}× to previz's wall clock per image including readback", geometric_mean(&w));
        }
        s += "\n";
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_error_on_a_power_law_ladder_by_hand() {
        // FLIP = 0.4 · spp^−½ (Monte-Carlo noise), time = 100 + 10 · spp ms.
        let ladder: Vec<Rung> =
            [1.0, 4.0, 16.0, 64.0].iter().map(|&n: &f64| Rung { spp: n, flip_roi: 0.4 / n.sqrt(), ms: 100.0 + 10.0 * n }).collect();
        // FLIP 0.1 is the 16-spp rung exactly: 260 ms.
        let at = at_equal_error(&ladder, 0.1).unwrap();
        assert!((at.spp - 16.0).abs() < 1e-9 && (at.tracer_ms - 260.0).abs() < 1e-9 && at.bracket == Bracket::Between, "{at:?}");
        // FLIP 0.4/√8 lies on the power law at 8 spp, between 4 and 16; the time on the line
        // through (4, 140) and (16, 260): 100 + 10 · 8 = 180 ms (log–log would say
        // √(140 · 260) = 190.8).
        let at = at_equal_error(&ladder, 0.4 / 8f64.sqrt()).unwrap();
        assert!((at.spp - 8.0).abs() < 1e-9, "{at:?}");
        assert!((at.tracer_ms - 180.0).abs() < 1e-9, "{at:?}");
        // Worse than 1 spp: one sample, 110 ms, an upper bound.
        let at = at_equal_error(&ladder, 0.5).unwrap();
        assert_eq!(at, AtEqualError { spp: 1.0, tracer_ms: 110.0, bracket: Bracket::BelowFirst });
        // Better than 64 spp: 256 spp on the power law, the time extrapolated from 16 and 64 spp
        // along the same line: 100 + 10 · 256 = 2660 ms.
        let at = at_equal_error(&ladder, 0.025).unwrap();
        assert!((at.spp - 256.0).abs() < 1e-6 && at.bracket == Bracket::PastLast, "{at:?}");
        assert!((at.tracer_ms - 2660.0).abs() < 1e-6, "{at:?}");
        assert!(at_equal_error(&ladder[..1], 0.1).is_none());
        assert!(at_equal_error(&ladder, 0.0).is_none());
    }

    #[test]
    fn scene_ratios_read_the_ladder_rows() {
        let row = |scene: &str, method: &str, flip_roi: f32, ms: f64| AccuracyRow {
            scene: scene.into(),
            method: method.into(),
            flip_frame: 0.0,
            flip_roi,
            model_luminance_ratio: 1.0,
            ms,
            wall_ms: (!method.starts_with("path tracer")).then_some(5.0 * ms),
            floor_ratio: None,
        };
        let rows = [
            row("a", "path tracer 16 spp", 0.1, 400.0),
            row("a", "path tracer 4 spp", 0.2, 100.0),
            row("a", "sh9-ggx", 0.2, 2.0),
            row("b", "sh9-ggx", 0.1, 1.0),
        ];
        let r = scene_ratios(&rows, "sh9-ggx");
        // Scene b has no ladder; scene a's error is its 4-spp rung: 100 ms over 2 ms.
        assert_eq!(r.len(), 1);
        // Its wall clock (10 ms) gives the second ratio, 10×.
        assert!((r[0].at.spp - 4.0).abs() < 1e-9 && (r[0].ratio - 50.0).abs() < 1e-9, "{r:?}");
        assert_eq!((r[0].wall_ms, r[0].ratio_wall), (Some(10.0), Some(10.0)));
        let md = markdown(&r);
        assert!(md.contains("| a | sh9-ggx | 0.200 | 2.00 | 10.0 | 4.0 | 100 | 50× | 10× |"), "{md}");
        assert!(md.contains("geometric mean over 1 scenes: 50× per frame (goal ≥ 1000×: not met); 10× to previz's wall clock"), "{md}");
        // Geometric mean by hand: √(10 · 1000) = 100.
        assert!((geometric_mean(&[10.0, 1000.0]) - 100.0).abs() < 1e-9 && geometric_mean(&[]).is_nan());
    }
}
