//! A burst of files into the drop directory of a running `phyllo serve` (real
//! binary, shipped model, real inotify): every file processed exactly once,
//! no event lost, peak RSS bounded.
//!
//! Periodic rescans are switched off (`rescan_secs = 0`), so every file must
//! come through inotify, or through the scan an inotify queue overflow
//! triggers: a file that only a periodic rescan would find counts as lost.
//!
//! Most files are 8×8 PNGs with valid names, which the decoder refuses as too
//! small after reading their header: they go through the whole path (intake,
//! queue, worker, hash, name, decode, one transaction) without paying for the
//! model, so the burst exercises the intake and the store at full speed. Every
//! `PHYLLO_LOAD_COUNT_EVERY`-th file (default 25) is a real image the model
//! counts.
//!
//! Knobs: `PHYLLO_LOAD_FILES` (default 1000; the full run is 10000),
//! `PHYLLO_LOAD_COUNT_EVERY` (25), `PHYLLO_LOAD_MAX_RSS_MB` (300). The full
//! run: `scripts/load.sh` (release build, 10,000 files).

mod common;

use std::time::{Duration, Instant};

use common::*;

#[test]
fn burst_of_files_all_processed_with_bounded_memory() {
    let n: usize = env_or("PHYLLO_LOAD_FILES", 1000);
    let every: usize = env_or("PHYLLO_LOAD_COUNT_EVERY", 25).max(1);
    let max_rss_mb: u64 = env_or("PHYLLO_LOAD_MAX_RSS_MB", 300);
    let site = Site::new("workers = 2\nintra_threads = 2\n", "rescan_secs = 0\n");
    let mut d = site.serve();
    site.wait_running(&mut d);
    let idle_rss = d.vm_hwm_kib();

    // Prepare the bytes first, so the burst is only file system work.
    let files: Vec<(String, Vec<u8>)> = (0..n)
        .map(|i| {
            let name = format!("L{:05}_2018-04-01_10-00-00_Vis_SV_0.png", i);
            let bytes = if i % every == 0 {
                small_png(i as u64, 96)
            } else {
                small_png(i as u64, 8)
            };
            (name, bytes)
        })
        .collect();
    let counted = files.iter().enumerate().filter(|(i, _)| i % every == 0).count() as i64;
    // Spread over a few folders, as snapshot layouts do; half renamed into place.
    let t0 = Instant::now();
    for (i, (name, bytes)) in files.iter().enumerate() {
        let dir = site.drop.join(format!("batch{:03}", i / 1000));
        if i % 1000 == 0 {
            std::fs::create_dir_all(&dir).unwrap();
        }
        drop_file(&dir.join(name), bytes, i % 2 == 1);
    }
    let burst = t0.elapsed();
    let mut peak_rss = 0;
    site.wait_for(
        &format!("{n} files processed"),
        Duration::from_secs(120 + n as u64 / 5),
        || {
            peak_rss = peak_rss.max(d.vm_hwm_kib());
            site.q("SELECT COUNT(*) FROM images") >= n as i64
        },
    );
    let took = t0.elapsed();
    std::thread::sleep(Duration::from_millis(500));
    peak_rss = peak_rss.max(d.vm_hwm_kib());
    assert!(d.term().success());

    assert_eq!(integrity(&site.db), "ok");
    assert_eq!(site.q("SELECT COUNT(*) FROM images"), n as i64, "each file once");
    assert_eq!(site.q("SELECT COUNT(DISTINCT path) FROM images"), n as i64);
    assert_eq!(site.q("SELECT COUNT(*) FROM observations"), counted);
    assert_eq!(
        site.q("SELECT COUNT(*) FROM images WHERE state = 'failed' AND error LIKE '%too small%'"),
        n as i64 - counted
    );
    let overflowed = site.log_text().contains("overflowed");
    eprintln!(
        "load: {n} files ({counted} counted by the model) written in {burst:.2?}, all processed {took:.1?} \
         after the first write ({:.0} files/s); inotify overflow: {overflowed}; peak RSS {:.1} MB \
         (idle after start {:.1} MB)",
        n as f64 / took.as_secs_f64(),
        peak_rss as f64 / 1024.0,
        idle_rss as f64 / 1024.0
    );
    assert!(
        peak_rss <= max_rss_mb * 1024,
        "peak RSS {:.1} MB > {max_rss_mb} MB",
        peak_rss as f64 / 1024.0
    );
}

/// The inotify queue overflows: the daemon is frozen with SIGSTOP while more
/// files land than the kernel queue holds (`fs.inotify.max_queued_events`,
/// 16384 by default; each written file makes three events), then thawed.
/// The kernel drops events and says so; the daemon rescans, and every file is
/// processed once, with periodic rescans off. Knob: `PHYLLO_OVERFLOW_FILES`
/// (default: enough files to overflow the queue, at least 6000).
#[test]
fn inotify_overflow_loses_nothing() {
    let limit: usize = std::fs::read_to_string("/proc/sys/fs/inotify/max_queued_events")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(16384);
    let n: usize = env_or("PHYLLO_OVERFLOW_FILES", (limit / 3 + 600).max(6000));
    let site = Site::new("workers = 2\nintra_threads = 1\n", "rescan_secs = 0\n");
    let mut d = site.serve();
    site.wait_running(&mut d);
    signal(d.pid(), "STOP");
    let bytes = small_png(1, 8);
    for i in 0..n {
        // Not-quite-identical content keeps each file its own record.
        let mut b = bytes.clone();
        b.extend(i.to_le_bytes());
        std::fs::write(
            site.drop
                .join(format!("O{i:05}_2018-04-01_10-00-00_Vis_SV_0.png")),
            b,
        )
        .unwrap();
    }
    signal(d.pid(), "CONT");
    let t0 = Instant::now();
    site.wait_for(
        &format!("{n} files after the overflow"),
        Duration::from_secs(120 + n as u64 / 20),
        || site.q("SELECT COUNT(*) FROM images") >= n as i64,
    );
    let took = t0.elapsed();
    std::thread::sleep(Duration::from_millis(500));
    assert!(d.term().success());
    assert_eq!(site.q("SELECT COUNT(*) FROM images"), n as i64);
    assert_eq!(site.q("SELECT COUNT(DISTINCT path) FROM images"), n as i64);
    assert_eq!(integrity(&site.db), "ok");
    let overflowed = site.log_text().contains("overflowed");
    eprintln!("overflow: {n} files while stopped (queue limit {limit}), overflow reported: {overflowed}, all processed in {took:.1?}");
    if 3 * n > limit {
        assert!(
            overflowed,
            "the kernel queue must have overflowed ({n} files, limit {limit})"
        );
    }
}
