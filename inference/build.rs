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
//!
//! A cross build (an aarch64 target on an x86 machine, say) gets the wheel
//! for the target's architecture, kept in its own cache folder, so an x86
//! library never lands in an ARM build.

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
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let Some(wheel) = WheelTarget::for_arch(&arch) else {
        println!(
            "cargo:warning=PyPI has no onnxruntime {ORT_VERSION} wheel for {arch}; \
             phyllo will look for the library at run time (PHYLLO_ORT_LIB, beside the binary, system paths)"
        );
        println!("cargo:rustc-env=PHYLLO_ORT_BUILD_LIB=");
        return;
    };
    match provision(&wheel) {
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

/// Which wheel to ask pip for: the host's own (pip's default), or another
/// architecture's for a cross build.
struct WheelTarget {
    /// `--platform` for pip, `None` when the target is the host.
    platform: Option<&'static str>,
    /// Appended to the cache folder's name; empty for the host's library, so
    /// caches from before cross builds stay valid.
    suffix: String,
    /// Part of the wheel's file name that names the architecture.
    arch_tag: &'static str,
}

impl WheelTarget {
    fn for_arch(arch: &str) -> Option<WheelTarget> {
        let arch_tag = match arch {
            "x86_64" => "x86_64",
            "aarch64" => "aarch64",
            _ => return None,
        };
        if arch == env::consts::ARCH {
            return Some(WheelTarget {
                platform: None,
                suffix: String::new(),
                arch_tag,
            });
        }
        // The wheels of this version are tagged manylinux_2_27/2_28; pip
        // accepts an older glibc tag for a newer --platform.
        let platform = match arch {
            "x86_64" => "manylinux_2_28_x86_64",
            _ => "manylinux_2_28_aarch64",
        };
        Some(WheelTarget {
            platform: Some(platform),
            suffix: format!("-{arch}"),
            arch_tag,
        })
    }
}

fn cache_dir(wheel: &WheelTarget) -> Option<PathBuf> {
    if let Some(dir) = env::var_os("PHYLLO_ORT_CACHE") {
        return Some(PathBuf::from(dir).join(wheel.suffix.trim_start_matches('-')));
    }
    let base = env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(
        base.join("phyllo")
            .join(format!("onnxruntime-{ORT_VERSION}{}", wheel.suffix)),
    )
}

fn provision(wheel_target: &WheelTarget) -> Result<PathBuf, String> {
    let lib_name = format!("libonnxruntime.so.{ORT_VERSION}");
    let out_dir = PathBuf::from(env::var("OUT_DIR").map_err(|e| e.to_string())?);
    let dir = cache_dir(wheel_target).unwrap_or_else(|| out_dir.join("onnxruntime"));
    let lib = dir.join(&lib_name);
    if lib.is_file() {
        return Ok(lib);
    }
    fs::create_dir_all(&dir).map_err(|e| format!("create {}: {e}", dir.display()))?;
    let wheel_dir = out_dir.join("onnxruntime-wheel");
    fs::create_dir_all(&wheel_dir).map_err(|e| format!("create {}: {e}", wheel_dir.display()))?;
    let wheel = match find_wheel(&wheel_dir, wheel_target.arch_tag) {
        Some(w) => w,
        None => {
            download_wheel(&wheel_dir, wheel_target.platform)?;
            find_wheel(&wheel_dir, wheel_target.arch_tag)
                .ok_or("pip reported success but left no onnxruntime wheel")?
        }
    };
    extract_library(&wheel, &lib_name, &lib)?;
    Ok(lib)
}

fn find_wheel(dir: &Path, arch_tag: &str) -> Option<PathBuf> {
    fs::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                n.starts_with(&format!("onnxruntime-{ORT_VERSION}-"))
                    && n.contains(arch_tag)
                    && n.ends_with(".whl")
            })
        })
}

fn download_wheel(dir: &Path, platform: Option<&str>) -> Result<(), String> {
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
            .args(platform_args(platform))
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

/// pip's arguments for another architecture's wheel; the Python version only
/// picks which of the (identical) libraries' wheels is taken.
fn platform_args(platform: Option<&str>) -> Vec<&str> {
    match platform {
        Some(p) => vec!["--platform", p, "--python-version", "3.12"],
        None => Vec::new(),
    }
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
