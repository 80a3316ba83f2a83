//! `phyllo export --config FILE [--out FILE.csv] [--since DATE] [--what KIND]`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::ops::health::{check_line, findings, health};
use crate::sinks::export::{self, KINDS};
use crate::sinks::nightly;
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
        (None, None) => {
            // This export is the one being written, so it is not stale.
            let mut h = health(&config, &store)?;
            h.export_age_hours = Some(0);
            let line = check_line(&findings(&h)).0;
            return nightly::write(&config, &store, since, line, &mut |l| println!("{l}"));
        }
        (what, Some(out)) => (what.unwrap_or_else(|| "timeline".into()), out),
        (Some(what), None) => {
            let out = config.export_dir().join(format!("{what}.csv"));
            (what, out)
        }
    };
    let n = export::export(&store, &what, since, &out)?;
    println!("{what}: {n} rows → {}", out.display());
    Ok(())
}
