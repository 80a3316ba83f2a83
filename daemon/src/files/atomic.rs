//! Files written beside their final name, synced and renamed into place, so
//! a reader (a breeder's browser, a spreadsheet, the next export) never opens
//! half a file, and an error or a power cut leaves the old one as it was.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, SystemTime};

use anyhow::Context;

/// Prefix of this module's temporaries.
const TMP_PREFIX: &str = ".phyllo-";

/// Other temporaries that share [`TMP_PREFIX`] and belong to their own
/// modules (backup, restore, import journal): never swept here.
const OTHER_PREFIXES: [&str; 3] = [".phyllo-backup-", ".phyllo-restore-", ".phyllo-import-"];

/// A temporary this old was left by a process that died mid-write (a killed
/// export): no export holds one open for an hour.
const STALE_AFTER: Duration = Duration::from_secs(3600);

/// Directories this process has already swept of stale temporaries.
static SWEPT: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// Calls `write` with a temporary path beside `out` (hidden, and ending in
/// `suffix`, since some encoders go by the extension), then syncs that file
/// and renames it to `out`. Creates `out`'s directory if needed.
pub fn replace<T>(
    out: &Path,
    suffix: &str,
    write: impl FnOnce(&Path) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    super::owner::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    sweep_once(dir);
    let tmp = tempfile::Builder::new()
        .prefix(TMP_PREFIX)
        .suffix(suffix)
        .tempfile_in(dir)
        .with_context(|| format!("creating a temporary file in {}", dir.display()))?;
    let value = write(tmp.path())?;
    // A temporary file is made private (0600); the finished file gets the
    // mode any new file would, so the breeders in the service's group can
    // read the exports (the units' UMask=0027).
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(
            tmp.path(),
            std::fs::Permissions::from_mode(0o666 & !process_umask()),
        )
        .with_context(|| format!("setting the mode of {}", tmp.path().display()))?;
    }
    std::fs::File::open(tmp.path())
        .and_then(|f| f.sync_all())
        .with_context(|| format!("syncing {}", tmp.path().display()))?;
    tmp.persist(out)
        .with_context(|| format!("renaming into {}", out.display()))?;
    super::owner::match_parent(out);
    Ok(value)
}

/// On this process's first write into `dir`, removes the temporaries that a
/// killed writer left there ([`remove_stale_temporaries`]). Once per
/// directory: a nightly export writes thousands of plots into one folder.
fn sweep_once(dir: &Path) {
    let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
    if swept.get_or_insert_with(HashSet::new).insert(dir.to_path_buf()) {
        remove_stale_temporaries(dir, STALE_AFTER);
    }
}

/// Removes from `dir` the regular files named like this module's
/// temporaries and last modified more than `age` ago; returns how many.
/// Best effort: a file that cannot be read or removed is left and logged.
pub fn remove_stale_temporaries(dir: &Path, age: Duration) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let now = SystemTime::now();
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if !name.starts_with(TMP_PREFIX) || OTHER_PREFIXES.iter().any(|p| name.starts_with(p)) {
            continue;
        }
        let Ok(meta) = entry.metadata() else { continue };
        let old = meta
            .modified()
            .ok()
            .and_then(|m| now.duration_since(m).ok())
            .is_some_and(|d| d > age);
        if !meta.is_file() || !old {
            continue;
        }
        match std::fs::remove_file(entry.path()) {
            Ok(()) => removed += 1,
            Err(e) => tracing::warn!("leaving the stale temporary {}: {e}", entry.path().display()),
        }
    }
    if removed > 0 {
        tracing::info!(
            "removed {removed} stale temporaries left in {} by an interrupted write",
            dir.display()
        );
    }
    removed
}

/// The process's file-creation mask, read from `/proc/self/status` (Linux
/// 4.7+): setting it to read it back would race other threads making files.
/// 0o022 where it cannot be read.
fn process_umask() -> u32 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("Umask:"))
                .and_then(|v| u32::from_str_radix(v.trim(), 8).ok())
        })
        .unwrap_or(0o022)
}

/// Makes a rename or deletion in `dir` durable.
pub fn sync_dir(dir: &Path) -> anyhow::Result<()> {
    std::fs::File::open(dir)
        .and_then(|d| d.sync_all())
        .with_context(|| format!("syncing directory {}", dir.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_finished_file_has_the_mode_the_umask_gives_not_a_temporary_files() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("plants.csv");
        replace(&out, ".csv", |p| Ok(std::fs::write(p, "a,b\n")?)).unwrap();
        let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
        // What a plain new file gets under the same umask.
        let plain = dir.path().join("plain");
        std::fs::write(&plain, "x").unwrap();
        assert_eq!(
            mode,
            std::fs::metadata(&plain).unwrap().permissions().mode() & 0o777
        );
        assert_eq!(mode, 0o666 & !process_umask());
    }

    #[test]
    fn the_old_file_stays_until_the_new_one_is_whole() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("sub/page.html");
        replace(&out, ".html", |p| Ok(std::fs::write(p, "one")?)).unwrap();
        let err = replace::<()>(&out, ".html", |p| {
            std::fs::write(p, "half")?;
            anyhow::bail!("the writer failed")
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "one");
        assert_eq!(
            std::fs::read_dir(dir.path().join("sub")).unwrap().count(),
            1,
            "no temporary left"
        );
    }

    /// Issue 57, item 12: a killed export's temporaries are removed by the
    /// next write into their folder; a live writer's, and other modules',
    /// are not.
    #[test]
    fn temporaries_left_by_a_killed_writer_are_swept_on_the_next_write() {
        let dir = tempfile::tempdir().unwrap();
        let make = |name: &str, age_secs: u64| {
            let path = dir.path().join(name);
            let f = std::fs::File::create(&path).unwrap();
            f.set_modified(SystemTime::now() - Duration::from_secs(age_secs))
                .unwrap();
            path
        };
        let stale_csv = make(".phyllo-a1B2c3.csv", 2 * 3600);
        let stale_png = make(".phyllo-d4E5f6.png", 30 * 86_400);
        let live = make(".phyllo-g7H8i9.png", 5);
        let backup = make(".phyllo-backup-x.sqlite", 2 * 3600);
        let operator = make("notes.csv", 2 * 3600);
        std::fs::create_dir(dir.path().join(".phyllo-dir")).unwrap();
        replace(&dir.path().join("plants.csv"), ".csv", |p| {
            Ok(std::fs::write(p, "a\n")?)
        })
        .unwrap();
        assert!(
            !stale_csv.exists() && !stale_png.exists(),
            "stale temporaries removed"
        );
        for kept in [&live, &backup, &operator, &dir.path().join(".phyllo-dir")] {
            assert!(kept.exists(), "{} kept", kept.display());
        }
        assert_eq!(
            remove_stale_temporaries(dir.path(), STALE_AFTER),
            0,
            "nothing left to sweep"
        );
    }
}
