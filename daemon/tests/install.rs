//! `scripts/install.sh` into a temporary prefix: the installed `phyllo`,
//! stripped of its debug info, counts a sample from another directory with
//! an empty HOME and no environment, with the model and the ONNX Runtime
//! library it installed.

mod common;

use std::process::Command;

use common::{repo_root, BIN};

#[test]
fn installed_into_a_prefix_it_counts_from_anywhere() {
    let root = repo_root();
    let tmp = tempfile::tempdir().unwrap();
    let prefix = tmp.path().join("opt/phyllo");
    let out = Command::new("bash")
        .arg(root.join("scripts/install.sh"))
        .arg("--prefix")
        .arg(&prefix)
        .args(["--bin", BIN, "--no-systemd"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "install.sh failed: {said}");
    for f in [
        "bin/phyllo",
        "share/phyllo/phyllo.onnx",
        "lib/phyllo/libonnxruntime.so",
        "share/phyllo/phyllo.toml.example",
        "share/doc/phyllo/daemon.md",
    ] {
        assert!(prefix.join(f).is_file(), "{f} not installed: {said}");
    }
    // Installed without its debug info (in the debug build that the tests
    // use, 41 of 68 MB are left).
    let size = |p: &std::path::Path| std::fs::metadata(p).unwrap().len();
    let (built, installed) = (size(std::path::Path::new(BIN)), size(&prefix.join("bin/phyllo")));
    assert!(
        installed * 4 < built * 3,
        "installed phyllo is {installed} bytes, the built one {built}: not stripped"
    );

    let home = tmp.path().join("empty-home");
    std::fs::create_dir(&home).unwrap();
    let sample = root.join("docs/samples/402-127-N55-WW-1_2019-05-10_09-18-07.937_Vis_SV_108.jpg");
    let out = Command::new(prefix.join("bin/phyllo"))
        .arg("count")
        .arg(&sample)
        .env_clear()
        .env("HOME", &home)
        .env("PATH", "/usr/bin:/bin")
        .env("PHYLLO_LOG", "debug")
        .current_dir(tmp.path())
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        out.status.success(),
        "the installed phyllo failed: {stdout}{stderr}"
    );
    assert!(stdout.chars().any(|c| c.is_ascii_digit()), "no count: {stdout}");
    let lib = prefix.join("bin/../lib/phyllo/libonnxruntime.so");
    assert!(
        stderr.contains(&format!("ONNX Runtime loaded from {}", lib.display())),
        "not the installed library: {stderr}"
    );
}
