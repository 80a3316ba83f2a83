//! `phyllo import --dir [DIR]`: every CSV of a folder that is new or changed
//! since it was last taken, for a climate computer that rewrites its log
//! there every hour and for review sheets left beside it. phyllo-import.timer
//! runs it; each file goes through [`super::import::import_file`], so it is
//! checked, journalled and stored exactly as one imported by hand.
//!
//! What was taken is told by the import journal, not the database: a file
//! whose content equals the newest kept copy of its name is unchanged, and
//! one equal to a copy set aside by `--undo` stays out until it changes.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::{bail, Context};

use crate::config::Config;
use crate::import_journal;

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
        Ok(None) => match super::import::import_file(config, journal, file) {
            Ok(()) => Outcome::Imported,
            Err(e) => Outcome::Failed(format!("{e:#}")),
        },
        Ok(Some(skip)) => skip,
        Err(e) => Outcome::Failed(format!("{e:#}")),
    }
}

/// Why `file` is left alone this time, or `None` to import it.
fn decide(journal: &Path, file: &Path, settle: Duration) -> anyhow::Result<Option<Outcome>> {
    let meta = std::fs::metadata(file).with_context(|| format!("reading {}", file.display()))?;
    let age = meta
        .modified()
        .ok()
        .and_then(|m| SystemTime::now().duration_since(m).ok())
        .unwrap_or_default();
    if age < settle {
        return Ok(Some(Outcome::Settling));
    }
    let name = file
        .file_name()
        .with_context(|| format!("{} names no file", file.display()))?
        .to_string_lossy();
    let Some((copy, undone)) = import_journal::newest_copy(journal, &name)? else {
        return Ok(None);
    };
    let content = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let kept = std::fs::read(&copy).with_context(|| format!("reading {}", copy.display()))?;
    Ok((content == kept).then_some(if undone {
        Outcome::Undone
    } else {
        Outcome::Unchanged
    }))
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
