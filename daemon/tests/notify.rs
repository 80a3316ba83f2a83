//! `phyllo serve` as systemd runs it (`Type=notify`): the sd_notify protocol
//! over a real datagram socket — READY, STATUS, WATCHDOG pings, STOPPING on
//! SIGTERM and SIGHUP — and a clean exit. Uses the shipped model and ONNX Runtime.

mod common;

use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use common::{signal, write_config, BIN};

/// A `phyllo serve` with a notify socket, and the messages it has sent.
struct Notified {
    child: Child,
    sock: UnixDatagram,
    seen: Vec<String>,
    cfg: PathBuf,
}

impl Notified {
    /// Starts the service on a fresh site in `dir`, with `env` set.
    fn start(dir: &Path, env: &[(&str, &str)]) -> Notified {
        let sock_path = dir.join("notify.sock");
        let sock = UnixDatagram::bind(&sock_path).unwrap();
        sock.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
        let cfg = dir.join("phyllo.toml");
        std::fs::create_dir_all(dir.join("drop")).unwrap();
        write_config(&cfg, &dir.join("drop"), &dir.join("db/phyllo.sqlite"), "");
        let child = Command::new(BIN)
            .args(["serve", "-c"])
            .arg(&cfg)
            .env("NOTIFY_SOCKET", &sock_path)
            .envs(env.iter().copied())
            .spawn()
            .unwrap();
        Notified {
            child,
            sock,
            seen: Vec::new(),
            cfg,
        }
    }

    /// Waits until a message containing `want` has come.
    fn recv_until(&mut self, want: &str, timeout: Duration) {
        let mut buf = [0u8; 4096];
        let t0 = Instant::now();
        while !self.seen.iter().any(|m| m.contains(want)) {
            assert!(
                t0.elapsed() < timeout,
                "no {want} from phyllo serve; got {:?}",
                self.seen
            );
            if let Ok(n) = self.sock.recv(&mut buf) {
                self.seen.push(String::from_utf8_lossy(&buf[..n]).into_owned());
            }
        }
    }
}

#[test]
fn serve_speaks_sd_notify_and_stops_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let mut n = Notified::start(dir.path(), &[("WATCHDOG_USEC", "1000000")]);
    n.recv_until("READY=1", Duration::from_secs(120));
    n.recv_until("WATCHDOG=1", Duration::from_secs(5));
    let seen = &n.seen;
    assert!(seen.iter().any(|m| m.contains("STATUS=")), "{seen:?}");
    signal(n.child.id(), "TERM");
    n.recv_until("STOPPING=1", Duration::from_secs(10));
    let status = n.child.wait().unwrap();
    assert!(status.success(), "exit status after SIGTERM: {status}");
}

/// SIGHUP (a `kill -HUP`, a closed terminal) stops the service as SIGTERM
/// does, and exits 75 so that systemd's `Restart=on-failure` starts it again
/// (issue 57 item 3): before, the default action killed it mid-count with a
/// status systemd took for a clean stop, and the unit stayed down.
#[test]
fn serve_stops_cleanly_on_sighup_and_asks_to_be_started_again() {
    let dir = tempfile::tempdir().unwrap();
    let mut n = Notified::start(dir.path(), &[]);
    n.recv_until("READY=1", Duration::from_secs(120));
    signal(n.child.id(), "HUP");
    n.recv_until("STOPPING=1", Duration::from_secs(10));
    let status = n.child.wait().unwrap();
    assert_eq!(status.code(), Some(75), "exit status after SIGHUP: {status}");
    let out = Command::new(BIN)
        .args(["status", "--json", "-c"])
        .arg(&n.cfg)
        .output()
        .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["state"], "stopped", "{json}");
}
