//! `phyllo review --config FILE [--top N] [--since DATE] [--plant P] [--csv SHEET.csv] [--json]`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::review::{rank, NIGHTLY};
use crate::sinks::review_sheet;
use crate::store::Store;

/// Arguments of `phyllo review`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// How many sessions to list.
    #[arg(long, default_value_t = NIGHTLY)]
    top: usize,
    /// Only sessions from this date (YYYY-MM-DD) or time on.
    #[arg(long, value_name = "DATE")]
    since: Option<String>,
    /// Only this plant's sessions.
    #[arg(long, value_name = "NAME")]
    plant: Option<String>,
    /// Also write them as a sheet to fill in and hand to `phyllo import`.
    #[arg(long, value_name = "SHEET.csv")]
    csv: Option<PathBuf>,
    /// Print JSON (each session with its views, fit and images) instead of the table.
    #[arg(long)]
    json: bool,
}

/// Runs `phyllo review`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let since = args
        .since
        .as_deref()
        .map(super::import::parse_since)
        .transpose()?;
    let store = Store::open_read_only(&config.database)?;
    let timelines = match &args.plant {
        Some(p) => store.plant_timeline(p)?.into_iter().collect::<Vec<_>>(),
        None => store.plant_timelines()?,
    };
    if let (Some(p), true) = (&args.plant, timelines.is_empty()) {
        anyhow::bail!("no plant {p:?} in {}", config.database.display());
    }
    let ranked = rank(&timelines, since.as_deref());
    let items = review_sheet::items(&store, &ranked, args.top)?;
    if let Some(out) = &args.csv {
        let n = review_sheet::write(out, &items)?;
        eprintln!(
            "{n} sessions to check → {} (fill in leaf_count, then `phyllo import` it)",
            out.display()
        );
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&items)?);
        return Ok(());
    }
    println!(
        "{} of {} sessions in doubt{}:",
        items.len(),
        ranked.len(),
        if items.len() < ranked.len() {
            " (the most doubtful first)"
        } else {
            ""
        }
    );
    for it in &items {
        let d = &it.doubt;
        println!("{}\t{}\t{}", d.plant, d.start, d.why());
        for image in &it.images {
            println!("\t{image}");
        }
    }
    Ok(())
}
