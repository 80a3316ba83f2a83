//! The systemd units: `systemd-analyze verify` accepts them, and the service's
//! hardening keeps `systemd-analyze security` exposure at or below 2.0.
//! Skipped, with the reason printed, where systemd-analyze is not installed.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{repo_root, BIN};

const UNITS: [&str; 7] = [
    "phyllo.service",
    "phyllo-export.service",
    "phyllo-backup.service",
    "phyllo-import.service",
    "phyllo-export.timer",
    "phyllo-backup.timer",
    "phyllo-import.timer",
];

fn systemd_analyze() -> Option<PathBuf> {
    let ok = Command::new("systemd-analyze")
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if ok {
        Some(PathBuf::from("systemd-analyze"))
    } else {
        eprintln!("SKIPPED: systemd-analyze is not installed");
        None
    }
}

/// Copies the units, pointing ExecStart at the binary cargo just built (verify
/// checks that the command exists and is executable).
fn units_in(dir: &Path) -> Vec<PathBuf> {
    let src = repo_root().join("systemd");
    UNITS
        .iter()
        .map(|u| {
            let text = std::fs::read_to_string(src.join(u)).unwrap();
            let text = text.replace("/usr/local/bin/phyllo", BIN);
            let out = dir.join(u);
            std::fs::write(&out, text).unwrap();
            out
        })
        .collect()
}

#[test]
fn units_verify() {
    let Some(sa) = systemd_analyze() else { return };
    let dir = tempfile::tempdir().unwrap();
    let units = units_in(dir.path());
    let out = Command::new(&sa).arg("verify").args(&units).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    // Only complaints about our own units count; the host's other units may be odd.
    let ours: Vec<&str> = stderr
        .lines()
        .filter(|l| UNITS.iter().any(|u| l.contains(u)))
        .collect();
    assert!(
        out.status.success() && ours.is_empty(),
        "systemd-analyze verify:\n{stderr}"
    );
}

#[test]
fn service_exposure_is_at_most_2() {
    let Some(sa) = systemd_analyze() else { return };
    let dir = tempfile::tempdir().unwrap();
    let units = units_in(dir.path());
    for unit in &units[..3] {
        let out = Command::new(&sa)
            .args(["security", "--offline=yes", "--no-pager"])
            .arg(unit)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        let Some(line) = text.lines().find(|l| l.contains("Overall exposure level")) else {
            eprintln!(
                "SKIPPED: this systemd-analyze has no offline security analysis:\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
            return;
        };
        let level: f64 = line
            .split(':')
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .unwrap()
            .parse()
            .unwrap();
        eprintln!("{line}");
        assert!(level <= 2.0, "{}: {line}", unit.display());
    }
}

/// The service's memory is bounded: a runaway decode is stopped by the kernel,
/// not the greenhouse computer (read from the unit itself, no systemd needed).
#[test]
fn the_service_sets_a_memory_limit() {
    let unit =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../systemd/phyllo.service"))
            .unwrap();
    let value = |key: &str| {
        unit.lines()
            .find_map(|l| l.strip_prefix(key)?.strip_prefix('='))
            .map(str::trim)
            .map(String::from)
    };
    let gib = |v: Option<String>| -> f64 {
        let v = v.expect("set in phyllo.service");
        v.strip_suffix('G').expect("in G").parse().unwrap()
    };
    let (high, max) = (gib(value("MemoryHigh")), gib(value("MemoryMax")));
    assert!(
        high >= 2.0 && max > high && max <= 8.0,
        "MemoryHigh={high}G MemoryMax={max}G"
    );
}
