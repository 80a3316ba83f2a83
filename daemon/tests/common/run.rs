//! The binary under test and its processes: one-shot runs, waiting for a
//! condition, signals, a `phyllo tail` reader, a running `phyllo serve`.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

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

/// Runs `phyllo ARGS` to its end.
pub fn phyllo(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

/// Runs `phyllo ARGS`, failing the test with its stderr unless it succeeds;
/// its stdout.
pub fn ok(args: &[&str]) -> String {
    let out = phyllo(args);
    assert!(
        out.status.success(),
        "phyllo {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Polls `cond` every 50 ms until it holds (true) or `timeout` has passed
/// (false).
pub fn poll_until(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let t0 = Instant::now();
    while !cond() {
        if t0.elapsed() >= timeout {
            return false;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    true
}

/// Waits until `cond` holds, failing the test after `timeout`. (`Site::wait_for`
/// adds the daemon's log to the failure.)
pub fn wait_for(what: &str, timeout: Duration, cond: impl FnMut() -> bool) {
    assert!(poll_until(timeout, cond), "timed out waiting for {what}");
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

/// The last `n` lines of `s`.
pub fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// `phyllo tail -c CFG ARGS` in another process, its stdout read line by
/// line on a thread.
pub struct Tail {
    child: Child,
    reader: JoinHandle<Vec<String>>,
}

/// Starts `phyllo tail -c CFG ARGS` (e.g. `&["--json"]`).
pub fn spawn_tail(cfg: impl AsRef<std::ffi::OsStr>, args: &[&str]) -> Tail {
    let mut child = Command::new(BIN)
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

/// A tmpfs mounted for a test, unmounted (lazily) when dropped.
pub struct Tmpfs(PathBuf);

/// Mounts a tmpfs of `size` (`mount -o size=`, e.g. `"2M"`) on `dir`; `None`
/// where that is not allowed (not root, or no mount in this sandbox).
pub fn mount_tmpfs(dir: &Path, size: &str) -> Option<Tmpfs> {
    Command::new("mount")
        .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
        .arg(dir)
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
        .then(|| Tmpfs(dir.to_path_buf()))
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// A running `phyllo serve`, killed if the test ends without stopping it.
pub struct Daemon {
    /// `None` once stopped.
    pub(crate) child: Option<Child>,
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
