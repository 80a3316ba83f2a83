//! Provisions ONNX Runtime's shared library at build time, so that `cargo run`
//! and `cargo test` work on a fresh machine with no extra step.
//!
//! ONNX Runtime cannot be downloaded from its release host here, but PyPI's
//! `onnxruntime` wheel ships the same `libonnxruntime.so`. This script asks
//! pip (so the machine's index configuration applies) for that wheel, extracts
//! only the shared library into a per-user cache, and bakes its path into the
//! build as the last fallback of the runtime search (see `src/runtime.rs`).
//! Nothing here is needed at run time: the library can also come from the
//! system, from beside the executable, or from an explicit path.

use std::env;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::process::Command;

const ORT_VERSION: &str = "1.31.1";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for var in [
        "PHYLLO_ORT_NO_FETCH",
        "PHYLLO_ORT_CACHE",
        "XDG_CACHE_HOME",
        "HOME",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rustc-env=PHYLLO_ORT_VERSION={ORT_VERSION}");

    if env::var_os("PHYLLO_ORT_NO_FETCH").is_some()
        || env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("linux")
    {
        println!("cargo:rustc-env=PHYLLO_ORT_BUILD_LIB=");
        return;
    }
    match provision() {
        Ok(lib) => {
            println!("cargo:rerun-if-changed={}", lib.display());
            println!("cargo:rustc-env=PHYLLO_ORT_BUILD_LIB={}", lib.display());
        }
        Err(err) => {
            println!(
                "cargo:warning=could not provision ONNX Runtime {ORT_VERSION} from PyPI ({err}); \
                 phyllo will look for it at run time (PHYLLO_ORT_LIB, beside the binary, system paths)"
            );
            println!("cargo:rustc-env=PHYLLO_ORT_BUILD_LIB=");
        }
    }
}

fn cache_dir() -> Option<PathBuf> {
    if let Some(dir) = env::var_os("PHYLLO_ORT_CACHE") {
        return Some(PathBuf::from(dir));
    }
    let base = env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("phyllo").join(format!("onnxruntime-{ORT_VERSION}")))
}

fn provision() -> Result<PathBuf, String> {
    let lib_name = format!("libonnxruntime.so.{ORT_VERSION}");
    let out_dir = PathBuf::from(env::var("OUT_DIR").map_err(|e| e.to_string())?);
    let dir = cache_dir().unwrap_or_else(|| out_dir.join("onnxruntime"));
    let lib = dir.join(&lib_name);
    if lib.is_file() {
        return Ok(lib);
    }
    fs::create_dir_all(&dir).map_err(|e| format!("create {}: {e}", dir.display()))?;
    let wheel_dir = out_dir.join("onnxruntime-wheel");
    fs::create_dir_all(&wheel_dir).map_err(|e| format!("create {}: {e}", wheel_dir.display()))?;
    let wheel = match find_wheel(&wheel_dir) {
        Some(w) => w,
        None => {
            download_wheel(&wheel_dir)?;
            find_wheel(&wheel_dir).ok_or("pip reported success but left no onnxruntime wheel")?
        }
    };
    extract_library(&wheel, &lib_name, &lib)?;
    Ok(lib)
}

fn find_wheel(dir: &Path) -> Option<PathBuf> {
    fs::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(&format!("onnxruntime-{ORT_VERSION}-")) && n.ends_with(".whl"))
        })
}

fn download_wheel(dir: &Path) -> Result<(), String> {
    let spec = format!("onnxruntime=={ORT_VERSION}");
    let mut last_err = String::from("no python interpreter found");
    for python in ["python3", "python"] {
        let status = Command::new(python)
            .args([
                "-m",
                "pip",
                "download",
                "--no-deps",
                "--only-binary=:all:",
                "--disable-pip-version-check",
            ])
            .arg("--dest")
            .arg(dir)
            .arg(&spec)
            .status();
        match status {
            Ok(s) if s.success() => return Ok(()),
            Ok(s) => last_err = format!("`{python} -m pip download {spec}` exited with {s}"),
            Err(e) => last_err = format!("cannot run {python}: {e}"),
        }
    }
    Err(last_err)
}

fn extract_library(wheel: &Path, lib_name: &str, dest: &Path) -> Result<(), String> {
    let file = fs::File::open(wheel).map_err(|e| format!("open {}: {e}", wheel.display()))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| format!("read {}: {e}", wheel.display()))?;
    let member = format!("onnxruntime/capi/{lib_name}");
    let mut entry = archive
        .by_name(&member)
        .map_err(|e| format!("{} has no {member}: {e}", wheel.display()))?;
    // Extract beside the destination and rename, so a concurrent or interrupted
    // build never leaves a truncated library behind.
    let tmp = dest.with_extension(format!("partial.{}", std::process::id()));
    let mut out = fs::File::create(&tmp).map_err(|e| format!("create {}: {e}", tmp.display()))?;
    io::copy(&mut entry, &mut out).map_err(|e| format!("extract {member}: {e}"))?;
    out.sync_all()
        .map_err(|e| format!("sync {}: {e}", tmp.display()))?;
    fs::rename(&tmp, dest).map_err(|e| format!("rename into {}: {e}", dest.display()))?;
    Ok(())
}
