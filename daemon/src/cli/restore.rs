//! `phyllo restore --config FILE SNAPSHOT`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::sinks::backup;

/// Arguments of `phyllo restore`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// The snapshot to restore (from `phyllo backup --list`).
    #[arg(value_name = "SNAPSHOT")]
    snapshot: PathBuf,
}

/// Runs `phyllo restore`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let now = chrono::Local::now().naive_local();
    let done = backup::restore(&args.snapshot, &config.database, now)?;
    println!(
        "restored: {} → {} (integrity ok; schema {}, {} image versions, {} plants)",
        args.snapshot.display(),
        config.database.display(),
        done.contents.schema,
        done.contents.images,
        done.contents.plants
    );
    for p in &done.moved_aside {
        println!("kept:     {} (the database's former file)", p.display());
    }
    println!(
        "next:     start the service; it counts the images dropped since the snapshot again. \
         Counts imported since then need `phyllo import` again."
    );
    Ok(())
}
