//! `phyllo backup`: a consistent snapshot of the live database, checked and
//! renamed into place, so a lost or corrupted disk costs at most a day.
//!
//! `VACUUM INTO` copies the database as one read transaction: the service
//! keeps writing meanwhile (WAL), and the copy is compact and self-contained
//! (no `-wal` file to lose). SQLite does not sync what `VACUUM INTO` writes,
//! so the copy is synced, its integrity checked, and only then renamed to its
//! final name and the directory synced: a snapshot under a final name is
//! always whole, even after a power cut.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::{bail, Context};
use chrono::NaiveDateTime;

use crate::files::atomic::sync_dir;
use crate::store::snapshot;
pub use crate::store::snapshot::Contents;

/// File-name prefix and suffix of a snapshot: `phyllo-<YYYY-MM-DD>T<HHMMSS>[-N].sqlite`.
const PREFIX: &str = "phyllo-";
const SUFFIX: &str = ".sqlite";
const STAMP: &str = "%Y-%m-%dT%H%M%S";
/// Work directories of a snapshot being written.
const WORK_PREFIX: &str = ".phyllo-backup-";
/// A work directory older than this is left over from a run that died.
const STALE_WORK: Duration = Duration::from_secs(6 * 3600);

/// One snapshot on disk.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Snapshot {
    /// Its file.
    pub path: PathBuf,
    /// When it was taken (local time, from its name).
    pub taken_at: NaiveDateTime,
    /// Its size in bytes.
    pub bytes: u64,
}

impl Snapshot {
    /// Whole hours since it was taken (facility time, as its name).
    pub fn age_hours(&self) -> i64 {
        (chrono::Local::now().naive_local() - self.taken_at).num_hours()
    }
}

/// Writes a snapshot of the `source` database into `dir`, named for `now`.
pub fn snapshot(
    source: &snapshot::Source,
    dir: &Path,
    now: NaiveDateTime,
) -> anyhow::Result<(Snapshot, Contents)> {
    crate::files::owner::create_dir_all(dir)
        .with_context(|| format!("creating backup directory {}", dir.display()))?;
    remove_stale_work(dir);
    // VACUUM INTO writes at most the live pages; refuse before writing if
    // that would leave the service (often on the same disk) too little.
    let need = source.live_bytes()?;
    let free = crate::files::disk::free_bytes(dir)?;
    if free < need + crate::files::disk::SNAPSHOT_RESERVE_BYTES {
        bail!(
            "backup directory {} has {} free; a snapshot needs about {} and must leave {} for the service: \
             free space there, lower [backup] keep, or point [backup] dir at another disk",
            dir.display(),
            crate::files::disk::human(free),
            crate::files::disk::human(need),
            crate::files::disk::human(crate::files::disk::SNAPSHOT_RESERVE_BYTES)
        );
    }
    let work = tempfile::Builder::new()
        .prefix(WORK_PREFIX)
        .tempdir_in(dir)
        .with_context(|| format!("creating a work directory in {}", dir.display()))?;
    let copy = work.path().join("snapshot.sqlite");
    let copy_str = copy
        .to_str()
        .with_context(|| format!("backup directory {} is not valid UTF-8", dir.display()))?;
    source
        .copy_into(copy_str)
        .with_context(|| format!("copying the database into {}", copy.display()))?;
    std::fs::File::open(&copy)
        .and_then(|f| f.sync_all())
        .with_context(|| format!("syncing {}", copy.display()))?;
    let contents = check(&copy)?;
    let source_schema = source.schema_version()?;
    if contents.schema != source_schema {
        bail!(
            "snapshot {} has schema {} but the database has {source_schema}",
            copy.display(),
            contents.schema
        );
    }
    let path = free_name(dir, now);
    std::fs::rename(&copy, &path)
        .with_context(|| format!("renaming the snapshot into {}", path.display()))?;
    crate::files::owner::match_parent(&path);
    sync_dir(dir)?;
    let bytes = std::fs::metadata(&path)?.len();
    Ok((
        Snapshot {
            path,
            taken_at: now,
            bytes,
        },
        contents,
    ))
}

/// Opens a snapshot read-only, runs SQLite's full integrity check and reads
/// what it holds. Also what an operator runs on a snapshot before restoring it.
pub fn check(path: &Path) -> anyhow::Result<Contents> {
    crate::store::snapshot::check_file(path)
}

/// What [`restore`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Restored {
    /// What the restored database holds.
    pub contents: Contents,
    /// The database's former files (main, `-wal`, `-shm`), moved aside, never deleted.
    pub moved_aside: Vec<PathBuf>,
}

/// Puts `snapshot` in place of `database`, while no service runs on it.
///
/// The snapshot is checked first and copied beside the database (synced)
/// before anything is moved. The database's files are then moved aside,
/// `-wal` and `-shm` included: a write-ahead log left beside a restored
/// database would be replayed onto it and corrupt it. Images dropped after
/// the snapshot are found by the next start's scan and counted again.
/// `_held` shows that no service, import or recount is writing the database.
pub fn restore(
    snapshot: &Path,
    database: &Path,
    now: NaiveDateTime,
    _held: &crate::store::RestoreLock,
) -> anyhow::Result<Restored> {
    // Through a symlink, the file it leads to is the one replaced (and the
    // one the lock guards), not the link.
    let database = &crate::files::identity::resolved(database);
    let contents = check(snapshot)?;
    let known = crate::store::migrations::SCHEMA_VERSION as i64;
    if contents.schema > known {
        bail!(
            "snapshot {} has schema {}, newer than this phyllo knows ({known}): restore it with the phyllo that wrote it",
            snapshot.display(),
            contents.schema
        );
    }
    let dir = match database.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut staged = tempfile::Builder::new()
        .prefix(".phyllo-restore-")
        .tempfile_in(dir)
        .with_context(|| format!("creating a temporary file in {}", dir.display()))?;
    let mut from =
        std::fs::File::open(snapshot).with_context(|| format!("opening {}", snapshot.display()))?;
    std::io::copy(&mut from, staged.as_file_mut())
        .with_context(|| format!("copying {} into {}", snapshot.display(), dir.display()))?;
    staged.as_file().sync_all()?;
    // A restore run as root must leave a database the service user can open.
    crate::files::owner::match_parent(staged.path());
    if let Ok(old) = std::fs::metadata(database) {
        std::fs::set_permissions(staged.path(), old.permissions())
            .with_context(|| format!("setting the mode of {}", staged.path().display()))?;
    }
    let stamp = now.format(STAMP);
    let mut moved_aside = Vec::new();
    for suffix in ["", "-wal", "-shm", "-journal"] {
        let mut name = database.as_os_str().to_owned();
        name.push(suffix);
        let file = PathBuf::from(name);
        if file.exists() {
            let mut aside = file.clone().into_os_string();
            aside.push(format!(".before-restore-{stamp}"));
            let aside = PathBuf::from(aside);
            std::fs::rename(&file, &aside)
                .with_context(|| format!("moving {} aside to {}", file.display(), aside.display()))?;
            moved_aside.push(aside);
        }
    }
    staged
        .persist(database)
        .with_context(|| format!("renaming the restored database into {}", database.display()))?;
    sync_dir(dir)?;
    Ok(Restored {
        contents,
        moved_aside,
    })
}

/// The snapshots in `dir`, oldest first (none if `dir` does not exist).
/// Other files are left alone and not listed.
pub fn list(dir: &Path) -> anyhow::Result<Vec<Snapshot>> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("reading backup directory {}", dir.display())),
    };
    let mut found = Vec::new();
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name();
        let Some((taken_at, n)) = name.to_str().and_then(parse_name) else {
            continue;
        };
        let meta = entry.metadata()?;
        if meta.is_file() {
            found.push((
                taken_at,
                n,
                Snapshot {
                    path: entry.path(),
                    taken_at,
                    bytes: meta.len(),
                },
            ));
        }
    }
    found.sort_by_key(|a| (a.0, a.1));
    Ok(found.into_iter().map(|(_, _, s)| s).collect())
}

/// How many snapshots [`prune`] keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Retention {
    /// The newest snapshots kept, whatever their age (0: keep every snapshot).
    pub newest: usize,
    /// Beyond those, the newest snapshot of each of this many earlier
    /// calendar months: a fault found weeks late can still be undone.
    pub monthly: usize,
}

/// The snapshots `retention` keeps, from `all` sorted oldest first.
fn kept(all: &[Snapshot], retention: Retention) -> Vec<bool> {
    use chrono::Datelike;
    if retention.newest == 0 {
        return vec![true; all.len()];
    }
    let mut keep = vec![false; all.len()];
    let mut months = std::collections::BTreeSet::new();
    let mut extra_months = 0;
    // Newest first: the newest N, then the newest of each month not yet held.
    for (rank, i) in (0..all.len()).rev().enumerate() {
        let month = (all[i].taken_at.year(), all[i].taken_at.month());
        if rank < retention.newest {
            keep[i] = true;
            months.insert(month);
        } else if extra_months < retention.monthly && months.insert(month) {
            keep[i] = true;
            extra_months += 1;
        }
    }
    keep
}

/// Deletes the snapshots `retention` does not keep. Returns the files deleted.
pub fn prune(dir: &Path, retention: Retention) -> anyhow::Result<Vec<PathBuf>> {
    let all = list(dir)?;
    let mut removed = Vec::new();
    for (old, keep) in all.iter().zip(kept(&all, retention)) {
        if keep {
            continue;
        }
        std::fs::remove_file(&old.path)
            .with_context(|| format!("deleting old snapshot {}", old.path.display()))?;
        removed.push(old.path.clone());
    }
    if !removed.is_empty() {
        sync_dir(dir)?;
    }
    Ok(removed)
}

/// `phyllo-<stamp>[-N].sqlite` → (time, N).
fn parse_name(name: &str) -> Option<(NaiveDateTime, u32)> {
    let core = name.strip_prefix(PREFIX)?.strip_suffix(SUFFIX)?;
    let (stamp, n) = match core.rsplit_once('-') {
        // The date has dashes too: only a suffix after the time part is a counter.
        Some((head, tail)) if head.contains('T') => (head, tail.parse().ok()?),
        _ => (core, 0),
    };
    Some((NaiveDateTime::parse_from_str(stamp, STAMP).ok()?, n))
}

/// The first unused snapshot name for `now` (a second run within the same
/// second gets `-1`, `-2`, ...).
fn free_name(dir: &Path, now: NaiveDateTime) -> PathBuf {
    let stamp = now.format(STAMP);
    let mut path = dir.join(format!("{PREFIX}{stamp}{SUFFIX}"));
    let mut n = 1;
    while path.exists() {
        path = dir.join(format!("{PREFIX}{stamp}-{n}{SUFFIX}"));
        n += 1;
    }
    path
}

/// Removes work directories left by a run that died (a power cut mid-copy).
/// Young ones may belong to a run in progress and stay.
fn remove_stale_work(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let stale = entry.file_name().to_string_lossy().starts_with(WORK_PREFIX)
            && entry
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| SystemTime::now().duration_since(t).ok())
                .is_some_and(|age| age > STALE_WORK);
        if stale {
            if let Err(e) = std::fs::remove_dir_all(entry.path()) {
                tracing::warn!("could not remove {}: {e}", entry.path().display());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use rusqlite::Connection;

    use super::*;

    fn at(s: &str) -> NaiveDateTime {
        NaiveDateTime::parse_from_str(s, "%Y-%m-%d %H:%M:%S").unwrap()
    }

    fn db_with(dir: &Path, images: usize) -> Connection {
        let conn = Connection::open(dir.join("live.sqlite")).unwrap();
        conn.pragma_update(None, "journal_mode", "WAL").unwrap();
        conn.pragma_update(None, "user_version", 3).unwrap();
        conn.execute_batch(
            "CREATE TABLE images (id INTEGER PRIMARY KEY); CREATE TABLE plants (id INTEGER PRIMARY KEY);",
        )
        .unwrap();
        for _ in 0..images {
            conn.execute("INSERT INTO images DEFAULT VALUES", []).unwrap();
        }
        conn
    }

    #[test]
    fn names_round_trip_and_sort() {
        assert_eq!(
            parse_name("phyllo-2026-12-05T023012.sqlite"),
            Some((at("2026-12-05 02:30:12"), 0))
        );
        assert_eq!(
            parse_name("phyllo-2026-12-05T023012-2.sqlite"),
            Some((at("2026-12-05 02:30:12"), 2))
        );
        for other in [
            "phyllo.sqlite",
            "phyllo-2026-12-05.sqlite",
            "phyllo-x.sqlite",
            "notes.txt",
        ] {
            assert_eq!(parse_name(other), None, "{other}");
        }
    }

    #[test]
    fn snapshot_is_whole_checked_and_named() {
        let tmp = tempfile::tempdir().unwrap();
        let conn = db_with(tmp.path(), 5);
        let dir = tmp.path().join("backups");
        let now = at("2026-12-05 02:30:12");
        let (snap, contents) = snapshot(&(&conn).into(), &dir, now).unwrap();
        assert_eq!(snap.path, dir.join("phyllo-2026-12-05T023012.sqlite"));
        assert_eq!(
            contents,
            Contents {
                images: 5,
                plants: 0,
                schema: 3
            }
        );
        // A second one in the same second gets its own name; no work directory is left.
        let (again, _) = snapshot(&(&conn).into(), &dir, now).unwrap();
        assert_eq!(again.path, dir.join("phyllo-2026-12-05T023012-1.sqlite"));
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
        assert_eq!(list(&dir).unwrap(), vec![snap, again]);
    }

    #[test]
    fn prune_keeps_the_newest_and_only_touches_snapshots() {
        let tmp = tempfile::tempdir().unwrap();
        let conn = db_with(tmp.path(), 1);
        let dir = tmp.path().join("backups");
        for day in 1..=5 {
            snapshot(&(&conn).into(), &dir, at(&format!("2026-12-0{day} 02:30:00"))).unwrap();
        }
        std::fs::write(dir.join("README"), "operator's note").unwrap();
        let removed = prune(
            &dir,
            Retention {
                newest: 2,
                monthly: 0,
            },
        )
        .unwrap();
        assert_eq!(removed.len(), 3);
        let left: Vec<NaiveDateTime> = list(&dir).unwrap().iter().map(|s| s.taken_at).collect();
        assert_eq!(left, vec![at("2026-12-04 02:30:00"), at("2026-12-05 02:30:00")]);
        assert!(dir.join("README").exists());
        assert!(prune(
            &dir,
            Retention {
                newest: 0,
                monthly: 0
            }
        )
        .unwrap()
        .is_empty());
    }

    #[test]
    fn monthly_snapshots_outlive_the_daily_ones() {
        // Daily snapshots from 1 August to 14 December.
        let start = at("2026-08-01 02:00:00");
        let all: Vec<Snapshot> = (0..136)
            .map(|d| Snapshot {
                path: PathBuf::from(format!("{d}")),
                taken_at: start + chrono::Duration::days(d),
                bytes: 1,
            })
            .collect();
        let keep = kept(
            &all,
            Retention {
                newest: 14,
                monthly: 3,
            },
        );
        let days: Vec<String> = all
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(s, _)| s.taken_at.format("%m-%d").to_string())
            .collect();
        // The last 14 days (all December), then the last day of November, October, September.
        let mut want = vec!["09-30", "10-31", "11-30"];
        let dec: Vec<String> = (1..=14).map(|d| format!("12-{d:02}")).collect();
        want.extend(dec.iter().map(String::as_str));
        assert_eq!(days, want);
        assert!(kept(
            &all,
            Retention {
                newest: 0,
                monthly: 3
            }
        )
        .iter()
        .all(|k| *k));
    }

    #[test]
    fn a_damaged_snapshot_is_named_and_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let conn = db_with(tmp.path(), 200);
        let dir = tmp.path().join("backups");
        let (snap, _) = snapshot(&(&conn).into(), &dir, at("2026-12-05 02:30:00")).unwrap();
        // Overwrite the second page (the first table's b-tree) with garbage.
        let mut bytes = std::fs::read(&snap.path).unwrap();
        let page = u16::from_be_bytes([bytes[16], bytes[17]]) as usize;
        bytes[page..2 * page].fill(0xA5);
        std::fs::write(&snap.path, bytes).unwrap();
        let err = format!("{:#}", check(&snap.path).unwrap_err());
        assert!(err.contains(&snap.path.display().to_string()), "{err}");
    }

    #[test]
    fn restore_moves_the_old_files_aside_and_refuses_a_locked_database() {
        let tmp = tempfile::tempdir().unwrap();
        let conn = db_with(tmp.path(), 3);
        let (snap, _) = snapshot(
            &(&conn).into(),
            &tmp.path().join("backups"),
            at("2026-12-05 02:30:00"),
        )
        .unwrap();
        conn.execute("INSERT INTO images DEFAULT VALUES", []).unwrap();
        drop(conn);
        let live = tmp.path().join("live.sqlite");
        // The live database's write-ahead log must go aside with it.
        std::fs::write(tmp.path().join("live.sqlite-wal"), b"stale log").unwrap();
        let held = crate::store::DatabaseLock::acquire(&live, "phyllo serve").unwrap();
        let err = crate::store::RestoreLock::acquire(&live).unwrap_err().to_string();
        assert!(err.contains("phyllo serve"), "{err}");
        drop(held);
        let lock = crate::store::RestoreLock::acquire(&live).unwrap();
        let done = restore(&snap.path, &live, at("2026-12-05 09:00:00"), &lock).unwrap();
        assert_eq!(done.contents.images, 3);
        let aside: Vec<String> = done
            .moved_aside
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            aside,
            [
                "live.sqlite.before-restore-2026-12-05T090000",
                "live.sqlite-wal.before-restore-2026-12-05T090000"
            ]
        );
        assert!(!tmp.path().join("live.sqlite-wal").exists());
        let n: i64 = Connection::open(&live)
            .unwrap()
            .query_row("SELECT COUNT(*) FROM images", [], |r| r.get(0))
            .unwrap();
        assert_eq!(n, 3);
        let old: i64 = Connection::open(&done.moved_aside[0])
            .unwrap()
            .query_row("SELECT COUNT(*) FROM images", [], |r| r.get(0))
            .unwrap();
        assert_eq!(old, 4);
    }

    #[test]
    fn a_snapshot_from_a_newer_phyllo_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let conn = db_with(tmp.path(), 1);
        let newer = crate::store::migrations::SCHEMA_VERSION as i64 + 1;
        conn.pragma_update(None, "user_version", newer).unwrap();
        let (snap, _) = snapshot(
            &(&conn).into(),
            &tmp.path().join("backups"),
            at("2026-12-05 02:30:00"),
        )
        .unwrap();
        let live = tmp.path().join("other.sqlite");
        let lock = crate::store::RestoreLock::acquire(&live).unwrap();
        let err = restore(&snap.path, &live, at("2026-12-05 09:00:00"), &lock)
            .unwrap_err()
            .to_string();
        assert!(err.contains("newer than this phyllo"), "{err}");
        assert!(!live.exists());
    }

    #[test]
    fn an_unwritable_directory_is_named() {
        let tmp = tempfile::tempdir().unwrap();
        let conn = db_with(tmp.path(), 1);
        let file = tmp.path().join("not-a-dir");
        std::fs::write(&file, "").unwrap();
        let err = format!(
            "{:#}",
            snapshot(&(&conn).into(), &file, at("2026-12-05 02:30:00")).unwrap_err()
        );
        assert!(err.contains("not-a-dir"), "{err}");
    }
}
