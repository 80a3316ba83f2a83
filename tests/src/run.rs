//! Running the daemon's commands in a test: knobs from the environment, a
//! config file, signals, a `phyllo tail` reader. The same helpers as the
//! `phyllo` crate's own test harness (`daemon/tests/common/run.rs` and
//! `site.rs`), which this crate cannot include: that one runs the binary cargo
//! builds for those tests, this one the binary [`phyllo`](crate::phyllo) finds.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, ExitStatus, Stdio};
use std::thread::JoinHandle;

/// An environment knob with a default.
pub fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Writes a config to `cfg`: `drop_dir` and `database`, then `extra` as it
/// is; returns the text.
pub fn write_config(cfg: &Path, drop: &Path, db: &Path, extra: &str) -> String {
    let text = format!("drop_dir = {drop:?}\ndatabase = {db:?}\n{extra}");
    std::fs::write(cfg, &text).unwrap();
    text
}

/// Sends a signal with kill(1).
pub fn signal(pid: u32, sig: &str) {
    let ok = std::process::Command::new("kill")
        .args([&format!("-{sig}"), &pid.to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -{sig} {pid}");
}

/// `phyllo tail -c CFG ARGS` in another process, its stdout read line by
/// line on a thread.
pub struct Tail {
    child: Child,
    reader: JoinHandle<Vec<String>>,
}

/// Starts `phyllo tail -c CFG ARGS` (e.g. `&["--json"]`).
pub fn spawn_tail(cfg: impl AsRef<std::ffi::OsStr>, args: &[&str]) -> Tail {
    let mut child = crate::phyllo()
        .arg("tail")
        .arg("-c")
        .arg(cfg)
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        BufReader::new(stdout)
            .lines()
            .map(|l| l.unwrap())
            .collect::<Vec<String>>()
    });
    Tail { child, reader }
}

impl Tail {
    /// SIGTERM, then waits for it to exit: its exit status and every line it
    /// printed.
    pub fn stop(mut self) -> (ExitStatus, Vec<String>) {
        signal(self.child.id(), "TERM");
        let status = self.child.wait().unwrap();
        (status, self.reader.join().unwrap())
    }
}
