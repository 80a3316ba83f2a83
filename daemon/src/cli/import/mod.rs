//! `phyllo import --config FILE OBS.csv`: counts made elsewhere (by people or
//! another tool) become observations, fused and fitted like the model's; a
//! greenhouse temperature log gives every plant its phyllochron in
//! degree-days ([`crate::domain::thermal`]).

use std::path::PathBuf;

use anyhow::bail;

use super::ConfigArg;
use crate::ops::import_csv::{kind, read_climate, read_moves, read_rows, take, Kind};
use crate::ops::import_journal;
use crate::store::{Store, WritersLock};

mod dir;

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
        (None, None, Some(dir)) => return dir::run(&config, &journal, dir),
        (None, None, None) => unreachable!("clap requires OBS.csv, --undo or --dir"),
    };
    import_file(&config, &journal, &file)
}

/// Refuses a sheet with a capture time the drop directory's file names would
/// be refused for (before `[names] earliest`, or hours ahead of this clock):
/// one row dated 2091 would give its plant a phyllochron of decades.
fn check_capture_times(
    config: &crate::config::Config,
    file: &std::path::Path,
    sheet: &crate::ops::import_csv::Sheet,
) -> anyhow::Result<()> {
    let names = crate::domain::names::NamePatterns::from_config(&config.names)?;
    let now = chrono::Local::now().naive_local();
    for (plant, taken_at, _, _) in &sheet.rows {
        let shown = format!("{}, plant {plant},", file.display());
        names.check_time(std::path::Path::new(&shown), *taken_at, now)?;
    }
    Ok(())
}

/// Imports one CSV: checked, kept in the import journal, then stored, with
/// the journal entry recorded beside its rows.
pub fn import_file(
    config: &crate::config::Config,
    journal: &std::path::Path,
    file: &std::path::Path,
) -> anyhow::Result<()> {
    let (skipped, plants) = match kind(file)? {
        Kind::Counts => {
            let sheet = read_rows(file)?;
            check_capture_times(config, file, &sheet)?;
            let plants: std::collections::BTreeSet<String> = sheet.rows.into_iter().map(|r| r.0).collect();
            (sheet.skipped, plants)
        }
        Kind::Reassign => (0, read_moves(file)?.into_iter().map(|m| m.1).collect()),
        Kind::Climate => {
            read_climate(
                file,
                &crate::domain::climate_zone::ZoneRules::from_config(&config.timeline.zones)?,
            )?;
            (0, Default::default())
        }
    };
    let kept = import_journal::keep(journal, file, chrono::Local::now().naive_local())?;
    let entry = kept.entry;
    // Plants the database has never seen, named after the import: in a
    // filled review sheet they are most likely typing errors.
    let mut new_plants = Vec::new();
    let imported = Store::open(&config.database, &config.timeline, config.inference.max_attempts).and_then(
        |mut store| {
            let known: std::collections::BTreeSet<String> = store.plants()?.into_iter().collect();
            new_plants = plants.difference(&known).cloned().collect();
            take(&mut store, &entry)
        },
    );
    let done = match imported {
        Ok(done) => done,
        Err(e) => {
            if kept.copied {
                import_journal::forget(journal, &entry)?;
            }
            return Err(e);
        }
    };
    println!(
        "imported {done} from {} (kept as {}){}",
        file.display(),
        entry.file.display(),
        if skipped > 0 {
            format!("; {skipped} rows without a leaf_count skipped")
        } else {
            String::new()
        }
    );
    if !new_plants.is_empty() && !plants.iter().all(|p| new_plants.contains(p)) {
        let shown: Vec<&str> = new_plants.iter().take(10).map(String::as_str).collect();
        eprintln!(
            "note: {} plants new to the database: {}{} (a mistyped plant id makes a plant of its own: \
             `phyllo import --undo {}` takes this file back)",
            new_plants.len(),
            shown.join(", "),
            if new_plants.len() > shown.len() {
                ", ..."
            } else {
                ""
            },
            entry.source()
        );
    }
    Ok(())
}

/// `phyllo import --undo NAME`.
fn undo(config: &crate::config::Config, journal: &std::path::Path, name: &str) -> anyhow::Result<()> {
    let mut store = Store::open(&config.database, &config.timeline, config.inference.max_attempts)?;
    let back = store.unimport(name)?;
    let retired = import_journal::retire(journal, name)?;
    if back.counts + back.temperatures + back.images == 0 && retired == 0 {
        bail!(
            "nothing was imported from a file named {name:?} into {}",
            config.database.display()
        );
    }
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
