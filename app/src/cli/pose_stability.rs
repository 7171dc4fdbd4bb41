//! `previz pose-stability`: jitter, lag and failure cases of the pose filter on simulated
//! sensors; writes a CSV and a chart.

use crate::output::{write_atomic, write_png_rgb8};
use crate::pose::stability::{self, DisturbanceSeries, Estimator, StabilityConfig, StabilityReport, TradeoffRow};
use crate::sensors::sim::NoiseLevel;
use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Simulated runs per setting and noise level.
    #[arg(long, default_value_t = 20)]
    pub seeds: u64,
    /// Noise levels to measure (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "phone,bad")]
    pub noise: Vec<NoiseLevel>,
    /// Length of the held-still recording in seconds (the first 5 s are not scored).
    #[arg(long, default_value_t = 30.0)]
    pub hold: f64,
    /// Output directory for pose-stability.csv and pose-stability.png.
    #[arg(short = 'o', long = "output", default_value = "docs")]
    pub output: PathBuf,
}

pub fn run(args: Args) -> Result<()> {
    if args.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    if args.noise.is_empty() {
        bail!("--noise needs at least one level");
    }
    if !(args.hold.is_finite() && args.hold > 10.0) {
        bail!("--hold must be more than 10 seconds, got {}", args.hold);
    }
    if !args.output.is_dir() {
        bail!("output directory {} does not exist", args.output.display());
    }
    let cfg = StabilityConfig { seeds: args.seeds, noise_levels: args.noise.clone(), hold_s: args.hold, ..StabilityConfig::default() };
    let default_setting = cfg.settings[0].clone();
    let cases_per_level = 6;
    let total = cfg.seeds * cfg.noise_levels.len() as u64 * (1 + cases_per_level);
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} runs")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message("jitter/lag");
    let tradeoff = stability::measure_tradeoff(&cfg, || bar.inc(1))?;
    bar.set_message("failure cases");
    let (cases, disturbance) = stability::measure_cases(&cfg, &default_setting, || bar.inc(1))?;
    bar.finish_and_clear();
    let timing_settings: Vec<_> = cfg
        .settings
        .iter()
        .filter(|s| s.name == "default" || matches!(s.estimator, Estimator::CompassOnly { tau_s } if tau_s == 0.0))
        .cloned()
        .collect();
    let timing = stability::measure_timing(&cfg, &timing_settings)?;
    let report = StabilityReport { tradeoff, cases, timing, disturbance };

    let csv_path = args.output.join("pose-stability.csv");
    let png_path = args.output.join("pose-stability.png");
    write_atomic(&csv_path, report_csv(&report).as_bytes())?;
    draw_chart(&png_path, &report)?;
    print!("{}", report_markdown(&report, cfg.seeds));
    println!("\nwrote {} and {}", csv_path.display(), png_path.display());
    Ok(())
}

fn opt(v: f64) -> String {
    if v.is_finite() { format!("{v:.4}") } else { String::new() }
}

/// The CSV: one row per (kind, noise, scenario/setting).
pub fn report_csv(r: &StabilityReport) -> String {
    let mut s = String::from(
        "kind,noise,case,setting,jitter_rms_deg,jitter_peak_deg,wander_rms_deg,sun_offset_deg,error_rms_deg,lag_ms,max_error_deg,accuracy_coverage,flagged_fraction,ns_per_reading\n",
    );
    for t in &r.tradeoff {
        let _ = writeln!(
            s,
            "tradeoff,{},hold+turn,{},{},{},{},{},{},{},{},{},,",
            t.noise.name(),
            t.setting,
            opt(t.jitter_rms_deg),
            opt(t.jitter_peak_deg),
            opt(t.wander_rms_deg),
            opt(t.sun_offset_deg),
            opt(t.error_rms_deg),
            opt(t.lag_ms),
            opt(t.turn_peak_error_deg),
            opt(t.accuracy_coverage)
        );
    }
    for c in &r.cases {
        let _ = writeln!(
            s,
            "case,{},{},{},,,,,{},,{},,{},",
            c.noise.name(),
            c.case,
            c.setting,
            opt(c.rms_error_deg),
            opt(c.max_error_deg),
            c.flagged_fraction.map(opt).unwrap_or_default()
        );
    }
    for t in &r.timing {
        let _ = writeln!(s, "timing,,,{},,,,,,,,,,{}", t.setting, opt(t.ns_per_reading));
    }
    s
}

/// A markdown summary (printed; the numbers for the pose section of docs/PERFORMANCE.md).
pub fn report_markdown(r: &StabilityReport, seeds: u64) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "### Jitter and lag ({seeds} seeds per row; hand-held hold and a 90° turn at 90°/s)\n");
    let _ = writeln!(
        s,
        "| noise | setting | sun jitter RMS (°) | jitter peak (°) | wander RMS (°) | sun offset (°) | error RMS (°) | lag (ms) | turn peak error (°) | accuracy coverage |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    let mut rows: Vec<&TradeoffRow> = r.tradeoff.iter().collect();
    rows.sort_by(|a, b| {
        (a.noise.name(), a.jitter_rms_deg).partial_cmp(&(b.noise.name(), b.jitter_rms_deg)).unwrap_or(std::cmp::Ordering::Equal)
    });
    for t in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.0} | {:.2} | {} |",
            t.noise.name(),
            t.setting,
            t.jitter_rms_deg,
            t.jitter_peak_deg,
            t.wander_rms_deg,
            t.sun_offset_deg,
            t.error_rms_deg,
            t.lag_ms,
            t.turn_peak_error_deg,
            if t.accuracy_coverage.is_finite() { format!("{:.0} %", t.accuracy_coverage * 100.0) } else { "–".into() }
        );
    }
    let _ = writeln!(s, "\n### Failure cases\n");
    let _ = writeln!(s, "| noise | case | setting | max error (°) | RMS error (°) | flagged as disturbed | all finite |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for c in &r.cases {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.2} | {} | {} |",
            c.noise.name(),
            c.case,
            c.setting,
            c.max_error_deg,
            c.rms_error_deg,
            c.flagged_fraction.map(|f| format!("{:.0} %", f * 100.0)).unwrap_or_else(|| "–".into()),
            if c.finite { "yes" } else { "NO" }
        );
    }
    let _ = writeln!(s, "\n### Cost per reading\n");
    let base = r.timing.first().map(|t| t.ns_per_reading).unwrap_or(f64::NAN);
    for t in &r.timing {
        let _ = writeln!(s, "- {}: {:.0} ns per reading ({:.2}× the first)", t.setting, t.ns_per_reading, t.ns_per_reading / base);
    }
    s
}

/// Two panels: jitter vs lag per setting (phone noise), and heading error through a magnetic
/// disturbance with and without the gyro-only fallback.
pub fn draw_chart(path: &Path, r: &StabilityReport) -> Result<()> {
    use plotters::prelude::*;
    crate::chart::register_font();
    let (w, h) = (1400u32, 600u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("drawing {}: {e}", path.display());
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let (left, right) = root.split_horizontally(w / 2);
        let noise = r.tradeoff.iter().find(|t| t.noise == NoiseLevel::Phone).or(r.tradeoff.first()).map(|t| t.noise);
        let pts: Vec<&TradeoffRow> =
            r.tradeoff.iter().filter(|t| Some(t.noise) == noise && t.jitter_rms_deg > 0.0 && t.lag_ms.is_finite()).collect();
        let max_lag = pts.iter().map(|t| t.lag_ms).fold(50.0f64, f64::max) * 1.1;
        let min_lag = pts.iter().map(|t| t.lag_ms).fold(0.0f64, f64::min) - 5.0;
        let ymax = pts.iter().map(|t| t.jitter_rms_deg).fold(0.01f64, f64::max) * 2.0;
        let ymin = pts.iter().map(|t| t.jitter_rms_deg).fold(ymax, f64::min) / 2.0;
        let title = format!("Sun jitter vs lag ({} noise)", noise.map_or("?", NoiseLevel::name));
        let mut chart = ChartBuilder::on(&left)
            .caption(title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(min_lag..max_lag, (ymin..ymax).log_scale())
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("lag in a 90°/s turn (ms)")
            .y_desc("sun jitter RMS (°), log")
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| err(&e))?;
        let fusion: Vec<(f64, f64)> =
            pts.iter().filter(|t| t.setting.starts_with("fusion")).map(|t| (t.lag_ms, t.jitter_rms_deg)).collect();
        let compass: Vec<(f64, f64)> =
            pts.iter().filter(|t| t.setting.starts_with("compass")).map(|t| (t.lag_ms, t.jitter_rms_deg)).collect();
        let default: Vec<(f64, f64)> = pts.iter().filter(|t| t.setting == "default").map(|t| (t.lag_ms, t.jitter_rms_deg)).collect();
        chart
            .draw_series(fusion.iter().map(|&p| Circle::new(p, 4, BLUE.filled())))
            .map_err(|e| err(&e))?
            .label("gyro fusion (gain / smoothing grid)")
            .legend(|(x, y)| Circle::new((x, y), 4, BLUE.filled()));
        chart
            .draw_series(compass.iter().map(|&p| TriangleMarker::new(p, 6, RED.filled())))
            .map_err(|e| err(&e))?
            .label("compass only (seed 000), low-pass τ")
            .legend(|(x, y)| TriangleMarker::new((x, y), 6, RED.filled()));
        chart
            .draw_series(default.iter().map(|&p| Circle::new(p, 8, BLACK.stroke_width(3))))
            .map_err(|e| err(&e))?
            .label("default setting")
            .legend(|(x, y)| Circle::new((x, y), 6, BLACK.stroke_width(3)));
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.9))
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;

        draw_disturbance(&right, &r.disturbance).map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    write_png_rgb8(path, w, h, &buf).with_context(|| format!("writing chart {}", path.display()))
}

fn draw_disturbance<DB: plotters::prelude::DrawingBackend>(
    area: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    s: &DisturbanceSeries,
) -> Result<(), plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>> {
    use plotters::prelude::*;
    let t0 = s.t.first().copied().unwrap_or(0.0);
    let t1 = s.t.last().copied().unwrap_or(1.0).max(t0 + 1.0);
    let ymax = s.error_without_fallback_deg.iter().chain(&s.error_with_fallback_deg).copied().fold(1.0f64, f64::max) * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption("Heading error through a 25 µT disturbance", ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(t0..t1, 0.0..ymax)?;
    chart.configure_mesh().x_desc("time (s)").y_desc("heading error (°)").label_style(("sans-serif", 14)).draw()?;
    chart
        .draw_series(std::iter::once(Rectangle::new([(s.window.0, 0.0), (s.window.1, ymax)], RGBColor(255, 230, 200).filled())))?
        .label("disturbance present")
        .legend(|(x, y)| Rectangle::new([(x - 6, y - 6), (x + 6, y + 6)], RGBColor(255, 230, 200).filled()));
    // Where the filter flagged it: a band at the top.
    let flagged: Vec<(f64, f64)> = s.t.iter().zip(&s.flagged).filter(|(_, f)| **f).map(|(t, _)| (*t, ymax * 0.97)).collect();
    chart
        .draw_series(flagged.iter().map(|&p| Circle::new(p, 1, MAGENTA.filled())))?
        .label("flagged: gyro only")
        .legend(|(x, y)| Circle::new((x, y), 3, MAGENTA.filled()));
    let without: Vec<(f64, f64)> = s.t.iter().copied().zip(s.error_without_fallback_deg.iter().copied()).collect();
    let with: Vec<(f64, f64)> = s.t.iter().copied().zip(s.error_with_fallback_deg.iter().copied()).collect();
    chart
        .draw_series(LineSeries::new(without, RED.stroke_width(2)))?
        .label("compass always trusted")
        .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], RED.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(with, BLUE.stroke_width(2)))?
        .label("with gyro-only fallback")
        .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], BLUE.stroke_width(2)));
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.9))
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::stability::CaseRow;

    #[test]
    fn bad_arguments_are_errors_and_write_nothing() {
        let dir = std::env::temp_dir().join(format!("previz-ps-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let args = |seeds, out: PathBuf| Args { seeds, noise: vec![NoiseLevel::Phone], hold: 12.0, output: out };
        assert!(run(args(0, dir.clone())).is_err());
        assert!(run(args(1, dir.join("missing"))).is_err());
        assert!(!dir.join("pose-stability.csv").exists());
    }

    #[test]
    fn chart_renders_from_a_small_report() {
        let row = |setting: &str, lag, jit| TradeoffRow {
            noise: NoiseLevel::Phone,
            setting: setting.into(),
            seeds: 1,
            jitter_rms_deg: jit,
            jitter_peak_deg: jit * 3.0,
            wander_rms_deg: jit,
            sun_offset_deg: 0.5,
            error_rms_deg: 0.6,
            lag_ms: lag,
            turn_peak_error_deg: 1.0,
            accuracy_coverage: 0.7,
        };
        let report = StabilityReport {
            tradeoff: vec![row("default", 2.0, 0.02), row("fusion kacc=0.1", 5.0, 0.01), row("compass-only tau=0s", 0.0, 0.8)],
            cases: vec![CaseRow {
                noise: NoiseLevel::Phone,
                case: "pitch to +90".into(),
                setting: "default".into(),
                max_error_deg: 1.0,
                rms_error_deg: 0.5,
                flagged_fraction: None,
                finite: true,
            }],
            timing: vec![],
            disturbance: DisturbanceSeries {
                t: vec![0.0, 1.0, 2.0],
                error_with_fallback_deg: vec![0.1, 0.2, 0.1],
                error_without_fallback_deg: vec![0.1, 5.0, 3.0],
                flagged: vec![false, true, false],
                window: (0.5, 1.5),
            },
        };
        let dir = std::env::temp_dir().join(format!("previz-chart-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("c.png");
        draw_chart(&p, &report).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (1400, 600));
        // Something was drawn in both panels (not a blank image): blue and red pixels exist.
        assert!(img.pixels().any(|p| p[2] > 200 && p[0] < 50 && p[1] < 50));
        assert!(img.pixels().any(|p| p[0] > 200 && p[1] < 50 && p[2] < 50));
        let csv = report_csv(&report);
        assert_eq!(csv.lines().count(), 1 + 3 + 1);
        assert!(csv.lines().all(|l| l.split(',').count() == 14), "{csv}");
        assert!(report_markdown(&report, 1).contains("| phone | default |"));
    }
}
