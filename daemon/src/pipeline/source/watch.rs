//! inotify (through `notify`) → [`Candidate`]s.
//!
//! The watch is recursive. Close-after-write and rename-into events mark a
//! file complete; create/modify events only say "something is being written"
//! and leave the decision to the intake's stability check. An overflowed
//! kernel queue turns into [`Candidate::RescanAll`].

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::SystemTime;

use notify::event::{AccessKind, AccessMode, CreateKind, ModifyKind, RenameMode};
use notify::{Event, EventKind, RecommendedWatcher, RecursiveMode, Watcher};
use tokio::sync::mpsc;

use super::{Candidate, Filter};

/// A live recursive watch on the drop directory.
pub struct Watch {
    _watcher: RecommendedWatcher,
    root: PathBuf,
    root_id: (u64, u64, Option<SystemTime>),
    /// Set when inotify reports the root itself removed or moved away.
    root_gone: Arc<AtomicBool>,
}

/// What identifies the directory at `path`: device, inode and birth time. The
/// birth time matters because a directory deleted and recreated at once very
/// often gets the same inode number back (ext4 does this).
fn dir_id(meta: &std::fs::Metadata) -> (u64, u64, Option<SystemTime>) {
    (meta.dev(), meta.ino(), meta.created().ok())
}

impl Watch {
    /// Starts watching `filter.root()`; candidates go to `tx`.
    pub fn start(filter: Filter, tx: mpsc::Sender<Candidate>) -> anyhow::Result<Watch> {
        let root = filter.root().to_path_buf();
        let meta = std::fs::metadata(&root)
            .map_err(|e| anyhow::anyhow!("drop directory {}: {e}", root.display()))?;
        let root_gone = Arc::new(AtomicBool::new(false));
        let (gone, watched) = (root_gone.clone(), root.clone());
        let mut watcher = notify::recommended_watcher(move |res: notify::Result<Event>| {
            if let Ok(e) = &res {
                let about_root = e.paths.iter().any(|p| p == &watched);
                if about_root
                    && matches!(
                        e.kind,
                        EventKind::Remove(_) | EventKind::Modify(ModifyKind::Name(RenameMode::From))
                    )
                {
                    gone.store(true, Ordering::SeqCst);
                }
            }
            for c in classify(&filter, res) {
                // This runs on notify's own thread. When the intake falls behind, this blocks and
                // the kernel queue absorbs events; if it overflows, we get a rescan event.
                if tx.blocking_send(c).is_err() {
                    return; // the service is shutting down
                }
            }
        })?;
        watcher
            .watch(&root, RecursiveMode::Recursive)
            .map_err(|e| anyhow::anyhow!("watching drop directory {}: {e}", root.display()))?;
        Ok(Watch {
            _watcher: watcher,
            root,
            root_id: dir_id(&meta),
            root_gone,
        })
    }

    /// True if the watched directory is gone or was replaced by another one
    /// (deleted and recreated): the watch must be restarted.
    pub fn is_stale(&self) -> bool {
        if self.root_gone.load(Ordering::SeqCst) {
            return true;
        }
        match std::fs::metadata(&self.root) {
            Ok(m) => dir_id(&m) != self.root_id,
            Err(_) => true,
        }
    }
}

fn classify(filter: &Filter, res: notify::Result<Event>) -> Vec<Candidate> {
    let event = match res {
        Ok(e) => e,
        Err(e) => {
            tracing::warn!("watch error, rescanning: {e}");
            return vec![Candidate::RescanAll];
        }
    };
    if event.need_rescan() {
        tracing::warn!("inotify queue overflowed, rescanning");
        return vec![Candidate::RescanAll];
    }
    let file = |p: &Path, make: fn(PathBuf) -> Candidate| -> Option<Candidate> {
        filter.wants_file(p).then(|| make(p.to_path_buf()))
    };
    let moved_in = |p: &Path| -> Option<Candidate> {
        if p.is_dir() {
            filter.wants_dir(p).then(|| Candidate::ScanDir(p.to_path_buf()))
        } else {
            file(p, Candidate::Renamed)
        }
    };
    let paths = &event.paths;
    let out: Vec<Option<Candidate>> = match event.kind {
        EventKind::Access(AccessKind::Close(AccessMode::Write)) => {
            paths.iter().map(|p| file(p, Candidate::Closed)).collect()
        }
        EventKind::Modify(ModifyKind::Name(RenameMode::To)) => paths.iter().map(|p| moved_in(p)).collect(),
        EventKind::Modify(ModifyKind::Name(RenameMode::Both)) if paths.len() == 2 => {
            vec![Some(Candidate::Removed(paths[0].clone())), moved_in(&paths[1])]
        }
        EventKind::Modify(ModifyKind::Name(RenameMode::From)) | EventKind::Remove(_) => paths
            .iter()
            .map(|p| Some(Candidate::Removed(p.clone())))
            .collect(),
        EventKind::Create(CreateKind::Folder) => paths
            .iter()
            .map(|p| filter.wants_dir(p).then(|| Candidate::ScanDir(p.clone())))
            .collect(),
        EventKind::Create(_) | EventKind::Modify(_) => paths
            .iter()
            .map(|p| {
                if p.is_dir() {
                    None
                } else {
                    file(p, Candidate::Changed)
                }
            })
            .collect(),
        _ => vec![],
    };
    out.into_iter().flatten().collect()
}
