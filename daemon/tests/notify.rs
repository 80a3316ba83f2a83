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
