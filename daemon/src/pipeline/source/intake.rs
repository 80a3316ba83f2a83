//! The intake: decides when a candidate file is complete and queues it.
//!
//! A file is queued once its size and mtime have stayed unchanged for a quiet
//! period: short (`settle_ms`) after a close-after-write or a rename into the
//! tree, long (`stable_secs`) when only create/modify events were seen (a
//! writer that keeps the file open). A file whose mtime is already older than
//! the quiet period (found by a scan) is queued at the next tick. Before
//! queueing, a cheap database lookup (path, size, mtime) skips files already
//! done, so periodic rescans do not re-read the tree's content.

use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

use tokio::sync::{mpsc, watch};

use super::{Candidate, Filter};
use crate::config::WatchConfig;
use crate::files::mtime_string;
use crate::pipeline::worker::{Job, Stats};
use crate::store::Store;

#[derive(Debug)]
struct Pending {
    size: u64,
    mtime: Option<SystemTime>,
    quiet: Duration,
    since: Instant,
}

/// What the service loop must do after a candidate was noted.
#[derive(Debug, PartialEq)]
pub enum ScanRequest {
    /// Scan this directory.
    Dir(PathBuf),
    /// Scan the whole drop directory.
    All,
}

/// Intake state: files waiting to become stable.
pub struct Intake {
    filter: Filter,
    settle: Duration,
    stable: Duration,
    pending: HashMap<PathBuf, Pending>,
    store: Store,
    jobs: mpsc::Sender<Job>,
    in_flight: Arc<Mutex<HashSet<PathBuf>>>,
    stats: Arc<Stats>,
}

impl Intake {
    /// Creates the intake; `store` is used for the cheap "already done" lookups.
    pub fn new(
        filter: Filter,
        cfg: &WatchConfig,
        store: Store,
        jobs: mpsc::Sender<Job>,
        in_flight: Arc<Mutex<HashSet<PathBuf>>>,
        stats: Arc<Stats>,
    ) -> Intake {
        Intake {
            filter,
            settle: Duration::from_millis(cfg.settle_ms),
            stable: Duration::from_secs_f64(cfg.stable_secs),
            pending: HashMap::new(),
            store,
            jobs,
            in_flight,
            stats,
        }
    }

    /// Number of files waiting to become stable.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Takes note of a candidate; returns a scan request for directories.
    pub fn note(&mut self, c: Candidate) -> Option<ScanRequest> {
        match c {
            Candidate::Closed(p) | Candidate::Renamed(p) => self.watch(p, self.settle, true),
            Candidate::Changed(p) => self.watch(p, self.stable, true),
            Candidate::Scanned(p) => self.watch(p, self.stable, false),
            Candidate::Removed(p) => {
                self.pending.remove(&p);
            }
            Candidate::ScanDir(d) => return Some(ScanRequest::Dir(d)),
            Candidate::RescanAll => return Some(ScanRequest::All),
        }
        None
    }

    fn watch(&mut self, path: PathBuf, quiet: Duration, override_quiet: bool) {
        let (size, mtime) = stat(&path);
        let now = Instant::now();
        match self.pending.get_mut(&path) {
            Some(p) => {
                if override_quiet {
                    p.quiet = quiet;
                }
                if (p.size, p.mtime) != (size, mtime) {
                    (p.size, p.mtime, p.since) = (size, mtime, now);
                }
            }
            None => {
                self.pending.insert(
                    path,
                    Pending {
                        size,
                        mtime,
                        quiet,
                        since: now,
                    },
                );
            }
        }
    }

    /// Checks pending files and queues the stable ones. Waits while the queue
    /// is full (backpressure) unless shutdown is signalled.
    pub async fn tick(&mut self, shutdown: &mut watch::Receiver<bool>) {
        let now = Instant::now();
        let mut ready = Vec::new();
        let mut gone = Vec::new();
        for (path, p) in self.pending.iter_mut() {
            let (size, mtime) = stat(path);
            if mtime.is_none() {
                gone.push(path.clone());
                continue;
            }
            if (size, mtime) != (p.size, p.mtime) {
                (p.size, p.mtime, p.since) = (size, mtime, now);
                continue;
            }
            // An empty file is most likely one a writer has just created.
            let quiet = if size == 0 {
                p.quiet.max(self.stable)
            } else {
                p.quiet
            };
            let age = mtime
                .and_then(|m| SystemTime::now().duration_since(m).ok())
                .unwrap_or_default();
            if now.duration_since(p.since) >= quiet || age >= quiet {
                ready.push(path.clone());
            }
        }
        for path in gone {
            self.pending.remove(&path);
        }
        for path in ready {
            if *shutdown.borrow() {
                return;
            }
            if self.in_flight.lock().expect("in_flight lock").contains(&path) {
                continue; // still being processed: look again at the next tick
            }
            let p = self.pending.remove(&path).expect("ready paths are pending");
            let Some(rel) = self.filter.rel(&path) else {
                continue;
            };
            let mtime = match super::stat_or_link(&path) {
                Ok(m) => mtime_string(&m),
                // As the worker records it: no size, no time.
                Err(e) if crate::files::too_long(&e) => String::new(),
                Err(_) => continue,
            };
            match self
                .store
                .is_known(&rel, p.size, &mtime, || crate::files::readable(&path))
            {
                Ok(true) => continue,
                Ok(false) => {}
                Err(e) => tracing::warn!("database lookup for {rel}: {e:#}"),
            }
            self.in_flight
                .lock()
                .expect("in_flight lock")
                .insert(path.clone());
            self.stats.queued.fetch_add(1, Ordering::Relaxed);
            let job = Job {
                path: path.clone(),
                rel,
            };
            tokio::select! {
                r = self.jobs.send(job) => {
                    if r.is_err() {
                        return;
                    }
                }
                _ = shutdown.wait_for(|s| *s) => {
                    self.stats.queued.fetch_sub(1, Ordering::Relaxed);
                    self.in_flight.lock().expect("in_flight lock").remove(&path);
                    return;
                }
            }
        }
    }
}

fn stat(path: &std::path::Path) -> (u64, Option<SystemTime>) {
    match super::stat_or_link(path) {
        Ok(m) if m.is_file() || m.file_type().is_symlink() => {
            (m.len(), m.modified().ok().or(Some(SystemTime::UNIX_EPOCH)))
        }
        // Cannot be read by its path, but there: the worker records why.
        Err(e) if crate::files::too_long(&e) => (0, Some(SystemTime::UNIX_EPOCH)),
        _ => (0, None),
    }
}
