//! What a worker takes and shares: the job, the counters the service reports
//! and the context every worker holds ([`crate::pipeline::worker`] does the
//! work).

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize};
use std::sync::{Arc, Mutex};

use crate::config::Config;
use crate::counting::LeafCounter;

/// One file to process.
#[derive(Debug, Clone)]
pub struct Job {
    /// Absolute path.
    pub path: PathBuf,
    /// Path relative to the drop directory, `/` separators.
    pub rel: String,
}

/// Counters shared by the intake, the workers and the status reporter.
#[derive(Debug, Default)]
pub struct Stats {
    /// Jobs sent to the queue and not yet taken by a worker.
    pub queued: AtomicUsize,
    /// Jobs a worker is working on.
    pub busy: AtomicUsize,
    /// Images counted since start.
    pub counted: AtomicU64,
    /// Images recorded as failed since start.
    pub failed: AtomicU64,
    /// Duplicates and unchanged files skipped since start.
    pub skipped: AtomicU64,
    /// Errors of phyllo itself (database), since start; the file is retried by the next rescan.
    pub internal_errors: AtomicU64,
    /// Worker threads that ended while the service runs ([`super::supervise`]).
    pub dead_workers: AtomicUsize,
    /// Last image recorded.
    pub last: Mutex<Option<String>>,
}

/// Everything a worker needs.
pub struct WorkerCtx {
    /// Configuration.
    pub config: Config,
    /// The model.
    pub counter: Arc<dyn LeafCounter>,
    /// Shared counters.
    pub stats: Arc<Stats>,
    /// Paths queued or being processed (the intake will not queue them twice).
    pub in_flight: Arc<Mutex<HashSet<PathBuf>>>,
    /// Set on SIGTERM: queued jobs are handed back (left for the next start's scan).
    pub shutdown: Arc<AtomicBool>,
}
