//! `phyllo restore --config FILE SNAPSHOT [--no-reimport]`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::ops::backup;
use crate::ops::import_journal;
use crate::store::{RestoreLock, Store};

/// Arguments of `phyllo restore`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// The snapshot to restore (from `phyllo backup --list`).
    #[arg(value_name = "SNAPSHOT")]
    snapshot: PathBuf,
    /// Leave out the imports made after the snapshot (to undo a bad import);
    /// they are listed, and stay in the import journal.
    #[arg(long)]
    no_reimport: bool,
}

/// Runs `phyllo restore`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let now = chrono::Local::now().naive_local();
    let held = RestoreLock::acquire(&config.database)?;
    let done = backup::restore(&args.snapshot, &config.database, now, &held)?;
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
    // Opening the store brings an older snapshot to this schema, whose
    // import records start empty: every journal entry then counts as later.
    let mut store = Store::open(
        &config.database,
        &config.rules().timeline,
        config.inference.max_attempts,
    )?;
    let later = import_journal::missing(
        &import_journal::dir(&config.state_dir()),
        &store.journaled_imports()?,
    )?;
    // Each import is its own transaction: one that no longer fits the config
    // (a zone since renamed, say) is named, and the others are still taken.
    let mut failed = 0;
    for entry in &later {
        if args.no_reimport {
            println!("left out: {} (imported after the snapshot)", entry.file.display());
            continue;
        }
        match crate::ops::import_csv::take(&mut store, entry) {
            Ok(done) => println!(
                "imported: {} again ({done}, imported after the snapshot)",
                entry.file.display()
            ),
            Err(e) => {
                failed += 1;
                println!(
                    "failed:   {} ({e:#}); fix the cause and `phyllo import` it again",
                    entry.file.display()
                );
            }
        }
    }
    println!("next:     start the service; it counts the images dropped since the snapshot again.");
    if failed > 0 {
        anyhow::bail!(
            "{failed} of {} imports made after the snapshot could not be taken again (listed above); \
             the snapshot and the other imports are in place",
            later.len()
        );
    }
    Ok(())
}
