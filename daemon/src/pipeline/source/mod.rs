//! Sources: where candidate files come from.
//!
//! [`watch`] turns inotify events into [`Candidate`]s, [`scan`] walks the tree
//! at start and periodically (the safety net for lost events), and [`intake`]
//! decides when a file is complete and hands it to the bounded work queue.

pub mod intake;
pub mod scan;
pub mod watch;

use std::path::{Path, PathBuf};

use crate::config::WatchConfig;

/// Why a path was brought to the intake's attention.
#[derive(Debug, Clone, PartialEq)]
pub enum Candidate {
    /// A writer closed the file after writing: complete unless it reopens.
    Closed(PathBuf),
    /// The file was renamed or moved into the tree: complete.
    Renamed(PathBuf),
    /// Created or modified: wait until its size and mtime are stable.
    Changed(PathBuf),
    /// Found by a scan and not yet in the database.
    Scanned(PathBuf),
    /// Removed or renamed away: forget it.
    Removed(PathBuf),
    /// A directory appeared (created or moved in): scan it, since files may
    /// have landed in it before the watch on it was in place.
    ScanDir(PathBuf),
    /// Events were lost (queue overflow, watcher error): scan everything.
    RescanAll,
}

/// The file's metadata, following symbolic links; for a link that cannot be
/// followed (a loop, a missing target) the link's own metadata. Such links
/// still reach a worker, which records why they were not read instead of
/// leaving them silently unexplained.
/// Metadata of `path`, following a symlink, or of the link itself when its
/// target cannot be read.
pub fn stat_or_link(path: &Path) -> std::io::Result<std::fs::Metadata> {
    std::fs::metadata(path).or_else(|e| match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Ok(m),
        _ => Err(e),
    })
}

/// Which files are images phyllo should look at.
#[derive(Debug, Clone)]
pub struct Filter {
    root: PathBuf,
    extensions: Vec<String>,
    ignore_hidden: bool,
    /// With `[watch] skip_top_views`: the names that tell a top view.
    skip_top: Option<crate::domain::names::NamePatterns>,
}

impl Filter {
    /// Builds the filter for the drop directory `root`.
    pub fn new(root: &Path, cfg: &WatchConfig) -> Filter {
        Filter {
            root: root.to_path_buf(),
            extensions: cfg
                .extensions
                .iter()
                .map(|e| e.trim_start_matches('.').to_ascii_lowercase())
                .collect(),
            ignore_hidden: cfg.ignore_hidden,
            skip_top: None,
        }
    }

    /// The same filter, also leaving out every file `names` reads as a top
    /// view (by its name alone, so a skipped file is never read, not even by
    /// rescans).
    pub fn skipping_top_views(mut self, names: crate::domain::names::NamePatterns) -> Filter {
        self.skip_top = Some(names);
        self
    }

    /// The drop directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Path relative to the drop directory with `/` separators, if inside
    /// it, as lossless printable text ([`crate::domain::rel_path`]).
    pub fn rel(&self, path: &Path) -> Option<String> {
        crate::domain::rel_path::encode(path.strip_prefix(&self.root).ok()?)
    }

    /// True if a directory below the root should be descended into.
    pub fn wants_dir(&self, path: &Path) -> bool {
        !(self.ignore_hidden && self.hidden(path))
    }

    /// True if the path looks like an image phyllo should count.
    pub fn wants_file(&self, path: &Path) -> bool {
        if self.ignore_hidden && self.hidden(path) {
            return false;
        }
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if !self.extensions.contains(&ext) {
            return false;
        }
        // A name that does not parse is left to the worker, which records why.
        let top = self.skip_top.as_ref().is_some_and(|names| {
            self.rel(path)
                .and_then(|rel| names.parse(Path::new(&rel)).ok())
                .is_some_and(|n| n.view.is_top())
        });
        !top
    }

    fn hidden(&self, path: &Path) -> bool {
        let rel = path.strip_prefix(&self.root).unwrap_or(path);
        rel.components()
            .any(|c| c.as_os_str().to_string_lossy().starts_with('.'))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_views_are_left_out_when_asked() {
        let names =
            crate::domain::names::NamePatterns::from_config(&crate::config::NamesConfig::default()).unwrap();
        let cfg = WatchConfig::default();
        let side = Path::new("/drop/P1_2018-04-20_10-00-00_Vis_SV_36.png");
        let top = Path::new("/drop/P1_2018-04-20_10-02-00_Vis_TV_90.png");
        let odd = Path::new("/drop/not-a-phenotyping-name.png");
        let all = Filter::new(Path::new("/drop"), &cfg);
        assert!(all.wants_file(side) && all.wants_file(top) && all.wants_file(odd));
        let sides = all.skipping_top_views(names);
        assert!(sides.wants_file(side) && !sides.wants_file(top));
        assert!(sides.wants_file(odd), "the worker names what it cannot parse");
    }

    #[test]
    fn filter_images_and_hidden() {
        let f = Filter::new(Path::new("/drop"), &WatchConfig::default());
        assert!(f.wants_file(Path::new("/drop/a/P_2018-01-01_00-00-00_Vis_SV_0.PNG")));
        assert!(f.wants_file(Path::new("/drop/x.Crp.jpg")));
        assert!(!f.wants_file(Path::new("/drop/.x.png")));
        assert!(!f.wants_file(Path::new("/drop/.tmp/x.png")));
        assert!(!f.wants_file(Path::new("/drop/x.png.part")));
        assert!(!f.wants_file(Path::new("/drop/notes.txt")));
        assert_eq!(f.rel(Path::new("/drop/a/b.png")).as_deref(), Some("a/b.png"));
        assert_eq!(f.rel(Path::new("/elsewhere/b.png")), None);
        // A hidden parent of the root itself does not hide files.
        let f = Filter::new(Path::new("/home/.cache/drop"), &WatchConfig::default());
        assert!(f.wants_file(Path::new("/home/.cache/drop/b.png")));
    }
}
