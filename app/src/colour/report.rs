//! Charts for colour work, drawn with plotters into memory (the caller writes them atomically):
//! the histogram report of `previz colour-transfer --report` (like seed 000 Figs. 31j–l) and the
//! speed-vs-accuracy chart of the benchmark.

use super::lab::{LabSpace, rgb_to_lab};
use anyhow::{Result, anyhow};
use plotters::prelude::*;

/// An RGB8 raster.
pub struct Raster {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("drawing the chart failed: {e}")
}

const SERIES_COLOURS: [RGBColor; 3] = [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44)];
const BINS: usize = 96;

/// One named pixel set (linear RGB) of the histogram report.
pub struct HistogramSet<'a> {
    pub name: &'a str,
    pub pixels: &'a [[f32; 3]],
}

/// Values of one channel: 0 = luminance Y (linear), 1..=3 = log l, α, β.
fn channel_values(pixels: &[[f32; 3]], channel: usize) -> Vec<f64> {
    let sub = super::distance::subsample(pixels, 200_000);
    sub.iter()
        .map(|p| {
            if channel == 0 {
                f64::from(super::luminance_bt709(*p))
            } else {
                f64::from(rgb_to_lab(LabSpace::Log, glam::Vec3::from_array(*p))[channel - 1])
            }
        })
        .collect()
}

fn mean_sigma(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    (m, (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt())
}

/// Histograms of luminance and of each log-lαβ channel for up to three pixel sets, with each
/// set's σ in the legend.
pub fn histogram_report(sets: &[HistogramSet<'_>]) -> Result<Raster> {
    crate::chart::register_font();
    let (width, height) = (1400u32, 1000u32);
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (title, body) = root.split_vertically(50);
        title
            .draw(&Text::new("Colour transfer: luminance (linear BT.709) and log lαβ histograms", (20, 15), ("sans-serif", 24).into_font()))
            .map_err(err)?;
        let names = ["luminance Y (linear)", "l (log lαβ)", "α (log lαβ)", "β (log lαβ)"];
        for (channel, area) in body.split_evenly((2, 2)).iter().enumerate() {
            let values: Vec<Vec<f64>> = sets.iter().map(|s| channel_values(s.pixels, channel)).collect();
            let all = values.iter().flatten().copied().filter(|v| v.is_finite());
            let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            let (lo, hi) = if lo.is_finite() && hi > lo { (lo, hi) } else { (lo.min(0.0), lo.max(0.0) + 1.0) };
            let width = (hi - lo) / BINS as f64;
            let hists: Vec<Vec<f64>> = values
                .iter()
                .map(|v| {
                    let mut h = vec![0.0; BINS];
                    for x in v {
                        let b = (((x - lo) / width) as usize).min(BINS - 1);
                        h[b] += 1.0;
                    }
                    let n = v.len().max(1) as f64;
                    h.iter().map(|c| c / n).collect()
                })
                .collect();
            let ymax = hists.iter().flatten().copied().fold(0.0, f64::max).max(1e-6) * 1.1;
            let mut chart = ChartBuilder::on(area)
                .caption(names[channel], ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(30)
                .y_label_area_size(50)
                .build_cartesian_2d(lo..hi, 0.0..ymax)
                .map_err(err)?;
            chart.configure_mesh().y_desc("fraction of pixels").label_style(("sans-serif", 13)).draw().map_err(err)?;
            for (i, (h, set)) in hists.iter().zip(sets).enumerate() {
                let colour = SERIES_COLOURS[i % 3];
                let (m, s) = mean_sigma(&values[i]);
                let pts: Vec<(f64, f64)> = h.iter().enumerate().map(|(b, c)| (lo + (b as f64 + 0.5) * width, *c)).collect();
                chart
                    .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                    .map_err(err)?
                    .label(format!("{}: μ={m:.3} σ={s:.3}", set.name))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            }
            chart
                .configure_series_labels()
                .label_font(("sans-serif", 14))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(err)?;
        }
        root.present().map_err(err)?;
    }
    Ok(Raster { width, height, rgb })
}

/// A point of the speed-vs-accuracy chart.
pub struct SpeedPoint {
    pub label: String,
    /// Milliseconds per 960×640 frame.
    pub ms: f64,
    /// Distance to the source distribution (sliced Wasserstein-2, log lαβ).
    pub distance: f64,
    /// true: GPU shader; false: CPU tool.
    pub gpu: bool,
    /// Put the label above the point (to separate points that coincide).
    pub label_above: bool,
}

/// Scatter of distance (y) against cost per frame (x, log scale); `baseline` (the uncorrected
/// target's distance) is drawn as a dashed line.
pub fn speed_accuracy_chart(points: &[SpeedPoint], baseline: f64, subtitle: &str) -> Result<Raster> {
    crate::chart::register_font();
    let (width, height) = (1100u32, 700u32);
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let xs = points.iter().map(|p| p.ms).filter(|x| *x > 0.0);
        let (x0, x1) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
        let (x0, x1) = if x0.is_finite() && x1 > 0.0 { (x0 / 2.0, x1 * 2.0) } else { (0.01, 100.0) };
        let ymax = points.iter().map(|p| p.distance).fold(baseline, f64::max) * 1.15;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("Colour correction: accuracy vs cost per 960×640 frame ({subtitle})"), ("sans-serif", 20))
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), 0.0..ymax.max(1e-6))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("milliseconds per frame (log scale)")
            .y_desc("sliced Wasserstein-2 to source (log lαβ), lower is better")
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(err)?;
        chart
            .draw_series(DashedLineSeries::new(vec![(x0, baseline), (x1, baseline)], 8, 6, BLACK.stroke_width(1)))
            .map_err(err)?
            .label(format!("uncorrected target: {baseline:.3}"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        for gpu in [true, false] {
            let colour = if gpu { SERIES_COLOURS[0] } else { SERIES_COLOURS[1] };
            let pts: Vec<&SpeedPoint> = points.iter().filter(|p| p.gpu == gpu && p.ms > 0.0).collect();
            chart
                .draw_series(pts.iter().map(|p| Circle::new((p.ms, p.distance), 6, colour.filled())))
                .map_err(err)?
                .label(if gpu { "GPU shader (lavapipe)" } else { "CPU tool" })
                .legend(move |(x, y)| Circle::new((x + 10, y), 6, colour.filled()));
            chart
                .draw_series(pts.iter().map(|p| {
                    EmptyElement::at((p.ms, p.distance))
                        + Text::new(p.label.clone(), (8, if p.label_above { -22 } else { 6 }), ("sans-serif", 14).into_font())
                }))
                .map_err(err)?;
        }
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    Ok(Raster { width, height, rgb })
}

/// Put `tiles` (RGBA8 images, all the same size, alpha composited over white) side by side
/// with a caption under each.
pub fn montage(tiles: &[(&str, &crate::scene::Rgba8Image)]) -> Result<Raster> {
    crate::chart::register_font();
    let Some((_, first)) = tiles.first() else { return Err(anyhow!("no images to put side by side")) };
    let (tw, th) = (first.width, first.height);
    if tiles.iter().any(|(_, t)| t.width != tw || t.height != th) {
        return Err(anyhow!("montage tiles differ in size"));
    }
    let (gap, caption) = (8u32, 34u32);
    let width = tiles.len() as u32 * (tw + gap) + gap;
    let height = th + caption + 2 * gap;
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    for (i, (_, t)) in tiles.iter().enumerate() {
        let x0 = gap + i as u32 * (tw + gap);
        for y in 0..th {
            for x in 0..tw {
                let s = ((y * tw + x) * 4) as usize;
                let a = f32::from(t.pixels[s + 3]) / 255.0;
                let d = (((y + gap) * width + x0 + x) * 3) as usize;
                for c in 0..3 {
                    rgb[d + c] = (f32::from(t.pixels[s + c]) * a + 255.0 * (1.0 - a)).round() as u8;
                }
            }
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        for (i, (label, _)) in tiles.iter().enumerate() {
            let x = (gap + i as u32 * (tw + gap)) as i32;
            root.draw(&Text::new(label.to_string(), (x, (th + gap + 8) as i32), ("sans-serif", 15).into_font())).map_err(err)?;
        }
        root.present().map_err(err)?;
    }
    Ok(Raster { width, height, rgb })
}
