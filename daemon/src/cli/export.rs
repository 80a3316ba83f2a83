//! `phyllo export --config FILE [--out FILE.csv] [--since DATE] [--what KIND]`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::config::{Config, PlotAxis};
use crate::domain::climate_zone::ZoneRules;
use crate::domain::groups::GroupRule;
use crate::sinks::export::{self, KINDS};
use crate::sinks::{group_report, index_html, review_sheet};
use crate::store::Store;

/// Arguments of `phyllo export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Output CSV. Without it, `--what`'s kind is written to
    /// `<export.dir>/<kind>.csv`; without either, everything the nightly timer
    /// writes (every table, plots, review sheet, index.html).
    #[arg(long, value_name = "FILE.csv")]
    out: Option<PathBuf>,
    /// Only rows at or after this date (YYYY-MM-DD) or time (YYYY-MM-DDTHH:MM:SS).
    #[arg(long, value_name = "DATE", value_parser = crate::ops::import_csv::parse_since)]
    since: Option<String>,
    /// What to export (with `--out` alone: timeline).
    #[arg(long, value_parser = KINDS)]
    what: Option<String>,
}

/// Runs `phyllo export`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    let since = args.since.as_deref();
    let (what, out) = match (args.what, args.out) {
        (None, None) => return nightly(&config, &store, since),
        (what, Some(out)) => (what.unwrap_or_else(|| "timeline".into()), out),
        (Some(what), None) => {
            let out = config.export_dir().join(format!("{what}.csv"));
            (what, out)
        }
    };
    let n = export::export(store.conn(), &what, since, &out)?;
    println!("{what}: {n} rows → {}", out.display());
    Ok(())
}

/// What the nightly timer runs: every table into `[export] dir`, every
/// plant's plot and where its newest leaf emerged, the group summaries when
/// configured, the review sheet of the days most in doubt, and `index.html`
/// linking them all.
fn nightly(config: &Config, store: &Store, since: Option<&str>) -> anyhow::Result<()> {
    let dir = config.export_dir();
    let mut index = index_html::Index {
        generated_at: chrono::Local::now().format("%Y-%m-%d %H:%M").to_string(),
        plants: export::table(store.conn(), "plants")?,
        failed: (store.image_counts()?.failed, store.recent_failures(20)?),
        health: {
            // This export is the one being written, so it is not stale.
            let mut h = super::status::health(config, store)?;
            h.export_age_hours = Some(0);
            super::status::check_line(&super::status::findings(&h)).0
        },
        ..Default::default()
    };
    for kind in KINDS {
        let file = format!("{kind}.csv");
        let out = dir.join(&file);
        let n = export::export(store.conn(), kind, since, &out)?;
        println!("{kind}: {n} rows → {}", out.display());
        index.tables.push((file, n));
    }
    // Read once for the plots and the group summaries.
    let timelines = store.plant_timelines()?;
    if config.export.plots {
        let plots = dir.join("plots");
        let clocks = match config.export.plot_axis {
            PlotAxis::Days => None,
            PlotAxis::DegreeDays => {
                let clocks = store.zone_clocks(
                    ZoneRules::from_config(&config.timeline.zones)?,
                    config.timeline.base_temp_c,
                )?;
                if clocks.is_empty() {
                    println!("plots: in days, since no temperature log has been imported");
                    None
                } else {
                    Some(clocks)
                }
            }
        };
        let drawn = crate::sinks::plot::plot_all(&timelines, &plots, clocks.as_ref())?;
        index.plots = drawn.files;
        println!("plots: {} plants → {}", index.plots.len(), plots.display());
        if drawn.in_days > 0 {
            println!(
                "plots: {} plants in days, their sessions outside the temperature log",
                drawn.in_days
            );
        }
        let sites = dir.join("sites");
        let newest = crate::sinks::site_overlay::draw_newest(&timelines, &config.drop_dir, &sites)?;
        println!(
            "sites: the newest placed leaf of {} plants → {} ({} drawn now; {} whose image has left the drop directory)",
            newest.files.len(),
            sites.display(),
            newest.drawn,
            newest.gone
        );
        index.sites = newest.files;
    }
    let ranked = crate::domain::review::rank(&timelines, None);
    let items = review_sheet::items(store, &ranked, crate::domain::review::NIGHTLY)?;
    let n = review_sheet::write(&dir.join("review.csv"), &items)?;
    println!("review: the {n} sessions most in doubt of {}", ranked.len());
    index.tables.push(("review.csv".into(), n));
    index.review = (ranked.len(), review_sheet::rows(&items));
    if let Some(rule) = GroupRule::from_config(&config.groups)? {
        let rep = crate::domain::groups::summarise(&rule, &timelines);
        let n = group_report::write_groups(&rule, &rep, &dir.join("groups.csv"))?;
        let d = group_report::write_days(&rule, &rep, &dir.join("group_days.csv"))?;
        println!(
            "groups: {n} rows, group_days: {d} rows ({} plants match no pattern)",
            rep.unmatched.len()
        );
        let pairs = crate::domain::group_compare::compare(&rule, &timelines);
        let c = group_report::write_pairs(&rule, &pairs, &dir.join("group_pairs.csv"))?;
        println!("group_pairs: {c} rows");
        index.tables.push(("groups.csv".into(), n));
        index.tables.push(("group_days.csv".into(), d));
        index.tables.push(("group_pairs.csv".into(), c));
        if config.export.plots && !rep.days.is_empty() {
            group_report::plot(&rep, &dir.join("groups.png"))?;
            index.groups_plot = Some("groups.png".into());
        }
        index.groups = Some(group_report::group_table(&rule, &rep));
        index.unmatched = rep.unmatched.len();
    }
    let page = dir.join("index.html");
    index_html::write(&page, &index)?;
    println!("index: {}", page.display());
    Ok(())
}
