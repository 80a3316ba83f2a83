//! `phyllo import`'s rules: one CSV is checked, kept in the import journal,
//! then stored ([`import_file`]); a sheet is taken back by name ([`undo`]).
//!
//! `phyllo import --dir [DIR]` takes every CSV of a folder that is new or
//! changed since it was last taken, for a climate computer that rewrites its
//! log there every hour and for review sheets left beside it.
//! phyllo-import.timer runs it; each file goes through [`import_file`], so it
//! is checked, journalled and stored exactly as one imported by hand.
//!
//! What was taken is told by the import journal, not the database: a file
//! whose content equals the newest kept copy of its name is unchanged, and
//! one equal to a copy set aside by `--undo` stays out until it changes.
//!
//! A climate computer that appends to one log and rewrites it every hour
//! would leave a copy of the whole log in the journal each time, growing
//! with the square of the season. Where the new content begins with the
//! newest kept copy, that copy holds no row the new one lacks, and taking
//! the new one again stores every row the old one did, so once the new one
//! is stored the old entry is removed. A restore from an older snapshot then takes the newer,
//! longer copy instead.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::{bail, Context};

use crate::config::Config;
use crate::ops::import_csv::{kind, read_climate, read_moves, read_rows, take as store_entry, Kind, Sheet};
use crate::ops::import_journal;
use crate::store::{Store, Unimported};

/// What one imported file gave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Imported {
    /// What was stored, in words ("12 counts for 3 plants").
    pub done: String,
    /// The copy kept in the import journal.
    pub kept_as: PathBuf,
    /// Rows without a leaf count, skipped.
    pub skipped: usize,
    /// The sheet's plants the database had never seen, when some of its
    /// plants were known (in a filled review sheet: most likely typing errors).
    pub new_plants: Vec<String>,
    /// The name `--undo` takes it back by.
    pub source: String,
}

/// What became of one file of the folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Imported now.
    Imported(Imported),
    /// The same content as its newest kept copy.
    Unchanged,
    /// The same content as a copy taken back with `--undo`.
    Undone,
    /// Written too recently to be whole for sure; the next run takes it.
    Settling,
    /// Refused, with the reason (file and line).
    Failed(String),
}

/// The folder `phyllo import --dir` takes: the one given, else `[import] dir`.
pub fn folder(config: &Config, dir: Option<PathBuf>) -> anyhow::Result<PathBuf> {
    match dir.or_else(|| config.import.dir.clone()) {
        Some(dir) => Ok(dir),
        None => bail!("--dir without a folder: give one, or set [import] dir in the config"),
    }
}

/// How long a file must be left alone before it counts as whole.
pub fn settle_time(config: &Config) -> Duration {
    Duration::from_secs_f64(config.watch.stable_secs.max(0.0))
}

/// Imports `file` unless it is unchanged, undone or still being written.
pub fn take(config: &Config, journal: &Path, file: &Path, settle: Duration) -> Outcome {
    match decide(journal, file, settle) {
        Ok(Decision::Import { superseded }) => match import_file(config, journal, file) {
            Ok(imported) => {
                if let Some(old) = superseded {
                    // The new entry holds all of it; a failure here only leaves a copy more.
                    if let Err(e) = std::fs::remove_dir_all(&old) {
                        tracing::warn!(entry = %old.display(), "could not remove a superseded journal entry: {e}");
                    }
                }
                Outcome::Imported(imported)
            }
            Err(e) => Outcome::Failed(format!("{e:#}")),
        },
        Ok(Decision::Skip(skip)) => skip,
        Err(e) => Outcome::Failed(format!("{e:#}")),
    }
}

/// What to do with one file.
enum Decision {
    /// Import it; `superseded`: the journal entry its content extends.
    Import { superseded: Option<PathBuf> },
    /// Leave it alone this time.
    Skip(Outcome),
}

/// Whether to import `file`, and which older entry it would supersede.
fn decide(journal: &Path, file: &Path, settle: Duration) -> anyhow::Result<Decision> {
    let meta = std::fs::metadata(file).with_context(|| format!("reading {}", file.display()))?;
    let age = meta
        .modified()
        .ok()
        .and_then(|m| SystemTime::now().duration_since(m).ok())
        .unwrap_or_default();
    if age < settle {
        return Ok(Decision::Skip(Outcome::Settling));
    }
    let name = file
        .file_name()
        .with_context(|| format!("{} names no file", file.display()))?
        .to_string_lossy();
    let Some((copy, undone)) = import_journal::newest_copy(journal, &name)? else {
        return Ok(Decision::Import { superseded: None });
    };
    let content = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let kept = std::fs::read(&copy).with_context(|| format!("reading {}", copy.display()))?;
    Ok(if content == kept {
        Decision::Skip(if undone {
            Outcome::Undone
        } else {
            Outcome::Unchanged
        })
    } else {
        let superseded = (!undone && content.starts_with(&kept))
            .then(|| copy.parent().map(Path::to_path_buf))
            .flatten();
        Decision::Import { superseded }
    })
}

/// The folder's `*.csv` files (not hidden ones: editors' and copiers'
/// temporaries), in name order so that a later sheet lands after an earlier.
pub fn csv_files(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading import folder {}", dir.display()))?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            !name.starts_with('.')
                && p.extension().is_some_and(|x| x.eq_ignore_ascii_case("csv"))
                && p.is_file()
        })
        .collect();
    files.sort();
    Ok(files)
}

/// Refuses a sheet with a capture time the drop directory's file names would
/// be refused for (before `[names] earliest`, or hours ahead of this clock):
/// one row dated 2091 would give its plant a phyllochron of decades.
fn check_capture_times(config: &Config, file: &Path, sheet: &Sheet) -> anyhow::Result<()> {
    let names = &config.rules().names;
    let now = chrono::Local::now().naive_local();
    for (plant, taken_at, _, _) in &sheet.rows {
        let shown = format!("{}, plant {plant},", file.display());
        names.check_time(Path::new(&shown), *taken_at, now)?;
    }
    Ok(())
}

/// Imports one CSV: checked, kept in the import journal, then stored, with
/// the journal entry recorded beside its rows. A file that cannot be stored
/// leaves no journal entry behind.
pub fn import_file(config: &Config, journal: &Path, file: &Path) -> anyhow::Result<Imported> {
    let (skipped, plants) = match kind(file)? {
        Kind::Counts => {
            let sheet = read_rows(file)?;
            check_capture_times(config, file, &sheet)?;
            let plants: BTreeSet<String> = sheet.rows.into_iter().map(|r| r.0).collect();
            (sheet.skipped, plants)
        }
        Kind::Reassign => (0, read_moves(file)?.into_iter().map(|m| m.1).collect()),
        Kind::Climate => {
            read_climate(file, &config.rules().timeline.zones)?;
            (0, Default::default())
        }
    };
    let kept = import_journal::keep(journal, file, chrono::Local::now().naive_local())?;
    let entry = kept.entry;
    let mut new_plants = Vec::new();
    let stored = Store::open(
        &config.database,
        &config.rules().timeline,
        config.inference.max_attempts,
    )
    .and_then(|mut store| {
        let known: BTreeSet<String> = store.plants()?.into_iter().collect();
        new_plants = plants.difference(&known).cloned().collect();
        store_entry(&mut store, &entry)
    });
    let done = match stored {
        Ok(done) => done,
        Err(e) => {
            if kept.copied {
                import_journal::forget(journal, &entry)?;
            }
            return Err(e);
        }
    };
    // A sheet of only new plants is a new experiment, not a typing error.
    if plants.iter().all(|p| new_plants.contains(p)) {
        new_plants.clear();
    }
    Ok(Imported {
        done,
        kept_as: entry.file.clone(),
        skipped,
        new_plants,
        source: entry.source(),
    })
}

/// Takes back everything imported from files named `name`: its rows leave
/// the database and its journal entries are set aside. Returns what left and
/// how many entries were set aside; nothing at all is an error.
pub fn undo(config: &Config, journal: &Path, name: &str) -> anyhow::Result<(Unimported, usize)> {
    let mut store = Store::open(
        &config.database,
        &config.rules().timeline,
        config.inference.max_attempts,
    )?;
    let back = store.unimport(name)?;
    let retired = import_journal::retire(journal, name)?;
    if back.counts + back.temperatures + back.images == 0 && retired == 0 {
        bail!(
            "nothing was imported from a file named {name:?} into {}",
            config.database.display()
        );
    }
    Ok((back, retired))
}
