//! Records the git commit phyllo-gen is built from, so every dataset row can
//! say which generator made it (`Row::generator`).

use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into());
    // A binary built from uncommitted generator code must not claim the
    // commit's name: a dataset made with it could not be rebuilt from it.
    let dirty = Command::new("git")
        .args(["status", "--porcelain", "--", "."])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .is_some_and(|o| !o.stdout.is_empty());
    let suffix = if dirty && commit != "unknown" {
        "-dirty"
    } else {
        ""
    };
    println!("cargo:rustc-env=PHYLLO_GEN_COMMIT={commit}{suffix}");
    // A new commit moves HEAD's ref; a checkout moves HEAD itself; an edit
    // to the generator's own files makes it dirty.
    for p in [
        "../.git/HEAD",
        "../.git/refs/heads",
        "../.git/index",
        "src",
        "presets",
    ] {
        println!("cargo:rerun-if-changed={p}");
    }
}
