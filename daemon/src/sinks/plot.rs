//! `phyllo timeline --plot`: a plant's timeline as a PNG.
//!
//! Drawn with plotters' bitmap backend. Text uses DejaVu Sans, embedded in the
//! binary (crate `dejavu`) and registered with plotters' ab_glyph backend, so
//! rendering needs no system fonts and works offline and in a hardened unit.

use std::path::Path;

use anyhow::{anyhow, Context};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::domain::thermal::ThermalClock;
use crate::store::{parse_iso, PlantTimeline};

/// What a timeline plot's x axis measures from the plant's first session.
#[derive(Debug, Clone, Copy)]
pub enum TimeAxis<'a> {
    /// Calendar days.
    Days,
    /// Degree-days of the greenhouse's temperature log: a plant whose leaves
    /// appear at a steady rate per degree-day draws a straight staircase
    /// however the weather went.
    DegreeDays(&'a ThermalClock),
}

pub use phyllo_evaluation::plots::register_font;

/// A timeline chart: x in days or degree-days since the first session, y in leaves.
type Chart<'a, 'b> = ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;
/// What drawing into the PNG can fail with (one message for all, made by [`plot`]).
type DrawError = DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>;

/// Draws the timeline: per-view counts (grey; top views hollow; people's
/// counts black crosses), fused counts (blue; ringed orange where the
/// session is in doubt, [`crate::domain::review`]), leaves emerged (red steps), living leaves (green), emergence events
/// (red ticks numbered with the leaf), and leaves read as lost (brown steps)
/// once a plant has lost one.
/// The x axis is days, or degree-days, since the first session.
pub fn plot(t: &PlantTimeline, out: &Path, axis: TimeAxis) -> anyhow::Result<()> {
    register_font();
    let first = t
        .sessions
        .first()
        .ok_or_else(|| anyhow!("plant {} has no sessions to plot", t.plant))?;
    let at = Layout::of(t, &first.start, axis)?;
    let root = BitMapBackend::new(out, (1000, 600)).into_drawing_area();
    let err = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", out.display());
    root.fill(&WHITE).map_err(err)?;
    let mut chart = chart(&root, t, &first.start, axis, &at).map_err(err)?;
    draw_counts(&mut chart, t, &at.xs).map_err(err)?;
    draw_fits(&mut chart, t, &at.xs).map_err(err)?;
    draw_events(&mut chart, t, &at).map_err(err)?;
    draw_legend(&mut chart).map_err(err)?;
    root.present()
        .with_context(|| format!("writing {}", out.display()))?;
    Ok(())
}

/// Where a plot's points go and how far its axes reach.
struct Layout {
    /// Each session's x.
    xs: Vec<f64>,
    /// Each emergence event's x.
    event_xs: Vec<f64>,
    /// The next leaf's number and expected x, in days only: the log holds no
    /// future temperatures.
    next: Option<(u32, f64)>,
    /// The x axis's last value before its margin.
    xmax: f64,
    /// The y axis's highest count.
    ymax: f64,
}

impl Layout {
    /// Every x before drawing starts: an error must not leave a half-drawn file.
    fn of(t: &PlantTimeline, first: &str, axis: TimeAxis) -> anyhow::Result<Layout> {
        let t0 = parse_iso(first)?;
        let day = |s: &str| -> anyhow::Result<f64> {
            let at = parse_iso(s)?;
            match axis {
                TimeAxis::Days => Ok((at - t0).num_milliseconds() as f64 / 86_400_000.0),
                TimeAxis::DegreeDays(clock) => clock.between(t0, at).ok_or_else(|| {
                    anyhow!(
                        "plant {}: the temperature log does not cover {} to {s} (outside it, or a hole of over {} h): \
                         plot it in days",
                        t.plant,
                        first,
                        crate::domain::thermal::MAX_GAP_HOURS
                    )
                }),
            }
        };
        let mut xs = Vec::new();
        let mut ymax: f64 = 1.0;
        for s in &t.sessions {
            xs.push(day(&s.start)?);
            ymax = ymax.max(
                s.views
                    .values()
                    .cloned()
                    .fold(s.fused.max(s.leaves_emerged), f64::max),
            );
        }
        let event_xs = t
            .events
            .iter()
            .map(|(_, at, _)| day(at))
            .collect::<anyhow::Result<Vec<f64>>>()?;
        let next = match (axis, &t.next_leaf) {
            (TimeAxis::Days, Some(n)) => Some((n.leaf, day(&n.expected)?)),
            _ => None,
        };
        let ymax = ymax.max(next.map_or(0.0, |n| f64::from(n.0) + 0.5));
        let xmax = xs
            .last()
            .cloned()
            .unwrap_or(0.0)
            .max(next.map_or(0.0, |n| n.1))
            .max(1.0);
        Ok(Layout {
            xs,
            event_xs,
            next,
            xmax,
            ymax,
        })
    }
}

/// The chart's caption, axes and grid, before any series.
fn chart<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    t: &PlantTimeline,
    first: &str,
    axis: TimeAxis,
    at: &Layout,
) -> Result<Chart<'a, 'b>, DrawError> {
    // Half a day's margin either side, in the axis's own unit.
    let pad = match axis {
        TimeAxis::Days => 0.5,
        TimeAxis::DegreeDays(_) => 0.02 * at.xmax,
    };
    let ph = match (t.phyllochron_days, t.phyllochron_cd) {
        (Some(p), Some(cd)) => format!("{p:.2} days/leaf, {cd:.1} °Cd/leaf"),
        (Some(p), None) => format!("{p:.2} days/leaf"),
        (None, _) => "n/a".into(),
    };
    let mut chart = ChartBuilder::on(root)
        .caption(format!("{} — phyllochron {ph}", t.plant), ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-pad..at.xmax + pad, 0.0..(at.ymax + 1.5).ceil())?;
    chart
        .configure_mesh()
        .x_desc(match axis {
            TimeAxis::Days => format!("days since {}", &first[..10]),
            TimeAxis::DegreeDays(c) => {
                format!("degree-days above {} °C since {}", c.base(), &first[..10])
            }
        })
        .y_desc("leaves")
        .x_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 14))
        .draw()?;
    Ok(chart)
}

/// A tick's label: whole numbers without decimals, others to one, and never
/// "-0.0" (a single session's axis runs from -0.5).
fn tick(v: f64) -> String {
    // Adding 0.0 turns -0.0 into 0.0.
    let r = (v * 10.0).round() / 10.0 + 0.0;
    if r.fract() == 0.0 {
        format!("{r:.0}")
    } else {
        format!("{r:.1}")
    }
}

/// The counts of each session: per view, fused, in doubt, and by people.
fn draw_counts(chart: &mut Chart<'_, '_>, t: &PlantTimeline, xs: &[f64]) -> Result<(), DrawError> {
    // Side and top views apart: the top view sees a few leaves fewer, and its
    // counts drawn like the side views' would read as a spread of the count.
    let grey = RGBColor(150, 150, 150);
    let (mut side, mut top, mut people) = (Vec::new(), Vec::new(), Vec::new());
    for (s, &x) in t.sessions.iter().zip(xs) {
        for (v, &c) in &s.views {
            let view = crate::domain::names::View::parse(v);
            let points = if view.is_top() {
                &mut top
            } else if view.is_person() {
                &mut people
            } else {
                &mut side
            };
            points.push((x, c));
        }
    }
    chart
        .draw_series(side.iter().map(|&p| Circle::new(p, 3, grey.filled())))?
        .label("side view")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, grey.filled()));
    if !top.is_empty() {
        chart
            .draw_series(top.iter().map(|&p| Circle::new(p, 3, grey.stroke_width(1))))?
            .label("top view")
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, grey.stroke_width(1)));
    }
    let fused: Vec<(f64, f64)> = t.sessions.iter().zip(xs).map(|(s, &x)| (x, s.fused)).collect();
    chart
        .draw_series(fused.iter().map(|&p| Circle::new(p, 5, BLUE.filled())))?
        .label("fused")
        .legend(|(x, y)| Circle::new((x + 10, y), 5, BLUE.filled()));
    draw_doubt(chart, t, xs)?;
    // Over the fused dot it sets, so the correction shows.
    if !people.is_empty() {
        chart
            .draw_series(people.iter().map(|&p| Cross::new(p, 6, BLACK.stroke_width(2))))?
            .label("person's count (overrides the views)")
            .legend(|(x, y)| Cross::new((x + 10, y), 6, BLACK.stroke_width(2)));
    }
    Ok(())
}

/// Rings round the sessions `phyllo review` lists, so a reader knows which
/// days the timeline is least sure of.
fn draw_doubt(chart: &mut Chart<'_, '_>, t: &PlantTimeline, xs: &[f64]) -> Result<(), DrawError> {
    let doubtful: std::collections::BTreeSet<String> =
        crate::domain::review::rank(std::slice::from_ref(t), None)
            .into_iter()
            .map(|d| d.start)
            .collect();
    if !doubtful.is_empty() {
        let orange = RGBColor(230, 120, 0);
        chart
            .draw_series(
                t.sessions
                    .iter()
                    .zip(xs)
                    .filter(|(s, _)| doubtful.contains(&s.start))
                    .map(|(s, &x)| Circle::new((x, s.fused), 9, orange.stroke_width(2))),
            )?
            .label("in doubt (phyllo review)")
            .legend(move |(x, y)| Circle::new((x + 10, y), 7, orange.stroke_width(2)));
    }
    Ok(())
}

/// The timeline's fitted lines: living leaves, leaves emerged and, once a
/// plant has lost one, leaves lost.
fn draw_fits(chart: &mut Chart<'_, '_>, t: &PlantTimeline, xs: &[f64]) -> Result<(), DrawError> {
    let living: Vec<(f64, f64)> = t.sessions.iter().zip(xs).map(|(s, &x)| (x, s.living)).collect();
    chart
        .draw_series(LineSeries::new(living, GREEN.stroke_width(2)))?
        .label("living (smoothed)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREEN.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            // Whole leaves, as every output a person reads gives them.
            steps(
                xs,
                t.sessions
                    .iter()
                    .map(|s| f64::from(crate::domain::timeline::whole_leaves(s.leaves_emerged))),
            ),
            RED.stroke_width(3),
        ))?
        .label("leaves emerged (whole leaves of the fit)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3)));
    if t.sessions.iter().any(|s| s.leaves_lost > 0.0) {
        let brown = RGBColor(140, 90, 40);
        chart
            .draw_series(LineSeries::new(
                steps(xs, t.sessions.iter().map(|s| s.leaves_lost)),
                brown.stroke_width(2),
            ))?
            .label("leaves lost (dead)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], brown.stroke_width(2)));
    }
    Ok(())
}

/// A tick at each dated leaf, and a paler one where the next is expected.
fn draw_events(chart: &mut Chart<'_, '_>, t: &PlantTimeline, at: &Layout) -> Result<(), DrawError> {
    for ((leaf, _, _), &x) in t.events.iter().zip(&at.event_xs) {
        let y = *leaf as f64;
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(x, y - 0.4), (x, y + 0.4)],
            RED.stroke_width(2),
        )))?;
        // The leaf's number above its tick, so a reader sees which leaf came when.
        chart.draw_series(std::iter::once(leaf_number(leaf.to_string(), (x, y), &RED)))?;
    }
    if let Some((leaf, x)) = at.next {
        // Drawn apart from the dated leaves: thin, and its number asked.
        let y = f64::from(leaf);
        let pale = RGBColor(230, 120, 120);
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(x, y - 0.4), (x, y + 0.4)],
                pale.stroke_width(1),
            )))?
            .label("next leaf expected")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x + 10, y - 6), (x + 10, y + 6)], pale.stroke_width(1))
            });
        chart.draw_series(std::iter::once(leaf_number(format!("{leaf}?"), (x, y), &pale)))?;
    }
    Ok(())
}

/// A leaf's number centred above its tick at `(x, y)`.
fn leaf_number<'a>(label: String, (x, y): (f64, f64), color: &RGBColor) -> Text<'a, (f64, f64), String> {
    Text::new(
        label,
        (x, y + 0.75),
        ("sans-serif", 13)
            .into_font()
            .color(color)
            .pos(Pos::new(HPos::Center, VPos::Bottom)),
    )
}

/// The legend of every phyllo plot: lower right, on a translucent white box,
/// where curves that climb with the days leave room (upper left, it hid a
/// plant's first sessions).
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
}

/// What [`plot_all`] drew.
#[derive(Debug, Default)]
pub struct PlotFiles {
    /// Plant id → its PNG's file name in the directory.
    pub files: std::collections::BTreeMap<String, String>,
    /// Plants without a counted session (nothing to draw).
    pub empty: usize,
    /// Plants drawn in days though degree-days were asked for (the
    /// temperature log does not cover their sessions).
    pub in_days: usize,
}

/// Draws every plant with a session into `dir`, one PNG per plant, in days,
/// or with `clocks` in degree-days of the plant's zone; a plant whose log does
/// not cover it is then drawn in days and counted in [`PlotFiles::in_days`].
pub fn plot_all(
    timelines: &[PlantTimeline],
    dir: &Path,
    clocks: Option<&crate::domain::climate_zone::ZoneClocks>,
) -> anyhow::Result<PlotFiles> {
    crate::files::owner::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut drawn = PlotFiles::default();
    let mut used = std::collections::HashSet::new();
    for t in timelines {
        if t.sessions.is_empty() {
            drawn.empty += 1;
            continue;
        }
        // Two ids that differ only in replaced characters must not share a file.
        let mut stem = file_stem(&t.plant);
        let mut n = 1;
        while !used.insert(stem.clone()) {
            n += 1;
            stem = format!("{}_{n}", file_stem(&t.plant));
        }
        let out = dir.join(format!("{stem}.png"));
        let in_degree_days = clocks.and_then(|c| c.for_plant(&t.plant)).map(|clock| {
            crate::files::atomic::replace(&out, ".png", |tmp| plot(t, tmp, TimeAxis::DegreeDays(clock)))
        });
        // Days where asked for, and where the plant's zone has no log or one
        // that does not cover its sessions (every x is worked out before drawing).
        if !matches!(in_degree_days, Some(Ok(()))) {
            crate::files::atomic::replace(&out, ".png", |tmp| plot(t, tmp, TimeAxis::Days))?;
            drawn.in_days += usize::from(clocks.is_some());
        }
        drawn.files.insert(t.plant.clone(), format!("{stem}.png"));
    }
    Ok(drawn)
}

/// A plant id as a file name: anything but letters, digits, `-`, `_` and `.` becomes `_`.
pub(crate) fn file_stem(plant: &str) -> String {
    let stem: String = plant
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    // A leading dot would hide the file; `..` would name the parent.
    match stem.strip_prefix('.') {
        Some(rest) => format!("_{rest}"),
        None => stem,
    }
}

/// A step line through `values` at `xs`: each value holds until the next session.
fn steps(xs: &[f64], values: impl Iterator<Item = f64>) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut last = None;
    for (&x, v) in xs.iter().zip(values) {
        if let Some(prev) = last {
            out.push((x, prev));
        }
        out.push((x, v));
        last = Some(v);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_read_without_minus_zero_or_needless_decimals() {
        assert_eq!(
            [-0.4, -0.0, -1e-12, 0.2, 1.0, 12.0].map(tick),
            ["-0.4", "0", "0", "0.2", "1", "12"]
        );
    }

    #[test]
    fn plant_ids_become_plain_file_names() {
        assert_eq!(file_stem("402-348-N276-WW-1"), "402-348-N276-WW-1");
        assert_eq!(file_stem("a/b c"), "a_b_c");
        assert_eq!(file_stem(".."), "_.");
    }

    #[test]
    fn steps_hold_each_value_until_the_next_session() {
        let got = steps(&[0.0, 1.0, 3.0], [5.0, 6.0, 6.0].into_iter());
        assert_eq!(
            got,
            vec![(0.0, 5.0), (1.0, 5.0), (1.0, 6.0), (3.0, 6.0), (3.0, 6.0)]
        );
        assert!(steps(&[], std::iter::empty()).is_empty());
    }
}
