//! Who may write a database, and when.
//!
//! `phyllo serve` and `phyllo restore` hold an exclusive advisory lock on
//! `<database>.lock` for as long as they run. A second service on the same
//! database (an operator's `phyllo serve` beside the systemd unit) would
//! count every image twice over the same files, and a restore under a
//! running service would swap the file out from under its open connections.
//!
//! `phyllo import` and `phyllo recount` write beside the service, so they
//! share a second lock, `<database>.writers.lock`, which a restore takes
//! exclusively: their writes would otherwise land in the file the restore
//! moves aside, and be lost.
//!
//! The kernel drops a lock when its process dies, so a crash or `kill -9`
//! never leaves a stale one.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

/// The service lock, held for as long as this value lives.
#[derive(Debug)]
pub struct DatabaseLock {
    _file: File,
    path: PathBuf,
}

impl DatabaseLock {
    /// Takes the lock of `database` for `holder` (written into the lock file,
    /// with the pid, so the refusal can say who holds it), or fails at once.
    pub fn acquire(database: &Path, holder: &str) -> anyhow::Result<DatabaseLock> {
        let path = lock_path(database, ".lock");
        let mut file = open(&path)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut who = String::new();
                let _ = file.read_to_string(&mut who);
                let who = who.trim();
                bail!(
                    "database {} is in use by {} (lock file {}): stop it first",
                    database.display(),
                    if who.is_empty() {
                        "another phyllo process"
                    } else {
                        who
                    },
                    path.display()
                );
            }
            Err(TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("locking {}", path.display()));
            }
        }
        file.set_len(0)?;
        file.rewind()?;
        write!(file, "{holder} (pid {})", std::process::id())?;
        Ok(DatabaseLock { _file: file, path })
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// The writers' lock: shared by the commands that write beside the service,
/// exclusive for a restore. Held for as long as this value lives.
#[derive(Debug)]
pub struct WritersLock {
    _file: File,
}

impl WritersLock {
    /// Shares the lock with the other writers (`phyllo import`, `phyllo
    /// recount`); fails at once while a restore holds it.
    pub fn shared(database: &Path) -> anyhow::Result<WritersLock> {
        let path = lock_path(database, ".writers.lock");
        let file = open(&path)?;
        match file.try_lock_shared() {
            Ok(()) => Ok(WritersLock { _file: file }),
            Err(TryLockError::WouldBlock) => bail!(
                "database {} is being restored (lock file {}): run this again once `phyllo restore` has finished",
                database.display(),
                path.display()
            ),
            Err(TryLockError::Error(e)) => Err(e).with_context(|| format!("locking {}", path.display())),
        }
    }

    /// Takes the lock alone; fails at once while an import or a recount runs.
    pub fn exclusive(database: &Path) -> anyhow::Result<WritersLock> {
        let path = lock_path(database, ".writers.lock");
        let file = open(&path)?;
        match file.try_lock() {
            Ok(()) => Ok(WritersLock { _file: file }),
            Err(TryLockError::WouldBlock) => bail!(
                "database {} is being written by `phyllo import` or `phyllo recount` (lock file {}): let it finish first",
                database.display(),
                path.display()
            ),
            Err(TryLockError::Error(e)) => Err(e).with_context(|| format!("locking {}", path.display())),
        }
    }
}

/// Both locks, as a restore holds them: no service, no import, no recount.
#[derive(Debug)]
pub struct RestoreLock {
    _service: DatabaseLock,
    _writers: WritersLock,
}

impl RestoreLock {
    /// Takes both locks of `database`, or fails at once naming who holds one.
    pub fn acquire(database: &Path) -> anyhow::Result<RestoreLock> {
        let service = DatabaseLock::acquire(database, "phyllo restore")?;
        let writers = WritersLock::exclusive(database)?;
        Ok(RestoreLock {
            _service: service,
            _writers: writers,
        })
    }
}

/// Opens (creating it and its directory) a lock file.
fn open(path: &Path) -> anyhow::Result<File> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        crate::files::owner::create_dir_all(dir)
            .with_context(|| format!("creating database directory {}", dir.display()))?;
    }
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .with_context(|| format!("opening lock file {}", path.display()))?;
    // Made by root, it would keep the service user out of every later lock.
    crate::files::owner::match_parent(path);
    Ok(file)
}

/// `<database><suffix>`, beside the file the database path leads to: a
/// symlink to a live database, or another spelling of its path, finds the
/// same lock file and is refused.
fn lock_path(database: &Path, suffix: &str) -> PathBuf {
    let mut name = crate::files::identity::resolved(database).into_os_string();
    name.push(suffix);
    PathBuf::from(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_by_name_until_the_first_lets_go() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("state/phyllo.sqlite");
        let first = DatabaseLock::acquire(&db, "phyllo serve").unwrap();
        assert_eq!(first.path(), dir.path().join("state/phyllo.sqlite.lock"));
        let err = DatabaseLock::acquire(&db, "phyllo restore")
            .unwrap_err()
            .to_string();
        let pid = std::process::id();
        assert!(err.contains(&format!("phyllo serve (pid {pid})")), "{err}");
        assert!(err.contains("phyllo.sqlite.lock"), "{err}");
        drop(first);
        DatabaseLock::acquire(&db, "phyllo restore").unwrap();
    }

    #[test]
    fn writers_share_their_lock_and_a_restore_waits_for_all_of_them() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("phyllo.sqlite");
        let import = WritersLock::shared(&db).unwrap();
        let recount = WritersLock::shared(&db).unwrap();
        let err = RestoreLock::acquire(&db).unwrap_err().to_string();
        assert!(
            err.contains("phyllo import") && err.contains("writers.lock"),
            "{err}"
        );
        drop(import);
        assert!(RestoreLock::acquire(&db).is_err(), "the recount still writes");
        drop(recount);
        let restore = RestoreLock::acquire(&db).unwrap();
        let err = WritersLock::shared(&db).unwrap_err().to_string();
        assert!(err.contains("being restored"), "{err}");
        // The service lock was let go with the refused attempts.
        assert!(DatabaseLock::acquire(&db, "phyllo serve").is_err());
        drop(restore);
        WritersLock::shared(&db).unwrap();
        DatabaseLock::acquire(&db, "phyllo serve").unwrap();
    }

    #[test]
    fn a_symlink_to_the_live_database_finds_the_same_lock() {
        let dir = tempfile::tempdir().unwrap();
        let live = dir.path().join("state/phyllo.sqlite");
        std::fs::create_dir_all(live.parent().unwrap()).unwrap();
        std::fs::write(&live, b"").unwrap();
        std::fs::create_dir(dir.path().join("other")).unwrap();
        let link = dir.path().join("other/db.sqlite");
        std::os::unix::fs::symlink(&live, &link).unwrap();
        let _service = DatabaseLock::acquire(&live, "phyllo serve").unwrap();
        let err = DatabaseLock::acquire(&link, "phyllo serve")
            .unwrap_err()
            .to_string();
        assert!(err.contains("in use by phyllo serve"), "{err}");
        let err = RestoreLock::acquire(&link).unwrap_err().to_string();
        assert!(err.contains("in use by phyllo serve"), "{err}");
        let spelled = dir.path().join("other/../state/./phyllo.sqlite");
        assert!(DatabaseLock::acquire(&spelled, "phyllo serve").is_err());
    }
}
