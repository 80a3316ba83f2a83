//! One writer of a database at a time: `phyllo serve` and `phyllo restore`
//! hold an exclusive advisory lock on `<database>.lock` for as long as they
//! run. A second service on the same database (an operator's `phyllo serve`
//! beside the systemd unit) would count every image twice over the same
//! files, and a restore under a running service would swap the file out from
//! under its open connections. The kernel drops the lock when the process
//! dies, so a crash or `kill -9` never leaves a stale one.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

/// Held for as long as this value lives.
#[derive(Debug)]
pub struct DatabaseLock {
    _file: File,
    path: PathBuf,
}

impl DatabaseLock {
    /// Takes the lock of `database` for `holder` (written into the lock file,
    /// with the pid, so the refusal can say who holds it), or fails at once.
    pub fn acquire(database: &Path, holder: &str) -> anyhow::Result<DatabaseLock> {
        let path = lock_path(database);
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating database directory {}", dir.display()))?;
        }
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("opening lock file {}", path.display()))?;
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

/// `<database>.lock`, beside the database.
fn lock_path(database: &Path) -> PathBuf {
    let mut name = database.as_os_str().to_owned();
    name.push(".lock");
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
}
