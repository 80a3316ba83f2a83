//! Supervising the workers. A panic anywhere in one image's processing (the
//! store, the timeline fit, not only the model) fails that image with an
//! error row and the worker takes the next one. A worker thread that ends
//! while the service is not stopping is counted in
//! [`Stats::dead_workers`](super::job::Stats): the service then stops
//! with an error, so systemd restarts it instead of the watchdog being fed
//! while capacity drains away.

use std::any::Any;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use super::job::{Job, WorkerCtx};
use crate::files::{mtime_string, sha256_hex};
use crate::store::{FileFacts, Outcome, Recorded, Store};

/// The text of a panic's payload (empty when it carries none).
pub fn panic_message(panic: &(dyn Any + Send)) -> String {
    panic
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_default()
}

/// Runs `work` on `job`; a panic in it is logged and recorded against the
/// file as failed (not retried: the same bytes would panic again).
pub fn supervised(
    store: &mut Store,
    ctx: &WorkerCtx,
    job: &Job,
    work: impl FnOnce(&mut Store) -> anyhow::Result<Option<Recorded>>,
) -> anyhow::Result<Option<Recorded>> {
    let panic = match std::panic::catch_unwind(AssertUnwindSafe(|| work(&mut *store))) {
        Ok(done) => return done,
        Err(panic) => panic,
    };
    let error = format!("{}: processing panicked: {}", job.rel, panic_message(&*panic));
    tracing::error!("{error}");
    // What the unwinding left of a write transaction was rolled back when it dropped.
    let recorded = store.record(
        &facts_after_panic(job, &error),
        Outcome::Failed {
            name: None,
            error,
            retry: false,
        },
    )?;
    ctx.stats.failed.fetch_add(1, Ordering::Relaxed);
    Ok(Some(recorded))
}

/// The file's facts read again: the panic took the worker's copy.
fn facts_after_panic(job: &Job, error: &str) -> FileFacts {
    let bytes = std::fs::read(&job.path).ok();
    let meta = std::fs::metadata(&job.path).ok();
    FileFacts {
        rel: job.rel.clone(),
        size: meta.as_ref().map_or(0, |m| m.len()),
        mtime: meta.as_ref().map(mtime_string),
        // Unreadable now: a stable marker of the failure, as for a refused file.
        sha256: match bytes {
            Some(b) => sha256_hex(&b),
            None => sha256_hex(format!("phyllo-panicked:{error}").as_bytes()),
        },
    }
}

/// Held by each worker thread for its whole life: dropped while the service
/// is not shutting down (the thread died), it counts a dead worker.
pub struct Lifeline(pub Arc<WorkerCtx>);

impl Drop for Lifeline {
    fn drop(&mut self) {
        if !self.0.shutdown.load(Ordering::SeqCst) {
            self.0.stats.dead_workers.fetch_add(1, Ordering::SeqCst);
            tracing::error!(
                "a worker thread ended while the service runs{}",
                if std::thread::panicking() {
                    " (it panicked)"
                } else {
                    ""
                }
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;
    use std::path::Path;
    use std::sync::atomic::AtomicBool;
    use std::sync::Mutex;

    use crate::config::Config;
    use crate::counting::{CountError, LeafCounter};
    use crate::domain::names::View;
    use crate::pipeline::job::Stats;
    use crate::store::CountRecord;

    struct NeverCalled;

    impl LeafCounter for NeverCalled {
        fn count(&self, _: &Path, _: &View, _: &[u8]) -> Result<CountRecord, CountError> {
            unreachable!("the test never counts")
        }
        fn model_id(&self) -> String {
            "none".into()
        }
    }

    fn ctx(dir: &Path) -> Arc<WorkerCtx> {
        let config = Config::parse(&format!(
            "drop_dir = {:?}\ndatabase = {:?}\n",
            dir.join("drop"),
            dir.join("db.sqlite")
        ))
        .unwrap();
        Arc::new(WorkerCtx {
            config,
            counter: Arc::new(NeverCalled),
            stats: Arc::new(Stats::default()),
            in_flight: Arc::new(Mutex::new(HashSet::new())),
            shutdown: Arc::new(AtomicBool::new(false)),
        })
    }

    #[test]
    fn a_panic_past_the_model_fails_the_image_and_the_worker_goes_on() {
        let dir = tempfile::tempdir().unwrap();
        let ctx = ctx(dir.path());
        let mut store = Store::open(&ctx.config.database, &ctx.config.rules().timeline, 3).unwrap();
        let path = dir.path().join("P1_2019-05-10_09-18-07_Vis_SV_0.png");
        std::fs::write(&path, b"bytes").unwrap();
        let job = Job {
            path,
            rel: "P1_2019-05-10_09-18-07_Vis_SV_0.png".into(),
        };
        let r = supervised(&mut store, &ctx, &job, |_| {
            panic!("timeline fit: index out of bounds")
        })
        .unwrap();
        assert_eq!(r, Some(Recorded::Failed));
        let failures = store.recent_failures(5).unwrap();
        assert_eq!(failures.len(), 1);
        assert!(
            failures[0].1.contains(&job.rel) && failures[0].1.contains("processing panicked: timeline fit"),
            "{failures:?}"
        );
        // The same store serves the next image.
        assert_eq!(supervised(&mut store, &ctx, &job, |_| Ok(None)).unwrap(), None);
        assert_eq!(ctx.stats.failed.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn a_worker_that_dies_is_counted_unless_the_service_stops() {
        let dir = tempfile::tempdir().unwrap();
        let ctx = ctx(dir.path());
        let c = ctx.clone();
        let died = std::thread::spawn(move || {
            let _life = Lifeline(c);
            panic!("receiver lock poisoned");
        });
        assert!(died.join().is_err());
        assert_eq!(ctx.stats.dead_workers.load(Ordering::SeqCst), 1);
        ctx.shutdown.store(true, Ordering::SeqCst);
        drop(Lifeline(ctx.clone()));
        assert_eq!(ctx.stats.dead_workers.load(Ordering::SeqCst), 1);
    }
}
