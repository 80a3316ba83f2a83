//! The import journal: a copy of every CSV `phyllo import` took, kept under
//! `<state>/imports/<YYYY-MM-DDTHHMMSS>[-N]/<file name>`.
//!
//! People's corrections exist nowhere else once their spreadsheet is gone,
//! and a snapshot holds only the imports made before it. The database
//! records each import by its journal entry, so after a restore the entries
//! the snapshot lacks are exactly the imports to take again
//! ([`missing`]). Entries are never pruned: they are small, and a restore
//! from an old monthly snapshot needs all of them.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use anyhow::Context;
use chrono::NaiveDateTime;

use crate::files::atomic::sync_dir;

/// Entry names: the local time of the import, to the second.
const STAMP: &str = "%Y-%m-%dT%H%M%S";

/// One imported CSV in the journal.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// The entry's name (`2026-12-05T101500`, or `…-1` for a second import
    /// within the same second), recorded in the database with the import.
    pub id: String,
    /// The kept copy; its file name is the original's, which names the
    /// import's source in the database.
    pub file: PathBuf,
}

impl Entry {
    /// The CSV's original file name.
    pub fn source(&self) -> String {
        self.file
            .file_name()
            .map_or("import".into(), |n| n.to_string_lossy().into_owned())
    }
}

/// The journal directory of a service whose state directory is `state_dir`.
pub fn dir(state_dir: &Path) -> PathBuf {
    state_dir.join("imports")
}

/// What [`keep`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Kept {
    /// The CSV's entry.
    pub entry: Entry,
    /// False when the CSV already was an entry (one imported again by hand).
    pub copied: bool,
}

/// Keeps a synced copy of `csv` in `journal` and returns its entry. A file
/// already in the journal is its own entry.
pub fn keep(journal: &Path, csv: &Path, now: NaiveDateTime) -> anyhow::Result<Kept> {
    if let Some(entry) = entry_of(journal, csv) {
        return Ok(Kept { entry, copied: false });
    }
    let name = csv
        .file_name()
        .with_context(|| format!("{} names no file", csv.display()))?;
    crate::files::owner::create_dir_all(journal)
        .with_context(|| format!("creating import journal {}", journal.display()))?;
    // Copied into a hidden directory first, so an entry is whole or absent.
    let work = tempfile::Builder::new()
        .prefix(".phyllo-import-")
        .tempdir_in(journal)
        .with_context(|| format!("creating a directory in {}", journal.display()))?;
    let copy = work.path().join(name);
    std::fs::copy(csv, &copy)
        .with_context(|| format!("copying {} into {}", csv.display(), journal.display()))?;
    std::fs::File::open(&copy)
        .and_then(|f| f.sync_all())
        .with_context(|| format!("syncing {}", copy.display()))?;
    crate::files::owner::match_parent(work.path());
    crate::files::owner::match_parent(&copy);
    sync_dir(work.path())?;
    let stamp = now.format(STAMP).to_string();
    let mut id = stamp.clone();
    let mut n = 1;
    // An undone entry keeps its name (with `.undone`), so the name stays taken.
    while journal.join(&id).exists() || journal.join(format!("{id}.undone")).exists() {
        id = format!("{stamp}-{n}");
        n += 1;
    }
    let work = work.keep();
    let entry_dir = journal.join(&id);
    std::fs::rename(&work, &entry_dir)
        .with_context(|| format!("renaming {} to {}", work.display(), entry_dir.display()))?;
    sync_dir(journal)?;
    Ok(Kept {
        entry: Entry {
            file: entry_dir.join(name),
            id,
        },
        copied: true,
    })
}

/// Removes an entry whose import failed, so that a restore does not take
/// it in later as though it had landed.
pub fn forget(journal: &Path, entry: &Entry) -> anyhow::Result<()> {
    let dir = journal.join(&entry.id);
    std::fs::remove_dir_all(&dir).with_context(|| format!("removing {}", dir.display()))
}

/// Sets aside every entry whose file is named `source` (renamed to
/// `<id>.undone`, kept but no longer an entry), so that a restore does not
/// take back an import that was undone. Returns how many.
pub fn retire(journal: &Path, source: &str) -> anyhow::Result<usize> {
    let mut n = 0;
    for entry in entries(journal)?.into_iter().filter(|e| e.source() == source) {
        let from = journal.join(&entry.id);
        let to = journal.join(format!("{}.undone", entry.id));
        std::fs::rename(&from, &to)
            .with_context(|| format!("renaming {} to {}", from.display(), to.display()))?;
        n += 1;
    }
    if n > 0 {
        sync_dir(journal)?;
    }
    Ok(n)
}

/// Every entry in `journal`, oldest first (none if it does not exist).
pub fn entries(journal: &Path) -> anyhow::Result<Vec<Entry>> {
    let read = match std::fs::read_dir(journal) {
        Ok(r) => r,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("reading import journal {}", journal.display())),
    };
    let mut found = Vec::new();
    for dir in read {
        let dir = dir?;
        let id = dir.file_name().to_string_lossy().into_owned();
        let Some(key) = parse_id(&id) else {
            continue;
        };
        if !dir.file_type()?.is_dir() {
            continue;
        }
        for file in std::fs::read_dir(dir.path())? {
            let file = file?;
            if file.file_type()?.is_file() {
                found.push((
                    key,
                    Entry {
                        id: id.clone(),
                        file: file.path(),
                    },
                ));
            }
        }
    }
    found.sort_by_key(|a| a.0);
    Ok(found.into_iter().map(|(_, e)| e).collect())
}

/// The newest kept copy of a CSV named `name`, an entry's or one set aside
/// by `--undo`: (its path, true when undone). `phyllo import --dir` compares
/// a folder's file with it to tell a changed file from one already taken.
pub fn newest_copy(journal: &Path, name: &str) -> anyhow::Result<Option<(PathBuf, bool)>> {
    let read = match std::fs::read_dir(journal) {
        Ok(r) => r,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("reading import journal {}", journal.display())),
    };
    let mut newest: Option<((NaiveDateTime, u32), PathBuf, bool)> = None;
    for dir in read {
        let dir = dir?;
        let id = dir.file_name().to_string_lossy().into_owned();
        let (stem, undone) = match id.strip_suffix(".undone") {
            Some(stem) => (stem, true),
            None => (id.as_str(), false),
        };
        let Some(key) = parse_id(stem) else {
            continue;
        };
        let copy = dir.path().join(name);
        if copy.is_file() && newest.as_ref().is_none_or(|n| key > n.0) {
            newest = Some((key, copy, undone));
        }
    }
    Ok(newest.map(|(_, path, undone)| (path, undone)))
}

/// The entries of `journal` not in `held` (a database's imports), oldest first.
pub fn missing(journal: &Path, held: &BTreeSet<String>) -> anyhow::Result<Vec<Entry>> {
    Ok(entries(journal)?
        .into_iter()
        .filter(|e| !held.contains(&e.id))
        .collect())
}

/// The entry `csv` is, when it lies in `journal`.
fn entry_of(journal: &Path, csv: &Path) -> Option<Entry> {
    let journal = journal.canonicalize().ok()?;
    let csv = csv.canonicalize().ok()?;
    let entry_dir = csv.parent()?;
    if entry_dir.parent()? != journal {
        return None;
    }
    let id = entry_dir.file_name()?.to_str()?.to_owned();
    parse_id(&id)?;
    Some(Entry { id, file: csv })
}

/// The sort key of an entry name, or `None` for other names.
fn parse_id(id: &str) -> Option<(NaiveDateTime, u32)> {
    let (stamp, n) = match id.get(STAMP_LEN..) {
        Some("") => (id, 0),
        Some(rest) => (&id[..STAMP_LEN], rest.strip_prefix('-')?.parse().ok()?),
        None => return None,
    };
    Some((NaiveDateTime::parse_from_str(stamp, STAMP).ok()?, n))
}

/// Length of a formatted [`STAMP`].
const STAMP_LEN: usize = "2026-12-05T101500".len();

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: &str) -> NaiveDateTime {
        NaiveDateTime::parse_from_str(s, "%Y-%m-%d %H:%M:%S").unwrap()
    }

    #[test]
    fn imports_are_kept_in_order_and_the_missing_ones_found() {
        let tmp = tempfile::tempdir().unwrap();
        let journal = dir(tmp.path());
        let csv = tmp.path().join("fixes.csv");
        std::fs::write(&csv, "plant,timestamp,view,leaf_count\nP1,2026-11-01,human,5\n").unwrap();
        let kept = |csv: &Path, now| {
            let kept = keep(&journal, csv, at(now)).unwrap();
            assert!(kept.copied);
            kept.entry
        };
        let first = kept(&csv, "2026-12-05 10:15:00");
        std::fs::write(&csv, "plant,timestamp,view,leaf_count\nP1,2026-11-01,human,6\n").unwrap();
        let second = kept(&csv, "2026-12-05 10:15:00");
        let third = kept(&csv, "2026-12-05 10:15:00");
        assert_eq!(
            [&first.id, &second.id, &third.id],
            ["2026-12-05T101500", "2026-12-05T101500-1", "2026-12-05T101500-2"]
        );
        assert_eq!(first.source(), "fixes.csv");
        assert!(std::fs::read_to_string(&first.file).unwrap().ends_with(",5\n"));
        assert!(std::fs::read_to_string(&second.file).unwrap().ends_with(",6\n"));
        // An entry imported again by hand is itself, not a new entry.
        let again = keep(&journal, &second.file, at("2026-12-06 08:00:00")).unwrap();
        assert_eq!((&again.entry, again.copied), (&second, false));
        // Other files in the journal are left alone.
        std::fs::write(journal.join("README"), "").unwrap();
        std::fs::create_dir_all(journal.join(".phyllo-import-dead")).unwrap();
        let later = kept(&csv, "2026-12-06 08:00:00");
        let all = entries(&journal).unwrap();
        assert_eq!(all, [first.clone(), second.clone(), third.clone(), later.clone()]);
        let held = BTreeSet::from([first.id.clone(), third.id.clone()]);
        assert_eq!(missing(&journal, &held).unwrap(), [second, later.clone()]);
        forget(&journal, &later).unwrap();
        assert_eq!(entries(&journal).unwrap().len(), 3);
        // Undone: set aside, no longer an entry.
        assert_eq!(retire(&journal, "fixes.csv").unwrap(), 3);
        assert!(entries(&journal).unwrap().is_empty());
        assert!(journal.join("2026-12-05T101500.undone/fixes.csv").exists());
        // A later import in the same second does not take an undone entry's name.
        let next = kept(&csv, "2026-12-05 10:15:00");
        assert_eq!(next.id, "2026-12-05T101500-3");
        assert_eq!(retire(&journal, "fixes.csv").unwrap(), 1);
        assert!(entries(&tmp.path().join("none")).unwrap().is_empty());
    }
}
