//! `phyllo import --dir [DIR]`: every CSV of a folder that is new or changed
//! since it was last taken, for a climate computer that rewrites its log
//! there every hour and for review sheets left beside it. phyllo-import.timer
//! runs it; each file goes through [`super::import_file`], so it is
//! checked, journalled and stored exactly as one imported by hand.
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

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::{bail, Context};

use crate::config::Config;
use crate::ops::import_journal;

/// What became of one file of the folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Imported now.
    Imported,
    /// The same content as its newest kept copy.
    Unchanged,
    /// The same content as a copy taken back with `--undo`.
    Undone,
    /// Written too recently to be whole for sure; the next run takes it.
    Settling,
    /// Refused, with the reason (file and line).
    Failed(String),
}

/// Runs `phyllo import --dir [DIR]`; fails after the others are taken when
/// any file was refused.
pub fn run(config: &Config, journal: &Path, dir: Option<PathBuf>) -> anyhow::Result<()> {
    let Some(dir) = dir.or_else(|| config.import.dir.clone()) else {
        bail!("--dir without a folder: give one, or set [import] dir in the config");
    };
    let settle = Duration::from_secs_f64(config.watch.stable_secs.max(0.0));
    let mut failed = 0;
    let mut imported = 0;
    for file in csv_files(&dir)? {
        let outcome = take(config, journal, &file, settle);
        let name = file.display();
        match &outcome {
            Outcome::Imported => imported += 1,
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

/// Imports `file` unless it is unchanged, undone or still being written.
pub fn take(config: &Config, journal: &Path, file: &Path, settle: Duration) -> Outcome {
    match decide(journal, file, settle) {
        Ok(Decision::Import { superseded }) => match super::import_file(config, journal, file) {
            Ok(()) => {
                if let Some(old) = superseded {
                    // The new entry holds all of it; a failure here only leaves a copy more.
                    if let Err(e) = std::fs::remove_dir_all(&old) {
                        tracing::warn!(entry = %old.display(), "could not remove a superseded journal entry: {e}");
                    }
                }
                Outcome::Imported
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
fn csv_files(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
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
