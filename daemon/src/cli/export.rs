//! `phyllo export --config FILE [--out FILE.csv] [--since DATE] [--what KIND]`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::sinks::export::{export, KINDS};
use crate::store::Store;

/// Arguments of `phyllo export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Output CSV. Without it, every kind is written to `<export.dir>/<kind>.csv`
    /// (what the nightly timer does).
    #[arg(long, value_name = "FILE.csv")]
    out: Option<PathBuf>,
    /// Only rows at or after this date (YYYY-MM-DD) or time (YYYY-MM-DDTHH:MM:SS).
    #[arg(long, value_name = "DATE")]
    since: Option<String>,
    /// What to export.
    #[arg(long, default_value = "timeline", value_parser = KINDS)]
    what: String,
}

/// Runs `phyllo export`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let since = match &args.since {
        Some(s) => Some(crate::store::iso(super::import::parse_timestamp(s).map(|t| {
            // A bare date means from the start of that day.
            if s.len() == 10 {
                t.date().and_hms_opt(0, 0, 0).expect("midnight exists")
            } else {
                t
            }
        })?)),
        None => None,
    };
    let store = Store::open_read_only(&config.database)?;
    let nightly = args.out.is_none();
    let jobs: Vec<(String, PathBuf)> = match args.out {
        Some(out) => vec![(args.what.clone(), out)],
        None => {
            let dir = config.export_dir();
            KINDS
                .iter()
                .map(|k| (k.to_string(), dir.join(format!("{k}.csv"))))
                .collect()
        }
    };
    for (kind, out) in jobs {
        let n = export(store.conn(), &kind, since.as_deref(), &out)?;
        println!("{kind}: {n} rows → {}", out.display());
    }
    // The nightly run also leaves every plant's plot beside the tables.
    if nightly && config.export.plots {
        let dir = config.export_dir().join("plots");
        let (drawn, _) = crate::sinks::plot::plot_all(&store, &dir)?;
        println!("plots: {drawn} plants → {}", dir.display());
    }
    // And, where the config reads groups from plant ids, their summaries.
    if nightly {
        if let Some(rule) = crate::groups::GroupRule::from_config(&config.groups)? {
            let dir = config.export_dir();
            let rep = crate::sinks::group_report::report(&store, &rule)?;
            let n = crate::sinks::group_report::write_groups(&rule, &rep, &dir.join("groups.csv"))?;
            let d = crate::sinks::group_report::write_days(&rule, &rep, &dir.join("group_days.csv"))?;
            println!(
                "groups: {n} rows, group_days: {d} rows ({} plants match no pattern)",
                rep.unmatched.len()
            );
            if config.export.plots && !rep.days.is_empty() {
                let out = dir.join("groups.png");
                crate::sinks::group_report::plot(&rep, &out)?;
                println!("plots: groups → {}", out.display());
            }
        }
    }
    Ok(())
}
