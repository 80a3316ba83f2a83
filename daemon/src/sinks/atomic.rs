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
    std::fs::File::open(tmp.path())
        .and_then(|f| f.sync_all())
        .with_context(|| format!("syncing {}", tmp.path().display()))?;
    tmp.persist(out)
        .with_context(|| format!("renaming into {}", out.display()))?;
    Ok(value)
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
