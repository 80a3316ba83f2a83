//! `phyllo recount --config FILE [--plant NAME] [--dry-run]`: counts the
//! stored images again with the configured model and settings, after an
//! upgrade, so that a plant's timeline does not mix old and new counts.

use std::process::ExitCode;

use super::ConfigArg;
use crate::counting::onnx_counter;
use crate::ops::recount::recount;
use crate::store::{Store, WritersLock};

/// Arguments of `phyllo recount`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Only this plant's images.
    #[arg(long, value_name = "NAME")]
    plant: Option<String>,
    /// Count and report, but store nothing.
    #[arg(long)]
    dry_run: bool,
}

/// Runs `phyllo recount`; exit 1 if any image could not be counted.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let config = args.config.load()?;
    let _writing = WritersLock::shared(&config.database)?;
    let counter = onnx_counter(&config.inference)?;
    let mut store = Store::open(
        &config.database,
        &config.rules().timeline,
        config.inference.max_attempts,
    )?;
    let s = recount(
        &mut store,
        counter.as_ref(),
        &config.drop_dir,
        args.plant.as_deref(),
        args.dry_run,
        |img, new| {
            if let Some(n) = new.filter(|&n| n != img.leaf_count) {
                println!("{}\t{}\t{} -> {n}", img.plant, img.path, img.leaf_count);
            }
        },
    )?;
    println!(
        "recounted {} images with {}: {} counts changed (net {:+} leaves){}; {} missing, {} changed on disk since counted (left to the daemon), {} failed; {} plant timelines refitted",
        s.recounted,
        counter.model_id(),
        s.changed,
        s.net_leaves,
        if args.dry_run { ", nothing stored (--dry-run)" } else { "" },
        s.missing.len(),
        s.modified.len(),
        s.failed.len(),
        s.plants_refitted
    );
    for (path, why) in &s.failed {
        eprintln!("failed: {path}: {why}");
    }
    Ok(if s.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
