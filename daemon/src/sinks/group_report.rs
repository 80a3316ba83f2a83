//! Group summaries out: `groups.csv` (one row per group), `group_days.csv`
//! (one row per group and day), `group_pairs.csv` (every two groups tested
//! against each other) and `groups.png` (each group's mean leaves emerged
//! per day, ± one SD), each written beside and renamed into place.

use std::path::Path;

use anyhow::{anyhow, Context};
use chrono::NaiveDate;
use plotters::prelude::*;

use super::export::{format_real, write_csv};
use crate::domain::group_compare::Comparison;
use crate::domain::groups::{GroupReport, GroupRule, Spread};

fn mean(s: Option<Spread>) -> String {
    s.map_or(String::new(), |s| format_real(s.mean))
}

fn sd(s: Option<Spread>) -> String {
    s.map_or(String::new(), |s| format_real(s.sd))
}

/// The rows of `groups.csv`: (header, rows).
pub fn group_table(rule: &GroupRule, rep: &GroupReport) -> (Vec<String>, Vec<Vec<String>>) {
    let mut head: Vec<String> = rule.columns().to_vec();
    head.extend(
        [
            "plants",
            "leaves_emerged_mean",
            "leaves_emerged_sd",
            "living_mean",
            "living_sd",
            "leaves_lost_mean",
            "phyllochron_days_mean",
            "phyllochron_days_sd",
            "phyllochron_plants",
            "phyllochron_cd_mean",
            "phyllochron_cd_sd",
            "phyllochron_cd_plants",
            "first_session",
            "last_session",
        ]
        .map(String::from),
    );
    let rows = rep
        .summaries
        .iter()
        .map(|g| {
            let mut rec = g.group.clone();
            rec.extend([
                g.plants.to_string(),
                mean(g.leaves_emerged),
                sd(g.leaves_emerged),
                mean(g.living),
                sd(g.living),
                mean(g.leaves_lost),
                mean(g.phyllochron_days),
                sd(g.phyllochron_days),
                g.phyllochron_days.map_or(0, |s| s.n).to_string(),
                mean(g.phyllochron_cd),
                sd(g.phyllochron_cd),
                g.phyllochron_cd.map_or(0, |s| s.n).to_string(),
                g.first_session.clone(),
                g.last_session.clone(),
            ]);
            rec
        })
        .collect();
    (head, rows)
}

/// Writes `groups.csv`. Returns the number of rows.
pub fn write_groups(rule: &GroupRule, rep: &GroupReport, out: &Path) -> anyhow::Result<usize> {
    write_table(out, group_table(rule, rep))
}

/// Writes a header and rows as CSV; returns the number of rows.
fn write_table(out: &Path, (head, rows): (Vec<String>, Vec<Vec<String>>)) -> anyhow::Result<usize> {
    write_csv(out, |w| {
        w.write_record(&head)?;
        for r in &rows {
            w.write_record(r)?;
        }
        Ok(rows.len())
    })
}

/// The `group_pairs.csv` table: per measure and pair of groups, the Welch
/// test ([`crate::domain::group_compare`]); a group's columns are joined by `/`.
pub fn pairs_table(rule: &GroupRule, pairs: &[Comparison]) -> (Vec<String>, Vec<Vec<String>>) {
    let by = rule.columns().join("/");
    let head = [
        "measure".to_string(),
        format!("{by}_a"),
        format!("{by}_b"),
        "plants_a".into(),
        "plants_b".into(),
        "mean_a".into(),
        "mean_b".into(),
        "difference".into(),
        "ci95_low".into(),
        "ci95_high".into(),
        "t".into(),
        "df".into(),
        "p".into(),
        "p_holm".into(),
        "blocks".into(),
    ]
    .to_vec();
    let rows = pairs
        .iter()
        .map(|c| {
            vec![
                c.measure.to_string(),
                c.a.join("/"),
                c.b.join("/"),
                c.n_a.to_string(),
                c.n_b.to_string(),
                format_real(c.mean_a),
                format_real(c.mean_b),
                format_real(c.difference),
                format_real(c.ci95.0),
                format_real(c.ci95.1),
                format_real(c.t),
                format_real(c.df),
                format!("{:.3e}", c.p),
                format!("{:.3e}", c.p_holm),
                c.blocks.map_or(String::new(), |n| n.to_string()),
            ]
        })
        .collect();
    (head, rows)
}

/// Writes `group_pairs.csv`. Returns the number of rows.
pub fn write_pairs(rule: &GroupRule, pairs: &[Comparison], out: &Path) -> anyhow::Result<usize> {
    write_table(out, pairs_table(rule, pairs))
}

/// Writes `group_days.csv`. Returns the number of rows.
pub fn write_days(rule: &GroupRule, rep: &GroupReport, out: &Path) -> anyhow::Result<usize> {
    write_csv(out, |w| {
        let mut head: Vec<String> = rule.columns().to_vec();
        head.extend(
            [
                "date",
                "plants",
                "leaves_emerged_mean",
                "leaves_emerged_sd",
                "living_mean",
                "living_sd",
            ]
            .map(String::from),
        );
        w.write_record(&head)?;
        for d in &rep.days {
            let mut rec = d.group.clone();
            rec.extend([
                d.date.clone(),
                d.leaves_emerged.n.to_string(),
                format_real(d.leaves_emerged.mean),
                format_real(d.leaves_emerged.sd),
                format_real(d.living.mean),
                format_real(d.living.sd),
            ]);
            w.write_record(&rec)?;
        }
        Ok(rep.days.len())
    })
}

/// Draws each group's mean leaves emerged per day with ± one SD bars, one
/// colour per group, drawn beside `out` and renamed into place.
pub fn plot(rep: &GroupReport, out: &Path) -> anyhow::Result<()> {
    super::plot::register_font();
    let dates: Vec<NaiveDate> = rep
        .days
        .iter()
        .map(|d| NaiveDate::parse_from_str(&d.date, "%Y-%m-%d").with_context(|| format!("date {:?}", d.date)))
        .collect::<anyhow::Result<_>>()?;
    let Some(&d0) = dates.iter().min() else {
        anyhow::bail!("no group has a session to plot");
    };
    let x = |d: &NaiveDate| (*d - d0).num_days() as f64;
    let xmax = dates.iter().map(x).fold(1.0, f64::max);
    let ymax = rep
        .days
        .iter()
        .map(|d| d.leaves_emerged.mean + d.leaves_emerged.sd)
        .fold(1.0, f64::max);
    crate::files::atomic::replace(out, ".png", |tmp| {
        let root = BitMapBackend::new(tmp, (1000, 600)).into_drawing_area();
        let err = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", out.display());
        root.fill(&WHITE).map_err(err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "leaves emerged per group (mean ± SD of the plants imaged that day)",
                ("sans-serif", 22),
            )
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(-0.5..xmax + 0.5, 0.0..(ymax + 1.0).ceil())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(format!("days since {d0}"))
            .y_desc("leaves emerged")
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(err)?;
        let k = rep.summaries.len() as f64;
        for (i, g) in rep.summaries.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            // Each group's bars a little apart, so groups on the same day stay readable.
            let nudge = (i as f64 - (k - 1.0) / 2.0) * (0.3 / k);
            let pts: Vec<(f64, Spread)> = rep
                .days
                .iter()
                .zip(&dates)
                .filter(|(d, _)| d.group == g.group)
                .map(|(d, date)| (x(date) + nudge, d.leaves_emerged))
                .collect();
            chart
                .draw_series(pts.iter().map(|&(px, s)| {
                    PathElement::new(
                        vec![(px, s.mean - s.sd), (px, s.mean + s.sd)],
                        colour.stroke_width(1),
                    )
                }))
                .map_err(err)?;
            chart
                .draw_series(LineSeries::new(
                    pts.iter().map(|&(px, s)| (px, s.mean)),
                    colour.stroke_width(2),
                ))
                .map_err(err)?
                .label(format!(
                    "{} ({} plant{})",
                    g.group.join(" / "),
                    g.plants,
                    if g.plants == 1 { "" } else { "s" }
                ))
                .legend(move |(lx, ly)| {
                    PathElement::new(vec![(lx, ly), (lx + 20, ly)], colour.stroke_width(2))
                });
            // A dot on every day, so that a group of one plant, or of one
            // day, which has no line to draw, still shows.
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(px, s)| Circle::new((px, s.mean), 3, colour.filled())),
                )
                .map_err(err)?;
        }
        super::plot::draw_legend(&mut chart).map_err(err)?;
        root.present()
            .with_context(|| format!("writing {}", out.display()))?;
        Ok(())
    })
}
