//! `phyllo import --config FILE OBS.csv`: counts made elsewhere (by people or
//! another tool) become observations, fused and fitted like the model's; a
//! greenhouse temperature log gives every plant its phyllochron in
//! degree-days ([`crate::domain::thermal`]).

use std::path::{Path, PathBuf};

use anyhow::bail;

use super::ConfigArg;
use crate::config::Config;
use crate::ops::import::{self, Imported, Outcome};
use crate::ops::import_journal;
use crate::store::WritersLock;

/// Arguments of `phyllo import`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// CSV with a header row and columns plant,timestamp,view,leaf_count
    /// (other columns are ignored), or a greenhouse temperature log with
    /// columns timestamp,temp_c and, where compartments keep logs of their
    /// own, zone (a `[[timeline.zones]]` name; empty: the facility's log), or
    /// a sheet of images filed under the wrong plant with columns image,plant
    /// (each image, as images.csv names it, moves to that plant). Timestamps: ISO 8601 (`2018-04-20T10:32:16`,
    /// a space instead of `T`, or a date alone for noon), facility local time.
    #[arg(value_name = "OBS.csv", required_unless_present_any = ["undo", "dir"])]
    file: Option<PathBuf>,
    /// Take back everything imported from files of this name (a sheet
    /// imported by mistake): its counts or temperatures leave the database,
    /// its plants are refitted, and its journal entries are set aside so a
    /// restore does not bring it back.
    #[arg(long, value_name = "NAME.csv", conflicts_with = "file")]
    undo: Option<String>,
    /// Take every CSV in this folder (default: the config's `[import] dir`)
    /// that is new or changed since it was last taken; each is imported as
    /// one file would be, a bad one is named and the others still taken.
    #[arg(long, value_name = "DIR", num_args = 0..=1, conflicts_with_all = ["file", "undo"])]
    dir: Option<Option<PathBuf>>,
}

/// Runs `phyllo import`: the CSV is checked, kept in the import journal,
/// then stored, with the journal entry recorded beside its rows.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let _writing = WritersLock::shared(&config.database)?;
    let journal = import_journal::dir(&config.state_dir());
    let file = match (args.file, args.undo, args.dir) {
        (Some(file), _, _) => file,
        (None, Some(name), _) => return undo(&config, &journal, &name),
        (None, None, Some(dir)) => return folder(&config, &journal, dir),
        (None, None, None) => unreachable!("clap requires OBS.csv, --undo or --dir"),
    };
    print_imported(&file, &import::import_file(&config, &journal, &file)?);
    Ok(())
}

/// "imported … from FILE (kept as …)", and the plants new to the database.
fn print_imported(file: &Path, i: &Imported) {
    println!(
        "imported {} from {} (kept as {}){}",
        i.done,
        file.display(),
        i.kept_as.display(),
        if i.skipped > 0 {
            format!("; {} rows without a leaf_count skipped", i.skipped)
        } else {
            String::new()
        }
    );
    if !i.new_plants.is_empty() {
        let shown: Vec<&str> = i.new_plants.iter().take(10).map(String::as_str).collect();
        eprintln!(
            "note: {} plants new to the database: {}{} (a mistyped plant id makes a plant of its own: \
             `phyllo import --undo {}` takes this file back)",
            i.new_plants.len(),
            shown.join(", "),
            if i.new_plants.len() > shown.len() {
                ", ..."
            } else {
                ""
            },
            i.source
        );
    }
}

/// `phyllo import --dir [DIR]`: every new or changed CSV of the folder; fails
/// after the others are taken when any file was refused.
fn folder(config: &Config, journal: &Path, dir: Option<PathBuf>) -> anyhow::Result<()> {
    let dir = import::folder(config, dir)?;
    let settle = import::settle_time(config);
    let mut failed = 0;
    let mut imported = 0;
    for file in import::csv_files(&dir)? {
        let outcome = import::take(config, journal, &file, settle);
        let name = file.display();
        match &outcome {
            Outcome::Imported(i) => {
                print_imported(&file, i);
                imported += 1
            }
            Outcome::Unchanged => {}
            Outcome::Undone => println!(
                "undone:   {name} (taken back with --undo; it stays out until it changes: remove it from {})",
                dir.display()
            ),
            Outcome::Settling => {
                println!("waiting:  {name} (written in the last {settle:?}; the next run takes it)")
            }
            Outcome::Failed(e) => {
                failed += 1;
                println!("failed:   {name}: {e}");
            }
        }
    }
    println!("{}: {imported} files imported, {failed} refused", dir.display());
    if failed > 0 {
        bail!(
            "{failed} files in {} could not be imported (listed above)",
            dir.display()
        );
    }
    Ok(())
}

/// `phyllo import --undo NAME`.
fn undo(config: &Config, journal: &Path, name: &str) -> anyhow::Result<()> {
    let (back, retired) = import::undo(config, journal, name)?;
    println!(
        "took back {} counts and {} temperatures imported from {name}{}; {} plants refitted; \
         {retired} journal entries set aside (as <entry>.undone in {})",
        back.counts,
        back.temperatures,
        if back.images > 0 {
            format!(
                ", and moved {} images back to the plants they came from",
                back.images
            )
        } else {
            String::new()
        },
        back.plants,
        journal.display()
    );
    Ok(())
}
