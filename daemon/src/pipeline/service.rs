//! `phyllo serve`: wires sources, intake, workers and store together and runs
//! until shutdown.
//!
//! Shutdown (SIGTERM/SIGINT, or the `shutdown` channel in tests): intake stops
//! first (watch dropped, no more jobs queued); queued jobs not yet started are
//! handed back (left unrecorded, so the next start's scan finds them); workers
//! finish the image they hold, each in its own transaction; then the database
//! connections close, which checkpoints the WAL.

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use tokio::sync::{mpsc, watch};
use tokio::time::MissedTickBehavior;

use crate::config::Config;
use crate::counting::LeafCounter;
use crate::files::identity::DatabaseIdentity;
use crate::pipeline::health;
use crate::pipeline::source::intake::{Intake, ScanRequest};
use crate::pipeline::source::watch::Watch;
use crate::pipeline::source::{scan, Candidate, Filter};
use crate::pipeline::systemd;
use crate::pipeline::worker::{spawn_workers, Stats, WorkerCtx};
use crate::store::{now_utc, DatabaseLock, Store};

/// How often the service writes its self-report for `phyllo status`.
const STATUS_EVERY: Duration = Duration::from_secs(2);
/// How often feed entries older than `[feed] keep_days` are deleted.
const PRUNE_FEED_EVERY: Duration = Duration::from_secs(3600);
/// How often the free space beside the database is checked.
const DISK_EVERY: Duration = Duration::from_secs(60);

/// Runs the service until `shutdown` becomes true. Must be called inside a
/// multi-threaded tokio runtime.
pub async fn run(
    config: Config,
    counter: Arc<dyn LeafCounter>,
    mut shutdown: watch::Receiver<bool>,
) -> anyhow::Result<()> {
    // Held until the service returns: one service per database.
    let _lock = DatabaseLock::acquire(&config.database, "phyllo serve")?;
    let mut status_store = Store::open(
        &config.database,
        &config.rules().timeline,
        config.inference.max_attempts,
    )?;
    let model_id = counter.model_id();
    let settings = counter.settings();
    let stats = Arc::new(Stats::default());
    let in_flight = Arc::new(Mutex::new(HashSet::new()));
    let stop_workers = Arc::new(AtomicBool::new(false));
    let (job_tx, job_rx) = mpsc::channel(config.inference.queue_capacity);
    let ctx = Arc::new(WorkerCtx {
        config: config.clone(),
        counter,
        stats: stats.clone(),
        in_flight: in_flight.clone(),
        shutdown: stop_workers.clone(),
    });
    let workers = spawn_workers(config.inference.workers, job_rx, ctx)?;

    let mut sources = Sources::start(&config)?;
    let intake_store = Store::open(
        &config.database,
        &config.rules().timeline,
        config.inference.max_attempts,
    )?;
    let mut intake = Intake::new(
        sources.filter.clone(),
        &config.watch,
        intake_store,
        job_tx,
        in_flight,
        stats.clone(),
    );
    sources.scan_all(&config);

    let db = DatabaseIdentity::of(&config.database)?;
    announce_running(&mut status_store, &config, &model_id, &settings, &db)?;
    let state_dir = config.state_dir();
    let status_task = tokio::spawn(report_status(
        status_store,
        (stats.clone(), db),
        config.feed.keep(),
        state_dir,
        shutdown.clone(),
    ));
    sources.feed_intake(&config, &mut intake, &mut shutdown).await;

    systemd::stopping("stopping: finishing in-flight images");
    tracing::info!(
        "shutting down: {} pending, finishing in-flight images",
        intake.pending()
    );
    drop(sources.watcher.take());
    stop_workers.store(true, Ordering::SeqCst);
    // Dropping the intake drops the queue's sender: workers drain (handing back) and exit.
    drop(intake);
    tokio::task::spawn_blocking(move || {
        for w in workers {
            let _ = w.join();
        }
    })
    .await
    .context("joining workers")?;
    let mut store = status_task.await.context("status task")?;
    store.set_service(&[("state", "stopped".into()), ("stopped_at", now_utc())])?;
    drop(store);
    tracing::info!(
        "stopped: {} counted, {} failed since start",
        stats.counted.load(Ordering::Relaxed),
        stats.failed.load(Ordering::Relaxed)
    );
    Ok(())
}

/// Tells `phyllo status`, systemd and the journal that the service is up,
/// with the model and settings its counts are made with.
fn announce_running(
    status_store: &mut Store,
    config: &Config,
    model_id: &str,
    settings: &serde_json::Value,
    db: &DatabaseIdentity,
) -> anyhow::Result<()> {
    status_store.set_service(&[
        ("database_identity", db.text()),
        ("state", "running".into()),
        ("pid", std::process::id().to_string()),
        ("started_at", now_utc()),
        ("model", model_id.to_string()),
        ("settings", settings.to_string()),
        ("drop_dir", config.drop_dir.display().to_string()),
        ("workers", config.inference.workers.to_string()),
    ])?;
    systemd::ready(&format!("watching {} with {model_id}", config.drop_dir.display()));
    tracing::info!(
        "phyllo serve: watching {} → {} (model {model_id}, {} workers)",
        config.drop_dir.display(),
        config.database.display(),
        config.inference.workers
    );
    Ok(())
}

/// The drop directory's sources: its watch and its scans feed candidates into
/// one channel, whose only reader is the intake.
struct Sources {
    /// Which files under the drop directory are images to count.
    filter: Filter,
    tx: mpsc::Sender<Candidate>,
    rx: mpsc::Receiver<Candidate>,
    /// `None` while the drop directory is missing or the watch failed.
    watcher: Option<Watch>,
    /// Set while a scan of the whole drop directory runs ([`spawn_scan`]).
    scanning: Arc<AtomicBool>,
    /// Spaces out the warning about a drop directory that cannot be watched.
    quiet: WarnBackoff,
}

/// When to say again that the drop directory cannot be watched: at once,
/// then once a minute for its first hour, then hourly (the watch is retried
/// every tick; a warning every 5 s was 17,000 log lines a day).
#[derive(Debug, Default)]
struct WarnBackoff {
    /// Since when it has failed, and when it was last said.
    failing: Option<(std::time::Instant, std::time::Instant)>,
}

impl WarnBackoff {
    /// Whether to warn about a failure now.
    fn due(&mut self, now: std::time::Instant) -> bool {
        match self.failing {
            None => {
                self.failing = Some((now, now));
                true
            }
            Some((since, said)) => {
                let every = if now - since < Duration::from_secs(3600) {
                    Duration::from_secs(60)
                } else {
                    Duration::from_secs(3600)
                };
                let due = now - said >= every;
                if due {
                    self.failing = Some((since, now));
                }
                due
            }
        }
    }
}

impl Sources {
    /// Starts watching the drop directory; scanning is left to the caller.
    fn start(config: &Config) -> anyhow::Result<Sources> {
        let (tx, rx) = mpsc::channel::<Candidate>(4096);
        let filter = Filter::new(&config.drop_dir, &config.watch);
        let filter = if config.watch.skip_top_views {
            filter.skipping_top_views(config.rules().names.clone())
        } else {
            filter
        };
        let mut quiet = WarnBackoff::default();
        let watcher = start_watch(&filter, &tx, &mut quiet);
        Ok(Sources {
            filter,
            tx,
            rx,
            watcher,
            scanning: Arc::new(AtomicBool::new(false)),
            quiet,
        })
    }

    /// Scans the whole drop directory, unless a scan of it is running.
    fn scan_all(&self, config: &Config) {
        spawn_scan(
            config,
            &self.filter,
            self.filter.root().to_path_buf(),
            &self.tx,
            &self.scanning,
        );
    }

    /// Hands candidates to the intake and ticks it, rescans and re-watches
    /// the drop directory, until `shutdown`.
    async fn feed_intake(
        &mut self,
        config: &Config,
        intake: &mut Intake,
        shutdown: &mut watch::Receiver<bool>,
    ) {
        let mut tick = tokio::time::interval(Duration::from_millis(config.watch.poll_ms.max(10)));
        tick.set_missed_tick_behavior(MissedTickBehavior::Delay);
        let rescan_every = Duration::from_secs(config.watch.rescan_secs.max(1));
        let mut rescan = tokio::time::interval_at(tokio::time::Instant::now() + rescan_every, rescan_every);
        rescan.set_missed_tick_behavior(MissedTickBehavior::Delay);
        // A drop directory that is missing or was replaced is re-watched this often.
        let mut rewatch = tokio::time::interval(Duration::from_secs(5));

        let mut intake_shutdown = shutdown.clone();
        loop {
            tokio::select! {
                _ = shutdown.wait_for(|s| *s) => break,
                Some(c) = self.rx.recv() => {
                    match intake.note(c) {
                        Some(ScanRequest::Dir(d)) => scan_new_dir(config, &self.filter, d, &self.tx, &self.scanning),
                        Some(ScanRequest::All) => self.scan_all(config),
                        None => {}
                    }
                }
                _ = tick.tick() => intake.tick(&mut intake_shutdown).await,
                _ = rescan.tick(), if config.watch.rescan_secs > 0 => self.scan_all(config),
                _ = rewatch.tick() => self.rewatch(config),
            }
        }
    }

    /// Watches the drop directory afresh when it is missing or was replaced,
    /// and scans it once the watch is in place: files may have landed unseen.
    fn rewatch(&mut self, config: &Config) {
        if self.watcher.as_ref().is_none_or(|w| w.is_stale()) {
            drop(self.watcher.take());
            self.watcher = start_watch(&self.filter, &self.tx, &mut self.quiet);
            if self.watcher.is_some() {
                tracing::info!(
                    "drop directory {} (re)appeared, watching and scanning it",
                    self.filter.root().display()
                );
                self.scan_all(config);
            }
        }
    }
}

fn start_watch(filter: &Filter, tx: &mpsc::Sender<Candidate>, quiet: &mut WarnBackoff) -> Option<Watch> {
    match Watch::start(filter.clone(), tx.clone()) {
        Ok(w) => {
            quiet.failing = None;
            Some(w)
        }
        Err(e) => {
            if quiet.due(std::time::Instant::now()) {
                tracing::warn!("{e:#}; retrying (said again once a minute, hourly after its first hour)");
            } else {
                tracing::debug!("{e:#}; retrying");
            }
            None
        }
    }
}

/// When a new directory is scanned again after it appeared. `notify` adds its
/// inotify watch on a new directory only after our handler has taken the
/// whole batch of events (and our handler blocks while the intake is behind),
/// so files can land in the directory after the first scan and before the
/// watch exists; one of these later scans starts after the watch is in place.
const NEW_DIR_RESCANS: [Duration; 4] = [
    Duration::from_millis(500),
    Duration::from_secs(2),
    Duration::from_secs(10),
    Duration::from_secs(60),
];

/// Scans a directory that just appeared, now and again at [`NEW_DIR_RESCANS`].
fn scan_new_dir(
    config: &Config,
    filter: &Filter,
    dir: PathBuf,
    tx: &mpsc::Sender<Candidate>,
    scanning: &Arc<AtomicBool>,
) {
    spawn_scan(config, filter, dir.clone(), tx, scanning);
    let (config, filter, tx, scanning) = (config.clone(), filter.clone(), tx.clone(), scanning.clone());
    tokio::spawn(async move {
        for delay in NEW_DIR_RESCANS {
            tokio::time::sleep(delay).await;
            if tx.is_closed() {
                return;
            }
            spawn_scan(&config, &filter, dir.clone(), &tx, &scanning);
        }
    });
}

/// Scans `dir` on a blocking thread, sending files not yet done as candidates.
/// At most one scan runs at a time; a request during a scan is dropped, since
/// the running scan or the next periodic one covers it.
fn spawn_scan(
    config: &Config,
    filter: &Filter,
    dir: PathBuf,
    tx: &mpsc::Sender<Candidate>,
    scanning: &Arc<AtomicBool>,
) {
    let whole = dir == filter.root();
    if whole && scanning.swap(true, Ordering::SeqCst) {
        return;
    }
    let (config, filter, tx, scanning) = (config.clone(), filter.clone(), tx.clone(), scanning.clone());
    tokio::task::spawn_blocking(move || {
        let store = Store::open(
            &config.database,
            &config.rules().timeline,
            config.inference.max_attempts,
        );
        let files = scan::scan(&filter, &dir);
        let mut sent = 0;
        for path in &files {
            let known = match (
                &store,
                filter.rel(path),
                crate::pipeline::source::stat_or_link(path),
            ) {
                (Ok(s), Some(rel), Ok(meta)) => s
                    .is_known(&rel, meta.len(), &crate::files::mtime_string(&meta), || {
                        crate::files::readable(path)
                    })
                    .unwrap_or(false),
                _ => false,
            };
            if !known {
                sent += 1;
                if tx.blocking_send(Candidate::Scanned(path.clone())).is_err() {
                    break;
                }
            }
        }
        tracing::debug!("scan of {}: {} files, {sent} new", dir.display(), files.len());
        if whole {
            scanning.store(false, Ordering::SeqCst);
        }
    });
}

/// Deletes old feed entries on a blocking thread (the delete scans the feed
/// and may wait for a worker's transaction). A failure is logged, not fatal:
/// the feed only grows until the next try.
async fn prune_feed(mut store: Store, keep: Duration) -> Store {
    match tokio::task::spawn_blocking(move || {
        match store.prune_feed(keep) {
            Ok(0) => {}
            Ok(n) => tracing::info!(
                "feed: deleted {n} entries older than {:.1} days",
                keep.as_secs_f64() / 86_400.0
            ),
            Err(e) => tracing::warn!("pruning the feed: {e:#}"),
        }
        store
    })
    .await
    {
        Ok(s) => s,
        Err(e) => panic!("feed pruning panicked: {e}"),
    }
}

/// Ends the process at once with [`health::EXIT_UNHEALTHY`], telling the
/// journal, systemd and (where it can) `phyllo status` why: a graceful stop
/// would go on writing into a database that is gone, or with workers missing.
fn stop_unhealthy(store: &mut Store, why: &str) -> ! {
    tracing::error!("stopping: {why}; systemd restarts the service");
    systemd::status(&format!("FAILED: {why}"));
    let _ = store.set_service(&[("state", format!("failed: {why}")), ("stopped_at", now_utc())]);
    std::process::exit(health::EXIT_UNHEALTHY)
}

/// Writes the self-report for `phyllo status`, the systemd status line and
/// the watchdog ping, and prunes the feed to `keep_feed`, until shutdown.
/// Returns the store for the final report.
async fn report_status(
    mut store: Store,
    (stats, db): (Arc<Stats>, DatabaseIdentity),
    keep_feed: Option<Duration>,
    state_dir: std::path::PathBuf,
    mut shutdown: watch::Receiver<bool>,
) -> Store {
    let watchdog = systemd::watchdog_interval();
    let every = watchdog.map_or(STATUS_EVERY, |w| w.min(STATUS_EVERY));
    let mut tick = tokio::time::interval(every);
    let mut prune = tokio::time::interval(PRUNE_FEED_EVERY);
    prune.set_missed_tick_behavior(MissedTickBehavior::Delay);
    let mut disk = tokio::time::interval(DISK_EVERY);
    disk.set_missed_tick_behavior(MissedTickBehavior::Delay);
    let mut low_disk = crate::files::disk::LowDiskWatch::new(state_dir);
    loop {
        let prune_now = tokio::select! {
            _ = shutdown.wait_for(|s| *s) => return store,
            _ = prune.tick(), if keep_feed.is_some() => keep_feed,
            _ = disk.tick() => {
                low_disk.check();
                continue;
            }
            _ = tick.tick() => None,
        };
        if let Some(keep) = prune_now {
            store = prune_feed(store, keep).await;
            continue;
        }
        if let Some(why) = health::unhealthy(&db, &stats) {
            stop_unhealthy(&mut store, &why);
        }
        let queued = stats.queued.load(Ordering::Relaxed);
        let busy = stats.busy.load(Ordering::Relaxed);
        let counted = stats.counted.load(Ordering::Relaxed);
        let failed = stats.failed.load(Ordering::Relaxed);
        let last = stats.last.lock().expect("last lock").clone().unwrap_or_default();
        let kv = [
            ("heartbeat", now_utc()),
            ("queued", queued.to_string()),
            ("busy", busy.to_string()),
            ("counted_since_start", counted.to_string()),
            ("failed_since_start", failed.to_string()),
            (
                "internal_errors",
                stats.internal_errors.load(Ordering::Relaxed).to_string(),
            ),
            ("last_image", last.clone()),
        ];
        // The write is short but may wait for a worker's transaction: keep it off the runtime.
        store = match tokio::task::spawn_blocking(move || {
            if let Err(e) = store.set_service(&kv) {
                tracing::warn!("writing service status: {e:#}");
            }
            store
        })
        .await
        {
            Ok(s) => s,
            Err(e) => panic!("status writer panicked: {e}"),
        };
        let disk_note = low_disk.low().map_or(String::new(), |free| {
            format!("; LOW DISK: {} free", crate::files::disk::human(free))
        });
        systemd::status(&format!(
            "queue {queued}, busy {busy}, counted {counted}, failed {failed}; last {last}{disk_note}"
        ));
        if watchdog.is_some() {
            systemd::watchdog();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lasting_watch_failure_is_said_once_a_minute_then_hourly() {
        let t0 = std::time::Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        let mut w = WarnBackoff::default();
        // Retried every 5 s for two hours: which retries warn.
        let said: Vec<u64> = (0..2 * 720).map(|i| i * 5).filter(|&s| w.due(at(s))).collect();
        assert_eq!(&said[..3], [0, 60, 120]);
        assert_eq!(said.iter().filter(|&&s| s < 3600).count(), 60, "{said:?}");
        assert!(said.iter().filter(|&&s| s >= 3600).count() <= 2, "{said:?}");
        w.failing = None;
        assert!(w.due(at(7200)), "a new failure is said at once");
    }
}
