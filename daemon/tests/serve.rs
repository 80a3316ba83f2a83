//! The service end to end on a real directory with real inotify events and a
//! real SQLite file. The model is replaced by a counter that reads the leaf
//! count from the file's text, so these tests need no ONNX Runtime; the e2e
//! tests in `tests/` run the real model.

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{config_text, flat_name, q, wait_for, SlowCounter, TextCounter};
use phyllo::config::Config;
use phyllo::counting::LeafCounter;
use phyllo::store::Store;
use tokio::sync::watch;

fn config(dir: &Path) -> Config {
    let text = config_text(
        &dir.join("drop"),
        &dir.join("state/phyllo.sqlite"),
        "[watch]\nstable_secs = 1.5\nsettle_ms = 100\npoll_ms = 50\nrescan_secs = 3\n",
    );
    Config::parse(&text).unwrap()
}

/// What [`TextCounter`] counts as `n` leaves.
fn body(n: u32) -> String {
    TextCounter::body(n)
}

/// A flat-layout name for view `angle`, taken `angle / 36` seconds past 10:00.
fn name(plant: &str, day: u32, angle: u32) -> String {
    flat_name(plant, day, angle / 36, angle)
}

struct Running {
    stop: watch::Sender<bool>,
    handle: std::thread::JoinHandle<anyhow::Result<()>>,
}

/// The service in-process with [`TextCounter`].
fn start(cfg: Config) -> Running {
    start_with(cfg, Arc::new(TextCounter))
}

/// The service in-process with `counter`, on a runtime of its own.
fn start_with(cfg: Config, counter: Arc<dyn LeafCounter>) -> Running {
    let (stop, rx) = watch::channel(false);
    let handle = std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(phyllo::pipeline::service::run(cfg, counter, rx))
    });
    Running { stop, handle }
}

impl Running {
    fn stop(self) {
        self.stop.send(true).unwrap();
        self.handle.join().unwrap().unwrap();
    }
}

#[test]
fn serve_counts_every_complete_image_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let drop = cfg.drop_dir.clone();
    let db = cfg.database.clone();
    std::fs::create_dir_all(&drop).unwrap();
    // Present before start: found by the start-up scan.
    std::fs::write(drop.join(name("P1", 1, 0)), body(8)).unwrap();

    // `tail` follows the feed in parallel, as an operator would.
    let tail_out = Arc::new(Mutex::new(Vec::<u8>::new()));
    let tail_stop = Arc::new(AtomicBool::new(false));
    let tail = {
        let (db, out, stop) = (db.clone(), tail_out.clone(), tail_stop.clone());
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            phyllo::sinks::tail::follow(&db, None, true, true, &mut buf, &|| stop.load(Ordering::Relaxed))
                .unwrap();
            out.lock().unwrap().extend(buf);
        })
    };

    let svc = start(cfg.clone());
    wait_for("start-up scan", Duration::from_secs(20), || {
        q(&db, "SELECT COUNT(*) FROM observations") == 1
    });

    // Close-after-write.
    std::fs::write(drop.join(name("P1", 2, 0)), body(9)).unwrap();
    // Written slowly, kept open, with pauses shorter than stable_secs.
    let slow = drop.join(name("P1", 3, 0));
    let writer = std::thread::spawn(move || {
        let mut f = std::fs::File::create(&slow).unwrap();
        for chunk in body(10).as_bytes().chunks(500) {
            f.write_all(chunk).unwrap();
            f.flush().unwrap();
            std::thread::sleep(Duration::from_millis(300));
        }
    });
    // Renamed into place from a hidden temporary file.
    let tmp = drop.join(".incoming.png");
    std::fs::write(&tmp, body(11)).unwrap();
    std::fs::rename(&tmp, drop.join(name("P1", 4, 0))).unwrap();
    // A new snapshot folder with files written right away.
    let snap = drop.join("2018-04-01_Exp_P2_2018-04-05_09-00-00_17");
    std::fs::create_dir_all(snap.join("Vis_SV_72")).unwrap();
    std::fs::write(snap.join("Vis_SV_72/0_0_0.png"), body(6)).unwrap();
    std::fs::write(snap.join("0_36_0.png"), body(7)).unwrap();
    // Bad input: an unmatched name and an undecodable image.
    std::fs::write(drop.join("holiday.png"), body(3)).unwrap();
    std::fs::write(drop.join(name("P3", 1, 0)), "garbage").unwrap();
    // The same content under another name.
    std::fs::create_dir_all(drop.join("copies")).unwrap();
    std::fs::write(drop.join("copies").join(name("P1", 2, 0)), body(9)).unwrap();
    writer.join().unwrap();

    wait_for("all images", Duration::from_secs(30), || {
        q(&db, "SELECT COUNT(*) FROM images") == 9
    });
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(
        q(&db, "SELECT COUNT(*) FROM observations"),
        6,
        "six distinct complete images"
    );
    assert_eq!(q(&db, "SELECT COUNT(*) FROM images WHERE state = 'duplicate'"), 1);
    assert_eq!(q(&db, "SELECT COUNT(*) FROM images WHERE state = 'failed'"), 2);
    // The slow file was never taken while partial.
    assert_eq!(
        q(
            &db,
            "SELECT COUNT(*) FROM images WHERE path LIKE 'P1_2018-04-03%'"
        ),
        1
    );
    assert_eq!(q(&db, "SELECT leaf_count FROM observations o JOIN images i ON i.id = o.image_id WHERE i.path LIKE 'P1_2018-04-03%'"), 10);
    let store = Store::open_read_only(&db).unwrap();
    let failures = store.recent_failures(10).unwrap();
    let holiday = failures
        .iter()
        .find(|(p, _)| p == "holiday.png")
        .expect("holiday.png recorded");
    assert!(
        holiday.1.contains("holiday.png") && holiday.1.contains("snapshot-dir"),
        "{}",
        holiday.1
    );
    assert!(failures
        .iter()
        .any(|(p, e)| p.starts_with("P3_") && e.contains("not a complete image")));
    let p2 = store.plant_timeline("P2").unwrap().unwrap();
    // The default fusion: the second-largest of the two side views, 6 and 7.
    assert_eq!((p2.sessions.len(), p2.sessions[0].fused), (1, 6.0));
    let p1 = store.plant_timeline("P1").unwrap().unwrap();
    assert_eq!(p1.sessions.len(), 4);
    let leaves: Vec<u32> = p1.events.iter().map(|e| e.0).collect();
    assert_eq!(leaves, vec![9, 10, 11]);

    // A changed file is a new version.
    std::fs::write(drop.join(name("P1", 4, 0)), body(12)).unwrap();
    wait_for("new version", Duration::from_secs(20), || {
        q(&db, "SELECT MAX(version) FROM images") == 2
    });
    svc.stop();
    assert_eq!(
        store.service().unwrap().get("state").map(String::as_str),
        Some("stopped")
    );

    // While down: one new file. After restart it is counted; nothing else is recounted.
    std::fs::write(drop.join(name("P1", 5, 0)), body(13)).unwrap();
    let svc = start(cfg.clone());
    wait_for("file added while down", Duration::from_secs(20), || {
        q(&db, "SELECT COUNT(*) FROM observations") == 8
    });
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(q(&db, "SELECT COUNT(*) FROM observations"), 8);
    assert_eq!(
        q(&db, "SELECT SUM(attempts) FROM images WHERE state = 'failed'"),
        2,
        "bad files not retried"
    );

    // The drop directory deleted and recreated: the watch comes back.
    std::fs::remove_dir_all(&drop).unwrap();
    std::fs::create_dir_all(&drop).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    std::fs::write(drop.join(name("P4", 1, 0)), body(5)).unwrap();
    wait_for("image in recreated drop dir", Duration::from_secs(30), || {
        q(&db, "SELECT COUNT(*) FROM plants WHERE name = 'P4'") == 1
    });
    svc.stop();

    tail_stop.store(true, Ordering::Relaxed);
    tail.join().unwrap();
    let out = String::from_utf8(tail_out.lock().unwrap().clone()).unwrap();
    let rows: Vec<serde_json::Value> = out.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let counts = rows.iter().filter(|r| r["kind"] == "count").count();
    assert_eq!(counts, 9, "tail saw every count:\n{out}");
    assert!(rows.iter().any(|r| r["kind"] == "event" && r["plant"] == "P1"));
    assert!(rows
        .iter()
        .any(|r| r["kind"] == "failed" && r["path"] == "holiday.png"));
}

/// A misnamed image renamed to its proper name is counted, and its old
/// failure is superseded: `status` and `--check` stop listing it (issue 56
/// item 2). A failure whose file is still there stays.
#[test]
fn a_failure_made_moot_by_a_rename_stops_counting_as_one() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let db: PathBuf = cfg.database.clone();
    std::fs::create_dir_all(&cfg.drop_dir).unwrap();
    std::fs::write(cfg.drop_dir.join("P7 from the camera.png"), body(6)).unwrap();
    std::fs::write(cfg.drop_dir.join("stays misnamed.png"), body(5)).unwrap();
    let svc = start(cfg.clone());
    let open_failures = "SELECT COUNT(*) FROM images WHERE state = 'failed' AND superseded = 0";
    wait_for("two failures", Duration::from_secs(30), || {
        q(&db, open_failures) == 2
    });
    std::fs::rename(
        cfg.drop_dir.join("P7 from the camera.png"),
        cfg.drop_dir.join(name("P7", 2, 0)),
    )
    .unwrap();
    wait_for("the renamed image counted", Duration::from_secs(30), || {
        q(&db, "SELECT COUNT(*) FROM observations") == 1
    });
    wait_for("its failure superseded", Duration::from_secs(10), || {
        q(&db, open_failures) == 1
    });
    svc.stop();
}

#[test]
fn missing_drop_dir_is_waited_for() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path());
    let db: PathBuf = cfg.database.clone();
    let svc = start(cfg.clone());
    wait_for("service start", Duration::from_secs(10), || db.exists());
    std::thread::sleep(Duration::from_millis(300));
    std::fs::create_dir_all(&cfg.drop_dir).unwrap();
    std::fs::write(cfg.drop_dir.join(name("P9", 1, 0)), body(4)).unwrap();
    wait_for("image in late drop dir", Duration::from_secs(30), || {
        q(&db, "SELECT COUNT(*) FROM observations") == 1
    });
    svc.stop();
}

#[test]
fn bounded_queue_and_sigterm_hand_back() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = config(dir.path());
    cfg.inference.queue_capacity = 2;
    cfg.inference.workers = 1;
    let db = cfg.database.clone();
    std::fs::create_dir_all(&cfg.drop_dir).unwrap();
    let n = 16;
    for i in 0..n {
        std::fs::write(cfg.drop_dir.join(name("Q", 1 + i, 0)), body(5 + i)).unwrap();
    }
    let run = |cfg: Config| start_with(cfg, Arc::new(SlowCounter(Duration::from_millis(250))));
    let svc = run(cfg.clone());
    // While the single worker is busy, the queue never holds more than its capacity.
    wait_for("first count", Duration::from_secs(20), || {
        q(&db, "SELECT COUNT(*) FROM observations") >= 1
    });
    let t0 = Instant::now();
    let mut max_queued = 0;
    while t0.elapsed() < Duration::from_millis(1000) {
        if let Ok(s) = Store::open_read_only(&db) {
            if let Some(q) = s.service().unwrap().get("queued") {
                max_queued = max_queued.max(q.parse::<usize>().unwrap());
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // SIGTERM equivalent mid-run: the image in hand is finished, the queued ones are handed back.
    svc.stop();
    let done = q(&db, "SELECT COUNT(*) FROM observations");
    assert!(done > 0 && done < n as i64, "stopped mid-run: {done} of {n}");
    assert_eq!(
        q(&db, "SELECT COUNT(*) FROM images"),
        done,
        "nothing half-recorded"
    );
    assert!(max_queued <= 3, "queue stayed bounded: {max_queued}");
    // After a restart every image is counted exactly once.
    let svc = run(cfg.clone());
    wait_for("the rest after restart", Duration::from_secs(60), || {
        q(&db, "SELECT COUNT(*) FROM observations") == n as i64
    });
    svc.stop();
    assert_eq!(q(&db, "SELECT COUNT(*) FROM images"), n as i64);
    assert_eq!(q(&db, "SELECT COUNT(DISTINCT path) FROM images"), n as i64);
}

/// `[feed] keep_days`: the running service deletes old feed entries (at start
/// and hourly) and never the counts behind them.
#[test]
fn old_feed_entries_are_pruned_and_counts_kept() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = config(dir.path());
    cfg.feed.keep_days = 1.0;
    let drop = cfg.drop_dir.clone();
    let db = cfg.database.clone();
    std::fs::create_dir_all(&drop).unwrap();
    std::fs::write(drop.join(name("P1", 1, 0)), body(8)).unwrap();
    std::fs::write(drop.join(name("P1", 2, 0)), body(9)).unwrap();
    let svc = start(cfg.clone());
    wait_for("two counts", Duration::from_secs(20), || {
        q(&db, "SELECT COUNT(*) FROM observations") == 2
    });
    svc.stop();
    let entries = q(&db, "SELECT COUNT(*) FROM feed");
    assert!(entries >= 2, "feed has {entries} entries");
    // Written two days ago, as far as the feed knows.
    let two_days_ago = (chrono::Utc::now() - chrono::Duration::days(2))
        .format("%Y-%m-%dT%H:%M:%S%.3fZ")
        .to_string();
    rusqlite::Connection::open(&db)
        .unwrap()
        .execute("UPDATE feed SET at = ?1", [&two_days_ago])
        .unwrap();

    let svc = start(cfg.clone());
    std::fs::write(drop.join(name("P1", 3, 0)), body(10)).unwrap();
    wait_for(
        "the third count, and the old feed gone",
        Duration::from_secs(20),
        || {
            q(&db, "SELECT COUNT(*) FROM observations") == 3
                && q(
                    &db,
                    &format!("SELECT COUNT(*) FROM feed WHERE at <= '{two_days_ago}'"),
                ) == 0
        },
    );
    svc.stop();
    assert!(q(&db, "SELECT COUNT(*) FROM feed WHERE kind = 'count'") >= 1);
    assert_eq!(q(&db, "SELECT COUNT(*) FROM images WHERE state = 'counted'"), 3);
    assert_eq!(q(&db, "SELECT sessions FROM plants WHERE name = 'P1'"), 3);
}
