//! `phyllo backup --config FILE [--out DIR] [--keep N] [--check FILE]`.

use std::path::PathBuf;

use super::ConfigArg;
use crate::ops::backup;
use crate::store::Store;

/// Arguments of `phyllo backup`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Directory of the snapshots (default: the config's `[backup] dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// The newest snapshots to keep; 0 keeps all (default: `[backup] keep`).
    /// The newest of each of `[backup] keep_monthly` earlier months stay too.
    #[arg(long, value_name = "N")]
    keep: Option<usize>,
    /// Only check a snapshot (SQLite's integrity check, what it holds) and
    /// write nothing: what to run before restoring one.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["out", "keep"])]
    check: Option<PathBuf>,
    /// List the snapshots kept and write nothing.
    #[arg(long, conflicts_with_all = ["keep", "check"])]
    list: bool,
}

/// Runs `phyllo backup`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    if let Some(file) = &args.check {
        let c = backup::check(file)?;
        println!(
            "{}: integrity ok; schema {}, {} image versions, {} plants",
            file.display(),
            c.schema,
            c.images,
            c.plants
        );
        return Ok(());
    }
    let dir = args.out.unwrap_or_else(|| config.backup_dir());
    if args.list {
        for s in backup::list(&dir)? {
            println!("{}\t{}\t{}", s.taken_at, s.bytes, s.path.display());
        }
        return Ok(());
    }
    let store = Store::open_read_only(&config.database)?;
    let now = chrono::Local::now().naive_local();
    let (snap, c) = backup::snapshot(&store.snapshot_source(), &dir, now)?;
    println!(
        "snapshot: {} ({:.1} MB; integrity ok; schema {}, {} image versions, {} plants)",
        snap.path.display(),
        snap.bytes as f64 / 1e6,
        c.schema,
        c.images,
        c.plants
    );
    let retention = backup::Retention {
        newest: args.keep.unwrap_or(config.backup.keep),
        monthly: config.backup.keep_monthly,
    };
    let removed = backup::prune(&dir, retention)?;
    for r in &removed {
        println!("deleted:  {}", r.display());
    }
    let kept = backup::list(&dir)?.len();
    let plural = if kept == 1 { "" } else { "s" };
    println!("kept:     {kept} snapshot{plural} in {}", dir.display());
    Ok(())
}
