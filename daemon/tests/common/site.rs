//! Config writers and a test's directories with a config for `phyllo serve`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use phyllo::store::Store;

use super::db::q;
use super::run::{model, poll_until, tail, Daemon, BIN};

/// A config's text: `drop_dir` and `database`, then `extra` as it is.
pub fn config_text(drop: &Path, db: &Path, extra: &str) -> String {
    format!("drop_dir = {drop:?}\ndatabase = {db:?}\n{extra}")
}

/// Writes [`config_text`] to `cfg`; returns the text.
pub fn write_config(cfg: &Path, drop: &Path, db: &Path, extra: &str) -> String {
    let text = config_text(drop, db, extra);
    std::fs::write(cfg, &text).unwrap();
    text
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
        write_config(
            &cfg,
            &drop,
            &db,
            &format!(
                "[watch]\n{}\n[inference]\nmodel = {:?}\n{extra}",
                watch.join("\n"),
                model()
            ),
        );
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

    /// Runs `phyllo ARGS -c CFG` to its end.
    pub fn phyllo(&self, args: &[&str]) -> Output {
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
    pub fn wait_for(&self, what: &str, timeout: Duration, cond: impl FnMut() -> bool) {
        assert!(
            poll_until(timeout, cond),
            "timed out after {timeout:?} waiting for {what}; log tail:\n{}",
            tail(&self.log_text(), 40)
        );
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
