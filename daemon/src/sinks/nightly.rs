//! The nightly export: every table into `[export] dir`, every plant's plot
//! and where its newest leaf emerged, the group summaries when configured,
//! the review sheet of the days most in doubt, and `index.html` linking them
//! all, with the service's health line at its top.

use std::path::Path;

use crate::config::{Config, PlotAxis};
use crate::domain::plant::PlantTimeline;
use crate::sinks::export::{self, KINDS};
use crate::sinks::{group_report, index_html, review_sheet};
use crate::store::Store;

/// Writes the nightly export; `health` is the `phyllo status --check` line
/// the page shows, and `say` receives one line per file or folder written.
pub fn write(
    config: &Config,
    store: &Store,
    since: Option<&str>,
    health: String,
    say: &mut dyn FnMut(String),
) -> anyhow::Result<()> {
    let dir = config.export_dir();
    let mut index = index_html::Index {
        generated_at: chrono::Local::now().format("%Y-%m-%d %H:%M").to_string(),
        plants: without_fits(export::table(store, "plants")?),
        failed: (store.image_counts()?.failed, store.recent_failures(20)?),
        health,
        ..Default::default()
    };
    for kind in KINDS {
        let file = format!("{kind}.csv");
        let out = dir.join(&file);
        let n = export::export(store, kind, since, &out)?;
        say(format!("{kind}: {n} rows → {}", out.display()));
        index.tables.push((file, n));
    }
    // Read once for the plots and the group summaries.
    let timelines = store.plant_timelines()?;
    if config.export.plots {
        write_plots(config, store, &timelines, &dir, &mut index, say)?;
    }
    let ranked = crate::domain::review::rank(&timelines, None);
    let items = review_sheet::items(store, &ranked, crate::domain::review::NIGHTLY)?;
    let n = review_sheet::write(&dir.join("review.csv"), &items)?;
    // "the 2 sessions most in doubt of 2" read as a riddle (issue 56 item 7).
    say(if n == ranked.len() {
        format!("review: {n} sessions in doubt, every one in review.csv")
    } else {
        format!("review: the {n} sessions most in doubt of {}", ranked.len())
    });
    index.tables.push(("review.csv".into(), n));
    index.review = (ranked.len(), review_sheet::rows(&items));
    write_groups(config, &timelines, &dir, &mut index, say)?;
    let page = dir.join("index.html");
    index_html::write(&page, &index)?;
    say(format!("index: {}", page.display()));
    Ok(())
}

/// A table without its `*_fit` columns: the page is for people, who read
/// whole leaves; the fits stay in the CSVs for analysis.
fn without_fits((head, rows): (Vec<String>, Vec<Vec<String>>)) -> (Vec<String>, Vec<Vec<String>>) {
    let keep: Vec<usize> = (0..head.len()).filter(|&i| !head[i].ends_with("_fit")).collect();
    let pick = |r: &Vec<String>| keep.iter().filter_map(|&i| r.get(i).cloned()).collect();
    (pick(&head), rows.iter().map(pick).collect())
}

/// Every plant's timeline plot and its newest placed leaf.
fn write_plots(
    config: &Config,
    store: &Store,
    timelines: &[PlantTimeline],
    dir: &Path,
    index: &mut index_html::Index,
    say: &mut dyn FnMut(String),
) -> anyhow::Result<()> {
    let plots = dir.join("plots");
    let clocks = match config.export.plot_axis {
        PlotAxis::Days => None,
        PlotAxis::DegreeDays => {
            let clocks =
                store.zone_clocks(config.rules().timeline.zones.clone(), config.timeline.base_temp_c)?;
            if clocks.is_empty() {
                say("plots: in days, since no temperature log has been imported".into());
                None
            } else {
                Some(clocks)
            }
        }
    };
    let drawn = crate::sinks::plot::plot_all(timelines, &plots, clocks.as_ref())?;
    index.plots = drawn.files;
    say(format!(
        "plots: {} plants → {}",
        index.plots.len(),
        plots.display()
    ));
    if drawn.in_days > 0 {
        say(format!(
            "plots: {} plants in days, their sessions outside the temperature log",
            drawn.in_days
        ));
    }
    let sites = dir.join("sites");
    let newest = crate::sinks::site_overlay::draw_newest(timelines, &config.drop_dir, &sites)?;
    say(format!(
        "sites: the newest placed leaf of {} plants → {} ({} drawn now; {} whose image has left the drop directory)",
        newest.files.len(),
        sites.display(),
        newest.drawn,
        newest.gone
    ));
    index.sites = newest.files;
    Ok(())
}

/// The group summaries, their comparisons and plot, when `[groups]` is set.
fn write_groups(
    config: &Config,
    timelines: &[PlantTimeline],
    dir: &Path,
    index: &mut index_html::Index,
    say: &mut dyn FnMut(String),
) -> anyhow::Result<()> {
    if let Some(rule) = &config.rules().groups {
        let rep = crate::domain::groups::summarise(rule, timelines);
        let n = group_report::write_groups(rule, &rep, &dir.join("groups.csv"))?;
        let d = group_report::write_days(rule, &rep, &dir.join("group_days.csv"))?;
        say(format!(
            "groups: {n} rows, group_days: {d} rows ({} plants match no pattern)",
            rep.unmatched.len()
        ));
        let pairs = crate::domain::group_compare::compare(rule, timelines);
        let c = group_report::write_pairs(rule, &pairs, &dir.join("group_pairs.csv"))?;
        say(format!("group_pairs: {c} rows"));
        index.tables.push(("groups.csv".into(), n));
        index.tables.push(("group_days.csv".into(), d));
        index.tables.push(("group_pairs.csv".into(), c));
        if config.export.plots && !rep.days.is_empty() {
            group_report::plot(&rep, &dir.join("groups.png"))?;
            index.groups_plot = Some("groups.png".into());
        }
        index.groups = Some(group_report::group_table(rule, &rep));
        index.unmatched = rep.unmatched.len();
    }
    Ok(())
}
