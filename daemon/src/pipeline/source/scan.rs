//! Scanning the drop directory: at start, periodically, when events were
//! lost, and for directories that appear. Runs on a blocking thread.

use std::path::{Path, PathBuf};

use super::Filter;

/// Every image file under `dir` (recursively) that the filter wants.
/// Unreadable directories are logged and skipped: one bad folder must not
/// hide the rest of the tree. Files and folders whose path is too long to
/// open are returned too, so that the worker records them as failed, named.
pub fn scan(filter: &Filter, dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = match std::fs::read_dir(&d) {
            Ok(e) => e,
            Err(e) if crate::files::too_long(&e) => {
                out.push(d);
                continue;
            }
            Err(e) => {
                if d != filter.root() || e.kind() != std::io::ErrorKind::NotFound {
                    tracing::warn!("scan: cannot read directory {}: {e}", d.display());
                }
                continue;
            }
        };
        for entry in entries.flatten() {
            let path = entry.path();
            // file_type() does not follow symlinks; metadata() does, so links to images are
            // candidates (the worker refuses those that lead out of the drop directory).
            let meta = match std::fs::metadata(&path) {
                Ok(m) => m,
                Err(e) => {
                    // A link that cannot be followed (loop, missing target) or a
                    // path too long to open: the worker records why.
                    let kind = entry.file_type().ok();
                    let link = kind.is_some_and(|t| t.is_symlink());
                    let folder = kind.is_some_and(|t| t.is_dir());
                    let wanted = if folder {
                        filter.wants_dir(&path)
                    } else {
                        filter.wants_file(&path)
                    };
                    if (link || crate::files::too_long(&e)) && wanted {
                        out.push(path);
                    }
                    continue;
                }
            };
            if meta.is_dir() {
                if filter.wants_dir(&path) && !entry.file_type().map(|t| t.is_symlink()).unwrap_or(false) {
                    stack.push(path);
                }
            } else if meta.is_file() && filter.wants_file(&path) {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::WatchConfig;

    #[test]
    fn scan_finds_nested_images_only() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        std::fs::create_dir_all(root.join("snap/Vis_SV_0")).unwrap();
        std::fs::create_dir_all(root.join(".partial")).unwrap();
        for f in [
            "a.png",
            "snap/Vis_SV_0/0_0_0.png",
            "snap/readme.txt",
            ".partial/b.png",
            ".c.png",
        ] {
            std::fs::write(root.join(f), b"x").unwrap();
        }
        let filter = Filter::new(root, &WatchConfig::default());
        let found: Vec<String> = scan(&filter, root)
            .iter()
            .map(|p| filter.rel(p).unwrap())
            .collect();
        assert_eq!(found, vec!["a.png", "snap/Vis_SV_0/0_0_0.png"]);
        assert!(scan(&filter, &root.join("missing")).is_empty());
    }
}
