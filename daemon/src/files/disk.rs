//! Free space on the file systems phyllo writes to. A service that runs for
//! months fills its disk slowly (database, nightly exports and snapshots);
//! `phyllo status` says how much is left and `phyllo backup` refuses a
//! snapshot that would leave the service too little.

use std::path::Path;

use anyhow::Context;

/// Bytes available to an unprivileged writer on the file system holding `path`.
pub fn free_bytes(path: &Path) -> anyhow::Result<u64> {
    let st =
        rustix::fs::statvfs(path).with_context(|| format!("reading free space of {}", path.display()))?;
    Ok(st.f_bavail.saturating_mul(st.f_frsize))
}

/// Below this much free space `phyllo status` warns.
pub const LOW_FREE_BYTES: u64 = 1 << 30;

/// Space a snapshot must leave free for the service beside it.
pub const SNAPSHOT_RESERVE_BYTES: u64 = 256 << 20;

/// How often a low-disk warning is repeated in the log while it lasts.
const WARN_EVERY: std::time::Duration = std::time::Duration::from_secs(3600);

/// The service's watch on the space beside its database: a disk that fills
/// slowly (exports, snapshots) is said in the log, hourly while it lasts,
/// before counting starts to fail.
#[derive(Debug)]
pub struct LowDiskWatch {
    dir: std::path::PathBuf,
    low: Option<u64>,
    warned_at: Option<std::time::Instant>,
}

impl LowDiskWatch {
    /// Watches the file system holding `dir`.
    pub fn new(dir: std::path::PathBuf) -> Self {
        Self {
            dir,
            low: None,
            warned_at: None,
        }
    }

    /// Reads the free space now, and logs a warning if it is low and the log
    /// has not said so within the hour.
    pub fn check(&mut self) {
        self.low = free_bytes(&self.dir).ok().filter(|&free| free < LOW_FREE_BYTES);
        match self.low {
            Some(free) if self.warned_at.is_none_or(|t| t.elapsed() >= WARN_EVERY) => {
                tracing::warn!(
                    "only {} free beside the database in {}: counting fails when it runs out",
                    human(free),
                    self.dir.display()
                );
                self.warned_at = Some(std::time::Instant::now());
            }
            Some(_) => {}
            None => self.warned_at = None,
        }
    }

    /// Bytes free as of the last check, when that was low.
    pub fn low(&self) -> Option<u64> {
        self.low
    }
}

/// Bytes as a short human figure (MB below 10 GB, GB above).
pub fn human(bytes: u64) -> String {
    if bytes >= 10_000_000_000 {
        format!("{:.0} GB", bytes as f64 / 1e9)
    } else {
        format!("{:.0} MB", bytes as f64 / 1e6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_space_is_read_and_named_on_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(free_bytes(dir.path()).unwrap() > 0);
        let err = format!("{:#}", free_bytes(&dir.path().join("missing")).unwrap_err());
        assert!(err.contains("missing"), "{err}");
        assert_eq!(human(512 << 20), "537 MB");
        assert_eq!(human(40_000_000_000), "40 GB");
    }
}
