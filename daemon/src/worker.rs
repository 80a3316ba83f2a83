//! Worker threads: take a file from the bounded queue, hash it, parse its
//! name, count it and store the outcome.
//!
//! Counting is blocking and CPU-heavy, so it runs on dedicated OS threads,
//! never on the tokio runtime. Every failure is recorded against the file and
//! logged; nothing a file contains can stop a worker (panics included).

use std::collections::HashSet;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use anyhow::Context;
use sha2::{Digest, Sha256};
use tokio::sync::mpsc;

use crate::config::Config;
use crate::counting::LeafCounter;
use crate::names::NamePatterns;
use crate::store::{FileFacts, Outcome, Precheck, Recorded, Store};

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
    /// Last image recorded.
    pub last: Mutex<Option<String>>,
}

/// Everything a worker needs.
pub struct WorkerCtx {
    /// Configuration.
    pub config: Config,
    /// File-name patterns.
    pub names: NamePatterns,
    /// The model.
    pub counter: Arc<dyn LeafCounter>,
    /// Shared counters.
    pub stats: Arc<Stats>,
    /// Paths queued or being processed (the intake will not queue them twice).
    pub in_flight: Arc<Mutex<HashSet<PathBuf>>>,
    /// Set on SIGTERM: queued jobs are handed back (left for the next start's scan).
    pub shutdown: Arc<AtomicBool>,
}

/// Starts `n` worker threads sharing one receiver.
pub fn spawn_workers(
    n: usize,
    rx: mpsc::Receiver<Job>,
    ctx: Arc<WorkerCtx>,
) -> anyhow::Result<Vec<JoinHandle<()>>> {
    let rx = Arc::new(Mutex::new(rx));
    let mut handles = Vec::with_capacity(n);
    for i in 0..n {
        let mut store = Store::open(
            &ctx.config.database,
            &ctx.config.timeline,
            ctx.config.inference.max_attempts,
        )?;
        let (rx, ctx) = (rx.clone(), ctx.clone());
        let h = std::thread::Builder::new()
            .name(format!("phyllo-worker-{i}"))
            .spawn(move || loop {
                // Holding the lock while waiting is fine: whoever holds it takes the next job.
                let job = rx.lock().expect("receiver lock").blocking_recv();
                let Some(job) = job else { break };
                ctx.stats.queued.fetch_sub(1, Ordering::Relaxed);
                if ctx.shutdown.load(Ordering::SeqCst) {
                    // Handed back: not recorded, so the next start's scan finds it again.
                    ctx.in_flight.lock().expect("in_flight lock").remove(&job.path);
                    continue;
                }
                ctx.stats.busy.fetch_add(1, Ordering::Relaxed);
                if let Err(e) = process(&mut store, &ctx, &job) {
                    ctx.stats.internal_errors.fetch_add(1, Ordering::Relaxed);
                    tracing::error!("{}: {e:#}", job.path.display());
                }
                ctx.stats.busy.fetch_sub(1, Ordering::Relaxed);
                ctx.in_flight.lock().expect("in_flight lock").remove(&job.path);
            })?;
        handles.push(h);
    }
    Ok(handles)
}

/// Formats a file's mtime as stored in the database.
pub fn mtime_string(meta: &std::fs::Metadata) -> String {
    match meta.modified() {
        Ok(t) => chrono::DateTime::<chrono::Utc>::from(t)
            .format("%Y-%m-%dT%H:%M:%S%.9fZ")
            .to_string(),
        Err(_) => String::new(),
    }
}

/// Hex SHA-256.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// Processes one file. Returns what the store did, `None` if it was skipped.
pub fn process(store: &mut Store, ctx: &WorkerCtx, job: &Job) -> anyhow::Result<Option<Recorded>> {
    let meta = match std::fs::metadata(&job.path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            tracing::debug!("{} vanished before it was read", job.rel);
            return Ok(None);
        }
        Err(e) => return Err(e).with_context(|| format!("stat {}", job.path.display())),
    };
    let mtime = mtime_string(&meta);
    let bytes = match std::fs::read(&job.path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("reading {}", job.path.display())),
    };
    let facts = FileFacts {
        rel: job.rel.clone(),
        size: bytes.len() as u64,
        mtime: Some(mtime),
        sha256: sha256_hex(&bytes),
    };
    if let Precheck::Skip(why) = store.precheck(&facts)? {
        tracing::debug!("skip: {why}");
        ctx.stats.skipped.fetch_add(1, Ordering::Relaxed);
        return Ok(None);
    }
    let recorded = match ctx.names.parse(Path::new(&job.rel)) {
        Err(e) => {
            let error = format!("{e:#}");
            tracing::warn!("{error}");
            store.record(
                &facts,
                Outcome::Failed {
                    name: None,
                    error,
                    retry: false,
                },
            )?
        }
        Ok(name) => {
            let counted = std::panic::catch_unwind(AssertUnwindSafe(|| ctx.counter.count(&job.path, &bytes)));
            match counted {
                Ok(Ok(count)) => {
                    let r = store.record(&facts, Outcome::Counted(&name, &count))?;
                    tracing::info!(
                        "{}: {} leaves ({} {}), {:.0} ms",
                        job.rel,
                        count.leaf_count,
                        name.plant,
                        name.view,
                        count.ms_total
                    );
                    r
                }
                Ok(Err(e)) => {
                    tracing::warn!("{}", e.message);
                    store.record(
                        &facts,
                        Outcome::Failed {
                            name: Some(&name),
                            error: e.message,
                            retry: e.retry,
                        },
                    )?
                }
                Err(panic) => {
                    let what = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    let error = format!("{}: counting panicked: {what}", job.path.display());
                    tracing::error!("{error}");
                    store.record(
                        &facts,
                        Outcome::Failed {
                            name: Some(&name),
                            error,
                            retry: false,
                        },
                    )?
                }
            }
        }
    };
    match &recorded {
        Recorded::Counted { .. } => ctx.stats.counted.fetch_add(1, Ordering::Relaxed),
        Recorded::Failed => ctx.stats.failed.fetch_add(1, Ordering::Relaxed),
        Recorded::Duplicate(_) => ctx.stats.skipped.fetch_add(1, Ordering::Relaxed),
    };
    *ctx.stats.last.lock().expect("last lock") = Some(job.rel.clone());
    Ok(Some(recorded))
}
