//! Helpers for the fault, bad-input and load tests: the real `phyllo`
//! binary run as a child process against a temporary drop directory and
//! state directory, with the shipped (untrained, contract-valid) model.
//!
//! Knobs shared by the tests are read from the environment with [`env_or`];
//! each test documents its own.

#![allow(dead_code)] // each test binary uses a different subset

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use phyllo::store::Store;

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_phyllo");

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The model the daemon runs: `PHYLLO_TEST_MODEL` (relative to the repository
/// root), else the shipped test model (random weights, valid contract).
pub fn model() -> PathBuf {
    match std::env::var_os("PHYLLO_TEST_MODEL") {
        Some(m) => repo_root().join(m),
        None => repo_root().join("models/phyllo-untrained.onnx"),
    }
}

/// An environment knob with a default.
pub fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A test's directories: `drop/`, `state/phyllo.sqlite`, `phyllo.toml`, `serve.log`.
pub struct Site {
    /// Keeps the temporary directory alive.
    pub tmp: tempfile::TempDir,
    /// The drop directory.
    pub drop: PathBuf,
    /// The state directory (holds the database).
    pub state: PathBuf,
    /// The database file.
    pub db: PathBuf,
    /// The config file.
    pub cfg: PathBuf,
    /// Where the daemon's stderr goes (appended over restarts).
    pub log: PathBuf,
}

impl Site {
    /// Creates the directories and a config with fast intake timings; `extra`
    /// is appended to `[inference]` (e.g. `"workers = 1\n"`), `watch_extra` to `[watch]`.
    pub fn new(extra: &str, watch_extra: &str) -> Site {
        let tmp = tempfile::tempdir().unwrap();
        let drop = tmp.path().join("drop");
        let state = tmp.path().join("state");
        std::fs::create_dir_all(&drop).unwrap();
        std::fs::create_dir_all(&state).unwrap();
        let db = state.join("phyllo.sqlite");
        let cfg = tmp.path().join("phyllo.toml");
        // Fast intake timings, each overridable by a line of `watch_extra`.
        let mut watch: Vec<String> = [
            "stable_secs = 1.0",
            "settle_ms = 100",
            "poll_ms = 50",
            "rescan_secs = 2",
        ]
        .iter()
        .filter(|d| {
            let key = d.split('=').next().unwrap().trim();
            !watch_extra
                .lines()
                .any(|l| l.split('=').next().unwrap().trim() == key)
        })
        .map(|d| d.to_string())
        .collect();
        watch.extend(
            watch_extra
                .lines()
                .filter(|l| !l.trim().is_empty())
                .map(String::from),
        );
        std::fs::write(
            &cfg,
            format!(
                "drop_dir = {drop:?}\ndatabase = {db:?}\n[watch]\n{}\n[inference]\nmodel = {:?}\n{extra}",
                watch.join("\n"),
                model()
            ),
        )
        .unwrap();
        let log = tmp.path().join("serve.log");
        Site {
            tmp,
            drop,
            state,
            db,
            cfg,
            log,
        }
    }

    /// Starts `phyllo serve` (stderr appended to the log).
    pub fn serve(&self) -> Daemon {
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.log)
            .unwrap();
        let child = Command::new(BIN)
            .args(["serve", "-c"])
            .arg(&self.cfg)
            .env("PHYLLO_LOG", "info")
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .unwrap();
        Daemon { child: Some(child) }
    }

    /// The daemon's log so far.
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// One integer from the database (-1 if it cannot be read yet).
    pub fn q(&self, sql: &str) -> i64 {
        q(&self.db, sql)
    }

    /// Runs `phyllo ARGS -c CFG`.
    pub fn phyllo(&self, args: &[&str]) -> std::process::Output {
        Command::new(BIN)
            .args(args)
            .arg("-c")
            .arg(&self.cfg)
            .output()
            .unwrap()
    }

    /// `phyllo status --json`.
    pub fn status(&self) -> serde_json::Value {
        let out = self.phyllo(&["status", "--json"]);
        serde_json::from_slice(&out.stdout).unwrap_or_default()
    }

    /// Waits until `cond` holds, failing with the log after `timeout`.
    pub fn wait_for(&self, what: &str, timeout: Duration, mut cond: impl FnMut() -> bool) {
        let t0 = Instant::now();
        while !cond() {
            assert!(
                t0.elapsed() < timeout,
                "timed out after {timeout:?} waiting for {what}; log tail:\n{}",
                tail(&self.log_text(), 40)
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Waits until the daemon `d` reports itself running (database open,
    /// model loaded, watch up).
    pub fn wait_running(&self, d: &mut Daemon) {
        let pid = d.pid().to_string();
        let t0 = Instant::now();
        loop {
            if let Some(st) = d.child.as_mut().unwrap().try_wait().unwrap() {
                panic!(
                    "phyllo serve exited early ({st}); log:\n{}",
                    tail(&self.log_text(), 40)
                );
            }
            if let Ok(s) = Store::open_read_only(&self.db) {
                if let Ok(svc) = s.service() {
                    if svc.get("pid") == Some(&pid) && svc.get("state").map(String::as_str) == Some("running")
                    {
                        return;
                    }
                }
            }
            assert!(t0.elapsed() < Duration::from_secs(60), "daemon never came up");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// The last `n` lines of `s`.
pub fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// One integer from the database at `db` (-1 if it cannot be read).
pub fn q(db: &Path, sql: &str) -> i64 {
    let Ok(s) = Store::open_read_only(db) else {
        return -1;
    };
    s.conn().query_row(sql, [], |r| r.get(0)).unwrap_or(-1)
}

/// One text value from the database.
pub fn qs(db: &Path, sql: &str) -> String {
    let s = Store::open_read_only(db).unwrap();
    s.conn()
        .query_row(sql, [], |r| r.get::<_, String>(0))
        .unwrap_or_else(|e| panic!("{sql}: {e}"))
}

/// All rows of a query, each row's columns joined with `|` (NULL as `∅`).
pub fn rows(db: &Path, sql: &str) -> Vec<String> {
    let s = Store::open_read_only(db).unwrap();
    let mut st = s.conn().prepare(sql).unwrap();
    let n = st.column_count();
    st.query_map([], |r| {
        let mut cols = Vec::with_capacity(n);
        for i in 0..n {
            use rusqlite::types::ValueRef;
            cols.push(match r.get_ref(i)? {
                ValueRef::Null => "∅".to_string(),
                ValueRef::Integer(v) => v.to_string(),
                ValueRef::Real(v) => format!("{v:.6}"),
                ValueRef::Text(t) | ValueRef::Blob(t) => String::from_utf8_lossy(t).into_owned(),
            });
        }
        Ok(cols.join("|"))
    })
    .unwrap()
    .map(Result::unwrap)
    .collect()
}

/// Timelines as comparable rows: sessions, plants and events per plant name.
pub fn timelines(db: &Path) -> Vec<String> {
    let mut out = rows(
        db,
        "SELECT 'session', p.name, s.start, s.views, s.n_counts, s.fused, s.leaves_emerged, s.living
         FROM sessions s JOIN plants p ON p.id = s.plant_id ORDER BY p.name, s.start",
    );
    out.extend(rows(
        db,
        "SELECT 'plant', name, sessions, last_taken_at, leaves_emerged, living, phyllochron_days
         FROM plants ORDER BY name",
    ));
    out.extend(rows(
        db,
        "SELECT 'event', p.name, e.leaf, e.emerged_at, e.seen_at FROM events e
         JOIN plants p ON p.id = e.plant_id ORDER BY p.name, e.leaf",
    ));
    out
}

/// A running `phyllo serve`.
pub struct Daemon {
    child: Option<Child>,
}

impl Daemon {
    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.as_ref().unwrap().id()
    }

    /// `kill -9`, and reaps it.
    pub fn kill9(mut self) {
        let mut c = self.child.take().unwrap();
        c.kill().unwrap(); // SIGKILL
        c.wait().unwrap();
    }

    /// SIGTERM, then waits for it to exit (at most 60 s).
    pub fn term(mut self) -> ExitStatus {
        let mut c = self.child.take().unwrap();
        signal(c.id(), "TERM");
        let t0 = Instant::now();
        loop {
            if let Some(st) = c.try_wait().unwrap() {
                return st;
            }
            if t0.elapsed() > Duration::from_secs(60) {
                let _ = c.kill();
                panic!("phyllo serve did not stop within 60 s of SIGTERM");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Peak resident set size (VmHWM) so far, in KiB.
    pub fn vm_hwm_kib(&self) -> u64 {
        let s = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).unwrap_or_default();
        s.lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .unwrap_or(0)
    }

    /// Waits up to `timeout` for it to exit on its own; its exit status, or
    /// `None` if it still runs.
    pub fn exited_within(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.child.as_mut().unwrap().try_wait().unwrap() {
                return Some(st);
            }
            if t0.elapsed() > timeout {
                return None;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Whether it is still running.
    pub fn alive(&mut self) -> bool {
        self.child.as_mut().unwrap().try_wait().unwrap().is_none()
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Sends a signal with kill(1) (no libc dependency in the tests).
pub fn signal(pid: u32, sig: &str) {
    let ok = Command::new("kill")
        .args([&format!("-{sig}"), &pid.to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -{sig} {pid}");
}

/// Images `range` of a stream: (relative name, bytes), spread over `plants`
/// plants named `<prefix>NN`, several days, five side views, unique content
/// each (seeded from `seed + i`).
pub fn image_stream(
    range: std::ops::Range<usize>,
    plants: usize,
    prefix: &str,
    seed: u64,
) -> Vec<(String, Vec<u8>)> {
    range
        .map(|i| {
            let plant = format!("{prefix}{:02}", i % plants);
            let k = i / plants;
            let (day, view) = (1 + (k / 5) as u32, (k % 5) as u32);
            (
                flat_name(&plant, day, view * 7, view * 36),
                small_png(seed + i as u64, 96),
            )
        })
        .collect()
}

/// A flat-layout file name.
pub fn flat_name(plant: &str, day: u32, second: u32, angle: u32) -> String {
    format!("{plant}_2018-04-{day:02}_10-00-{second:02}_Vis_SV_{angle}.png")
}

/// A small, unique PNG: white background, a green stripe whose position and
/// a corner pixel depend on `seed`, so no two seeds share content.
pub fn small_png(seed: u64, side: u32) -> Vec<u8> {
    let mut img = image::RgbImage::from_pixel(side, side, image::Rgb([235, 235, 230]));
    let x0 = (seed % (side as u64 / 2)) as u32 + side / 4;
    for y in side / 4..side {
        for x in x0.saturating_sub(3)..(x0 + 3).min(side) {
            img.put_pixel(x, y, image::Rgb([40, 120, 30]));
        }
    }
    let b = seed.to_le_bytes();
    img.put_pixel(0, 0, image::Rgb([b[0], b[1], b[2]]));
    img.put_pixel(1, 0, image::Rgb([b[3], b[4], b[5]]));
    encode(image::DynamicImage::ImageRgb8(img), image::ImageFormat::Png)
}

/// Encodes an image.
pub fn encode(img: image::DynamicImage, fmt: image::ImageFormat) -> Vec<u8> {
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), fmt).unwrap();
    out
}

/// A deterministic generator (xorshift64*), so a failing run reproduces from its seed.
pub struct Rng(pub u64);

impl Rng {
    /// Next value.
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `[lo, hi)` milliseconds.
    pub fn ms(&mut self, lo: u64, hi: u64) -> Duration {
        Duration::from_millis(lo + self.next() % (hi - lo).max(1))
    }
}

/// Writes `bytes` to `dst` either directly (close-after-write) or through a
/// hidden temporary renamed into place, as imaging stations do.
pub fn drop_file(dst: &Path, bytes: &[u8], via_rename: bool) {
    if via_rename {
        let tmp = dst.with_file_name(format!(".{}.part", dst.file_name().unwrap().to_string_lossy()));
        std::fs::write(&tmp, bytes).unwrap();
        std::fs::rename(&tmp, dst).unwrap();
    } else {
        std::fs::write(dst, bytes).unwrap();
    }
}

/// `PRAGMA integrity_check` of the database.
pub fn integrity(db: &Path) -> String {
    qs(db, "PRAGMA integrity_check")
}
