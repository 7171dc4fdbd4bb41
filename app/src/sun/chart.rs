//! The accuracy-versus-speed chart of `previz sun chart`: one point pair per algorithm,
//! x = nanoseconds per evaluation, y = max and RMS angular error against SPA, both log scale,
//! with the error band of a phone compass (1–3°).

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::prelude::*;

use super::Algorithm;
use super::accuracy::{Entry, Measurement};

/// Heading error of a calibrated phone compass, degrees: "about 1–3°" (issue 3). An algorithm
/// well below this band is accurate enough for compositing: the camera's own heading is worse.
pub const COMPASS_ERROR_BAND_DEG: (f64, f64) = (1.0, 3.0);

/// SPA's own stated uncertainty, drawn in place of its (zero) error against itself.
pub const SPA_STATED_UNCERTAINTY_DEG: f64 = 0.0003;

const WIDTH: u32 = 1400;
const HEIGHT: u32 = 900;

/// One distinct colour per entry (Tableau 10 without its orange, which is the compass band's).
fn colour(entry: Entry) -> RGBColor {
    match entry {
        Entry::Algorithm(Algorithm::Spa) => RGBColor(0, 0, 0),
        Entry::Algorithm(Algorithm::Grena1) => RGBColor(23, 190, 207),
        Entry::Algorithm(Algorithm::Grena2) => RGBColor(31, 119, 180),
        Entry::Algorithm(Algorithm::Grena3) => RGBColor(140, 86, 75),
        Entry::Algorithm(Algorithm::Grena4) => RGBColor(188, 189, 34),
        Entry::Algorithm(Algorithm::Grena5) => RGBColor(127, 127, 127),
        Entry::Algorithm(Algorithm::Psa) => RGBColor(44, 160, 44),
        Entry::Algorithm(Algorithm::Psa2020) => RGBColor(227, 119, 194),
        Entry::Algorithm(Algorithm::Julian) => RGBColor(214, 39, 40),
        Entry::JulianAsPrinted => RGBColor(148, 103, 189),
    }
}

fn plot_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("drawing the chart: {e}")
}

/// Draw the chart as an RGB8 image.
pub fn render(ms: &[Measurement]) -> Result<Vec<u8>> {
    crate::chart::register_font();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let x_max = ms.iter().map(|m| m.ns_per_eval).fold(1.0f64, f64::max) * 3.0;
        let x_min = ms.iter().map(|m| m.ns_per_eval).fold(f64::INFINITY, f64::min).max(0.1) / 3.0;
        let y_max = ms.iter().map(|m| m.max_error_deg).fold(10.0f64, f64::max) * 3.0;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("Sun position: accuracy vs speed ({} random cases per algorithm)", ms.first().map_or(0, |m| m.cases)),
                ("sans-serif", 28),
            )
            .margin(24)
            .x_label_area_size(60)
            .y_label_area_size(90)
            .build_cartesian_2d((x_min..x_max).log_scale(), (1e-5f64..y_max).log_scale())
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("time per evaluation (ns, log scale)")
            .y_desc("angular error vs SPA (degrees, log scale)")
            .label_style(("sans-serif", 18))
            .axis_desc_style(("sans-serif", 20))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:e}"))
            .draw()
            .map_err(plot_err)?;

        let band = RGBColor(255, 160, 60);
        let (lo, hi) = COMPASS_ERROR_BAND_DEG;
        chart
            .draw_series(std::iter::once(Rectangle::new([(x_min, lo), (x_max, hi)], band.mix(0.35).filled())))
            .map_err(plot_err)?
            .label(format!("phone compass heading error ({lo}–{hi}°)"))
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 18, y + 6)], band.mix(0.35).filled()));

        for m in ms {
            let c = colour(m.entry);
            let x = m.ns_per_eval;
            let spa_row = m.entry == Entry::Algorithm(Algorithm::Spa);
            let (max, rms) = if spa_row {
                (SPA_STATED_UNCERTAINTY_DEG, SPA_STATED_UNCERTAINTY_DEG)
            } else {
                (m.max_error_deg.max(1e-5), m.rms_error_deg.max(1e-5))
            };
            chart.draw_series(std::iter::once(PathElement::new(vec![(x, rms), (x, max)], c.stroke_width(2)))).map_err(plot_err)?;
            chart.draw_series(std::iter::once(TriangleMarker::new((x, rms), 8, c.stroke_width(2)))).map_err(plot_err)?;
            let (a, b) = m.entry.valid_years();
            let label = if spa_row {
                format!("spa ({a}..{b}; drawn at its stated ±{SPA_STATED_UNCERTAINTY_DEG}°)")
            } else {
                format!("{} ({a}..{b})", m.entry.name())
            };
            chart
                .draw_series(std::iter::once(Circle::new((x, max), 7, c.filled())))
                .map_err(plot_err)?
                .label(label)
                .legend(move |(x, y)| Circle::new((x + 9, y), 6, c.filled()));
        }
        // Legend entries for the two marker shapes.
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(plot_err)?
            .label("maximum error: filled circle")
            .legend(|(x, y)| Circle::new((x + 9, y), 6, BLACK.filled()));
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(plot_err)?
            .label("RMS error: triangle (joined to the maximum)")
            .legend(|(x, y)| TriangleMarker::new((x + 9, y), 7, BLACK.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", 18))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(buf)
}

/// Draw the chart and write it as PNG (atomically).
pub fn write_png(ms: &[Measurement], path: &Path) -> Result<()> {
    let rgb = render(ms)?;
    crate::output::write_png_rgb8(path, WIDTH, HEIGHT, &rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_every_entry_in_its_colour() {
        let ms: Vec<Measurement> = Entry::all()
            .into_iter()
            .enumerate()
            .map(|(i, entry)| Measurement {
                entry,
                cases: 10,
                ns_per_eval: 20.0 * (i + 1) as f64,
                max_error_deg: 0.01 * (i + 1) as f64,
                rms_error_deg: 0.004 * (i + 1) as f64,
            })
            .collect();
        let rgb = render(&ms).unwrap();
        assert_eq!(rgb.len(), (WIDTH * HEIGHT * 3) as usize);
        let has = |c: RGBColor| rgb.chunks_exact(3).any(|p| p == [c.0, c.1, c.2]);
        for e in Entry::all() {
            assert!(has(colour(e)), "{e:?}");
        }
        // The compass band is drawn (a light orange blended over white).
        assert!(rgb.chunks_exact(3).filter(|p| p[0] == 255 && p[1] > 200 && p[2] < 200).count() > 1000);
    }
}
