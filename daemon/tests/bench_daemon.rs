//! The daemon's performance on full 2454×2056 PNG frames: a benchmark, not a
//! timed test (`#[ignore]`d; run it with `scripts/bench-daemon.sh`, which
//! builds in release mode).
//!
//! It runs the real `phyllo serve` with the default intake timings and the
//! model `PHYLLO_BENCH_MODEL` (default: the shipped untrained model; the
//! network is the same size, so the speed is the same), and prints:
//!
//! - latency from close-after-write to the image's row in the database,
//!   p50 and p99 over `PHYLLO_BENCH_LATENCY_N` frames (default 20) dropped
//!   one at a time into an idle daemon; it includes the intake's `settle_ms`
//!   (300 ms by default) that guards against writers that reopen a file;
//! - sustained images/s over a burst of `PHYLLO_BENCH_BURST_N` frames
//!   (default 40), first close to last row;
//! - the daemon's peak RSS (VmHWM);
//! - the Python reference pipeline (`models/reference_pipeline.py`: PIL +
//!   numpy + onnxruntime, one process) on the same frames in the same run,
//!   with `PHYLLO_BENCH_PYTHON` (default `python3`).
//!
//! Frames: `PHYLLO_BENCH_FRAMES` (a directory of PNGs), else 8 frames made
//! by upscaling the real development images, as `phyllo bench` does.

mod common;

use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime};

use common::*;

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// Milliseconds since the epoch of an ISO 8601 UTC time as the store writes it.
fn epoch_ms(iso: &str) -> f64 {
    let t = chrono::DateTime::parse_from_rfc3339(iso).unwrap();
    t.timestamp_millis() as f64
}

fn now_ms() -> f64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
        * 1000.0
}

#[test]
#[ignore = "benchmark: run scripts/bench-daemon.sh"]
fn bench_daemon_on_full_frames() {
    let latency_n: usize = env_or("PHYLLO_BENCH_LATENCY_N", 20);
    let burst_n: usize = env_or("PHYLLO_BENCH_BURST_N", 40);
    let python: String = env_or("PHYLLO_BENCH_PYTHON", "python3".to_string());
    let model: PathBuf = std::env::var_os("PHYLLO_BENCH_MODEL")
        .map(PathBuf::from)
        .unwrap_or_else(common::model);
    let tmp = tempfile::tempdir().unwrap();
    let frames_dir = match std::env::var_os("PHYLLO_BENCH_FRAMES") {
        Some(d) => PathBuf::from(d),
        None => {
            let d = tmp.path().join("frames");
            std::fs::create_dir_all(&d).unwrap();
            phyllo::cli::bench::make_frames(&repo_root().join("../shared/data/unl-maize-dev/images"), &d, 8)
                .expect("making frames (set PHYLLO_BENCH_FRAMES to a directory of 2454x2056 PNGs)");
            d
        }
    };
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&frames_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    frames.sort();
    assert!(!frames.is_empty());
    let bytes: Vec<Vec<u8>> = frames.iter().map(|f| std::fs::read(f).unwrap()).collect();
    let (w, h) = image::image_dimensions(&frames[0]).unwrap();

    // Default intake and inference settings: what an installation gets.
    let site = Site::new("", "");
    let text = std::fs::read_to_string(&site.cfg).unwrap();
    let text = text
        .lines()
        .filter(|l| {
            !["stable_secs", "settle_ms", "poll_ms", "rescan_secs"]
                .iter()
                .any(|k| l.starts_with(k))
        })
        .map(|l| {
            if l.starts_with("model =") {
                format!("model = {model:?}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&site.cfg, text + "\n").unwrap();
    let mut d = site.serve();
    site.wait_running(&mut d);

    // Each dropped file needs unique content, or it is recorded as a duplicate
    // without counting. Bytes appended after IEND keep the PNG valid and make
    // the hash unique without re-encoding a frame.
    let unique = |i: usize| -> Vec<u8> {
        let mut b = bytes[i % bytes.len()].clone();
        b.extend(format!("phyllo-bench-{i}").as_bytes());
        b
    };
    let row_at = |name: &str| -> Option<String> {
        let s = common::open(&site.db).ok()?;
        s.query_row(
            "SELECT updated_at || '|' || state FROM images WHERE path = ?1",
            [name],
            |r| r.get::<_, String>(0),
        )
        .ok()
    };

    // Warm-up (first inference allocates).
    let warm = "W_2018-04-01_09-00-00_Vis_SV_0.png".to_string();
    std::fs::write(site.drop.join(&warm), unique(10_000)).unwrap();
    site.wait_for("warm-up", Duration::from_secs(120), || row_at(&warm).is_some());

    // Latency, one frame at a time into the idle daemon.
    let mut lat = Vec::new();
    for i in 0..latency_n {
        let name = flat_name("LAT", 1 + (i / 60) as u32, (i % 60) as u32, 0);
        let b = unique(i);
        std::fs::write(site.drop.join(&name), &b).unwrap(); // closed on return
        let closed = now_ms();
        let mut row = None;
        site.wait_for("latency frame", Duration::from_secs(60), || {
            row = row_at(&name);
            row.is_some()
        });
        let row = row.unwrap();
        let (at, state) = row.split_once('|').unwrap();
        assert_eq!(state, "counted", "{name}");
        lat.push(epoch_ms(at) - closed);
        std::thread::sleep(Duration::from_millis(300));
    }

    // Sustained throughput: a burst of frames.
    let names: Vec<String> = (0..burst_n)
        .map(|i| {
            flat_name(
                &format!("B{:02}", i / 6),
                2 + (i / 360) as u32,
                (i % 60) as u32,
                (i % 6) as u32 * 36,
            )
        })
        .collect();
    let payloads: Vec<Vec<u8>> = (0..burst_n).map(|i| unique(1_000 + i)).collect();
    let t0 = Instant::now();
    let first_close = now_ms();
    for (name, b) in names.iter().zip(&payloads) {
        std::fs::write(site.drop.join(name), b).unwrap();
    }
    let write_s = t0.elapsed().as_secs_f64();
    site.wait_for("the burst", Duration::from_secs(60 + 10 * burst_n as u64), || {
        site.q("SELECT COUNT(*) FROM images WHERE path LIKE 'B%'") >= burst_n as i64
    });
    let last_row = site.q("SELECT COUNT(*) FROM images WHERE path LIKE 'B%' AND state = 'counted'");
    assert_eq!(last_row, burst_n as i64);
    let last_ms = rows(
        &site.db,
        "SELECT MAX(updated_at) FROM images WHERE path LIKE 'B%'",
    )[0]
    .clone();
    let burst_s = (epoch_ms(&last_ms) - first_close) / 1000.0;
    let daemon_ips = burst_n as f64 / burst_s;
    let rss_mb = d.vm_hwm_kib() as f64 / 1024.0;
    let ms_model = rows(
        &site.db,
        "SELECT AVG(ms_total) FROM observations o JOIN images i ON i.id = o.image_id WHERE i.path LIKE 'B%'",
    )[0]
    .clone();
    assert!(d.term().success());

    // The Python pipeline on the same frames, in the same run.
    let py = phyllo::cli::bench::python_reference(&python, &model, &frames_dir, 1);
    let py_ips = py.as_ref().ok().and_then(|v| v["images_per_s"].as_f64());

    let (p50, p99) = (percentile(&mut lat, 0.5), percentile(&mut lat, 0.99));
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!();
    println!(
        "phyllo serve on {w}x{h} PNG frames ({} distinct, {cores} cores, load {})",
        frames.len(),
        load.trim()
    );
    println!("| measure | value |");
    println!("| --- | --- |");
    println!("| sustained images/s (burst of {burst_n}, first close to last row) | {daemon_ips:.2} |");
    println!("| mean model+pipeline ms per image (from observations) | {ms_model} |");
    println!("| latency close-after-write to row, p50 (idle, n={latency_n}) | {p50:.0} ms |");
    println!("| latency close-after-write to row, p99 (idle, n={latency_n}) | {p99:.0} ms |");
    println!("| peak RSS of phyllo serve (VmHWM) | {rss_mb:.0} MB |");
    match (&py, py_ips) {
        (Ok(_), Some(p)) => {
            println!("| Python reference images/s (same frames, same run) | {p:.2} |");
            println!("| phyllo serve / Python | {:.2}x |", daemon_ips / p);
        }
        (Err(e), _) => println!("| Python reference | skipped: {e:#} |"),
        _ => println!("| Python reference | no images_per_s in its summary |"),
    }
    println!("(burst written in {write_s:.2} s; intake settle_ms 300, poll_ms 250 are the defaults)");
}
