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
