//! Files written beside their final name, synced and renamed into place, so
//! a reader (a breeder's browser, a spreadsheet, the next export) never opens
//! half a file, and an error or a power cut leaves the old one as it was.

use std::path::Path;

use anyhow::Context;

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
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let tmp = tempfile::Builder::new()
        .prefix(".phyllo-")
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
    Ok(value)
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
}
