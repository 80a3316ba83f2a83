//! Helpers shared by phyllo's end-to-end tests: the built binaries, the
//! shipped models and the shared development data; running the daemon's
//! commands ([`run`]).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub mod run;

pub use run::{env_or, signal, spawn_tail, write_config, Tail};

/// Root of the repository.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The real development images beside the checkout (`../shared/data/unl-maize-dev`).
/// CI clones the repository with `shared/` beside it; `PHYLLO_DEV_DATA` overrides.
pub fn dev_data() -> Option<PathBuf> {
    let dir = std::env::var_os("PHYLLO_DEV_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("../shared/data/unl-maize-dev"));
    dir.join("images").is_dir().then_some(dir)
}

/// The directory cargo puts this profile's binaries in (`target/debug`).
fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test> -> target/<profile>
    exe.parent()
        .and_then(Path::parent)
        .expect("test binary lives in target/<profile>/deps")
        .to_path_buf()
}

/// Path to a workspace binary, (re)built first: `cargo test` builds other
/// packages' binaries only sometimes, and a stale binary would test old code.
/// Cargo does nothing when it is fresh.
pub fn binary(name: &str, package: &str) -> PathBuf {
    static BUILT: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let path = bin_dir().join(name);
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    if !built.iter().any(|b| b == name) {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let profile = bin_dir()
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut cmd = Command::new(cargo);
        cmd.current_dir(repo_root())
            .args(["build", "--quiet", "-p", package, "--bin", name]);
        if profile == "release" {
            cmd.arg("--release");
        }
        let status = cmd.status().expect("run cargo build");
        assert!(status.success(), "cargo build -p {package} failed");
        built.push(name.to_string());
    }
    path
}

/// The `phyllo` binary.
pub fn phyllo() -> Command {
    Command::new(binary("phyllo", "phyllo"))
}

/// Runs a command, returning its output (stdout, stderr as text).
pub fn run(cmd: &mut Command) -> (Output, String, String) {
    let out = cmd.output().expect("spawn");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    (out, stdout, stderr)
}

/// The untrained model shipped for tests (contract-valid, meaningless counts).
pub fn untrained_model() -> PathBuf {
    repo_root().join("models/phyllo-untrained.onnx")
}
