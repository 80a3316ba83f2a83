//! The paper's Figure 7 pair: predicted vs true counts with the regression
//! line, and the histogram of count errors.
//!
//! Text uses DejaVu Sans, embedded in the binary (crate `dejavu`) and
//! registered with plotters' ab_glyph backend ([`register_font`], which the
//! daemon's plots use too), so rendering needs no system fonts.

use std::path::Path;
use std::sync::Once;

use anyhow::anyhow;
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::metrics::{CountMetrics, CountPair};

static FONT: Once = Once::new();

/// Registers the embedded DejaVu Sans as plotters' "sans-serif" (once).
pub fn register_font() {
    FONT.call_once(|| {
        if plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular()).is_err() {
            tracing::warn!("could not register the embedded font; the plot will have no text");
        }
    });
}

/// Writes `scatter.png` and `error_histogram.png` into `dir`.
pub fn write(pairs: &[CountPair], metrics: &CountMetrics, title: &str, dir: &Path) -> anyhow::Result<()> {
    register_font();
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("cannot create {}: {e}", dir.display()))?;
    scatter(pairs, metrics, title, &dir.join("scatter.png"))?;
    histogram(pairs, title, &dir.join("error_histogram.png"))
}

fn scatter(pairs: &[CountPair], m: &CountMetrics, title: &str, out: &Path) -> anyhow::Result<()> {
    let err = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", out.display());
    let hi = pairs.iter().map(|p| p.truth.max(p.predicted)).max().unwrap_or(1) as f64 + 1.0;
    let root = BitMapBackend::new(out, (700, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{title}: exact {:.0}%, RMSE {:.2}, R² {:.2}",
                m.exact * 100.0,
                m.rmse,
                m.r2
            ),
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..hi, 0.0..hi)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("true leaf count")
        .y_desc("predicted leaf count")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(LineSeries::new([(0.0, 0.0), (hi, hi)], BLACK.mix(0.4)))
        .map_err(err)?;
    chart
        .draw_series(LineSeries::new(
            [(0.0, m.intercept), (hi, m.intercept + m.slope * hi)],
            RED.stroke_width(2),
        ))
        .map_err(err)?
        .label(format!("fit: {:.2} x + {:.2}", m.slope, m.intercept))
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
    // Overlapping points are spread a little so their number shows.
    let mut seen = std::collections::HashMap::<(u32, u32), u32>::new();
    let points: Vec<(f64, f64)> = pairs
        .iter()
        .map(|p| {
            let k = seen.entry((p.truth, p.predicted)).or_insert(0);
            *k += 1;
            let j = (*k as f64 - 1.0).sqrt() * 0.08;
            let a = *k as f64 * 2.4;
            (
                f64::from(p.truth) + j * a.cos(),
                f64::from(p.predicted) + j * a.sin(),
            )
        })
        .collect();
    chart
        .draw_series(
            points
                .iter()
                .map(|&(x, y)| Circle::new((x, y), 3, BLUE.mix(0.6).filled())),
        )
        .map_err(err)?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

fn histogram(pairs: &[CountPair], title: &str, out: &Path) -> anyhow::Result<()> {
    let err = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", out.display());
    let errors: Vec<i64> = pairs
        .iter()
        .map(|p| i64::from(p.predicted) - i64::from(p.truth))
        .collect();
    let lo = errors.iter().copied().min().unwrap_or(0).min(-1);
    let hi = errors.iter().copied().max().unwrap_or(0).max(1);
    let mut counts = std::collections::BTreeMap::<i64, u32>::new();
    for e in &errors {
        *counts.entry(*e).or_default() += 1;
    }
    let ymax = counts.values().copied().max().unwrap_or(1);
    let root = BitMapBackend::new(out, (700, 450)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{title}: predicted − true"), ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(45)
        .build_cartesian_2d((lo..hi).into_segmented(), 0u32..ymax + 1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("count error (leaves)")
        .y_desc("images")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(
            Histogram::vertical(&chart)
                .style(BLUE.mix(0.6).filled())
                .margin(4)
                .data(errors.iter().map(|e| (*e, 1u32))),
        )
        .map_err(err)?;
    root.present().map_err(err)
}
