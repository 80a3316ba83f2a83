//! `phyllo serve` as systemd runs it (`Type=notify`): the sd_notify protocol
//! over a real datagram socket — READY, STATUS, WATCHDOG pings, STOPPING on
//! SIGTERM — and a clean exit. Uses the shipped model and ONNX Runtime.

mod common;

use std::os::unix::net::UnixDatagram;
use std::process::Command;
use std::time::{Duration, Instant};

use common::{signal, write_config, BIN};

#[test]
fn serve_speaks_sd_notify_and_stops_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let sock_path = dir.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let cfg = dir.path().join("phyllo.toml");
    std::fs::create_dir_all(dir.path().join("drop")).unwrap();
    write_config(
        &cfg,
        &dir.path().join("drop"),
        &dir.path().join("db/phyllo.sqlite"),
        "",
    );
    let mut child = Command::new(BIN)
        .args(["serve", "-c"])
        .arg(&cfg)
        .env("NOTIFY_SOCKET", &sock_path)
        .env("WATCHDOG_USEC", "1000000")
        .spawn()
        .unwrap();
    let mut seen: Vec<String> = Vec::new();
    let mut buf = [0u8; 4096];
    let mut recv_until = |seen: &mut Vec<String>, want: &str, timeout: Duration| {
        let t0 = Instant::now();
        while !seen.iter().any(|m| m.contains(want)) {
            assert!(
                t0.elapsed() < timeout,
                "no {want} from phyllo serve; got {seen:?}"
            );
            if let Ok(n) = sock.recv(&mut buf) {
                seen.push(String::from_utf8_lossy(&buf[..n]).into_owned());
            }
        }
    };
    recv_until(&mut seen, "READY=1", Duration::from_secs(120));
    recv_until(&mut seen, "WATCHDOG=1", Duration::from_secs(5));
    assert!(seen.iter().any(|m| m.contains("STATUS=")), "{seen:?}");
    signal(child.id(), "TERM");
    recv_until(&mut seen, "STOPPING=1", Duration::from_secs(10));
    let status = child.wait().unwrap();
    assert!(status.success(), "exit status after SIGTERM: {status}");
}

/// SIGHUP (a `kill -HUP`, a closed terminal) stops the service as SIGTERM
/// does, and exits 75 so that systemd's `Restart=on-failure` starts it again
/// (issue 57 item 3): before, the default action killed it mid-count with a
/// status systemd took for a clean stop, and the unit stayed down.
#[test]
fn serve_stops_cleanly_on_sighup_and_asks_to_be_started_again() {
    let dir = tempfile::tempdir().unwrap();
    let sock_path = dir.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    let cfg = dir.path().join("phyllo.toml");
    std::fs::create_dir_all(dir.path().join("drop")).unwrap();
    std::fs::write(&cfg, "drop_dir = \"drop\"\ndatabase = \"db/phyllo.sqlite\"\n").unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_phyllo"))
        .args(["serve", "-c"])
        .arg(&cfg)
        .env("NOTIFY_SOCKET", &sock_path)
        .spawn()
        .unwrap();
    let mut seen = String::new();
    let mut buf = [0u8; 4096];
    let mut recv_until = |seen: &mut String, want: &str, timeout: Duration| {
        let t0 = Instant::now();
        while !seen.contains(want) {
            assert!(
                t0.elapsed() < timeout,
                "no {want} from phyllo serve; got {seen:?}"
            );
            if let Ok(n) = sock.recv(&mut buf) {
                seen.push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        }
    };
    recv_until(&mut seen, "READY=1", Duration::from_secs(120));
    assert!(Command::new("kill")
        .args(["-HUP", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    recv_until(&mut seen, "STOPPING=1", Duration::from_secs(10));
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(75), "exit status after SIGHUP: {status}");
    let out = Command::new(env!("CARGO_BIN_EXE_phyllo"))
        .args(["status", "--json", "-c"])
        .arg(&cfg)
        .output()
        .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["state"], "stopped", "{json}");
}
