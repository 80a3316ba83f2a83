//! Finding and loading the ONNX Runtime shared library.
//!
//! phyllo links ONNX Runtime dynamically so that one binary works with the
//! library from PyPI's wheel, a distribution package or a vendor build. The
//! library is searched in this order, first hit wins:
//!
//! 1. an explicit path (`--ort-lib`, the config key `ort_lib` under `[inference]`);
//! 2. the environment variable `PHYLLO_ORT_LIB` (then ort's own `ORT_DYLIB_PATH`);
//! 3. beside the executable, and in `../lib/phyllo/` relative to it (a packaged install);
//! 4. system locations: `/usr/lib/phyllo`, `/usr/local/lib`, the target's
//!    multiarch folder (`/usr/lib/x86_64-linux-gnu`, `/usr/lib/aarch64-linux-gnu`), `/usr/lib`;
//! 5. the copy provisioned at build time from PyPI (see `build.rs`).

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use crate::error::InferenceError;

/// Debian's multiarch library folder for the architecture this was built for.
const MULTIARCH_LIB_DIR: &str = if cfg!(target_arch = "aarch64") {
    "/usr/lib/aarch64-linux-gnu"
} else {
    "/usr/lib/x86_64-linux-gnu"
};

/// ONNX Runtime version this build expects (major.minor.patch).
pub const ORT_VERSION: &str = env!("PHYLLO_ORT_VERSION");

/// Environment variable naming the library explicitly.
pub const ORT_LIB_ENV: &str = "PHYLLO_ORT_LIB";

struct Loaded {
    path: PathBuf,
    env: ort::environment::Environment,
}

static RUNTIME: OnceLock<Loaded> = OnceLock::new();
static INIT_LOCK: Mutex<()> = Mutex::new(());

/// Candidate library paths in search order, given an explicit choice.
pub fn candidates(explicit: Option<&Path>) -> Vec<PathBuf> {
    if let Some(p) = explicit {
        return vec![p.to_path_buf()];
    }
    for var in [ORT_LIB_ENV, "ORT_DYLIB_PATH"] {
        if let Some(p) = std::env::var_os(var).filter(|v| !v.is_empty()) {
            return vec![PathBuf::from(p)];
        }
    }
    let names = [
        "libonnxruntime.so".to_string(),
        format!("libonnxruntime.so.{ORT_VERSION}"),
    ];
    let mut dirs = Vec::new();
    if let Some(exe_dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        dirs.push(exe_dir.join("../lib/phyllo"));
        dirs.push(exe_dir);
    }
    for d in ["/usr/lib/phyllo", "/usr/local/lib", MULTIARCH_LIB_DIR, "/usr/lib"] {
        dirs.push(PathBuf::from(d));
    }
    let mut out: Vec<PathBuf> = dirs
        .iter()
        .flat_map(|d| names.iter().map(move |n| d.join(n)))
        .collect();
    let built = env!("PHYLLO_ORT_BUILD_LIB");
    if !built.is_empty() {
        out.push(PathBuf::from(built));
    }
    out
}

/// Chooses the library to load: the explicit path as given, otherwise the
/// first candidate that exists.
pub fn locate(explicit: Option<&Path>) -> Result<PathBuf, InferenceError> {
    let cands = candidates(explicit);
    if explicit.is_some() || cands.len() == 1 {
        return Ok(cands[0].clone());
    }
    cands
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| not_found(&cands))
}

/// The error when no candidate exists: it names every way to point phyllo at the library.
fn not_found(searched: &[PathBuf]) -> InferenceError {
    InferenceError::Runtime(format!(
        "libonnxruntime {ORT_VERSION} not found; give its path with --ort-lib, {ORT_LIB_ENV} or \
         `ort_lib` under `[inference]` in the config (searched: {})",
        searched
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    ))
}

/// Loads ONNX Runtime once per process and returns its environment.
///
/// A second call with another explicit path is refused: ONNX Runtime allows
/// one library and one environment per process.
pub fn environment(
    explicit: Option<&Path>,
) -> Result<&'static ort::environment::Environment, InferenceError> {
    let _guard = INIT_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(loaded) = RUNTIME.get() {
        if let Some(p) = explicit {
            if p != loaded.path {
                return Err(InferenceError::Runtime(format!(
                    "{} requested, but {} is already loaded in this process",
                    p.display(),
                    loaded.path.display()
                )));
            }
        }
        return Ok(&loaded.env);
    }
    let path = locate(explicit)?;
    if !path.exists() {
        return Err(InferenceError::Runtime(format!(
            "{}: no such file",
            path.display()
        )));
    }
    // Both forms: `{:?}` keeps the dlopen reason (missing file, wrong ELF
    // class, ...) that ort's Display drops; Display explains version and
    // symbol problems in words.
    let builder = ort::init_from(&path)
        .map_err(|e| InferenceError::Runtime(format!("cannot load {}: {e} ({e:?})", path.display())))?;
    let env = builder
        .with_name("phyllo")
        .build()
        .map_err(|e| InferenceError::Runtime(format!("cannot start {}: {e}", path.display())))?;
    tracing::debug!("ONNX Runtime loaded from {}", path.display());
    Ok(&RUNTIME.get_or_init(|| Loaded { path, env }).env)
}

/// Path of the library loaded in this process, if any.
pub fn loaded_path() -> Option<&'static Path> {
    RUNTIME.get().map(|l| l.path.as_path())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_not_found_error_names_the_config_key_that_exists() {
        let e = not_found(&[PathBuf::from("/x/libonnxruntime.so")]).to_string();
        for part in [
            "--ort-lib",
            ORT_LIB_ENV,
            "`ort_lib` under `[inference]`",
            "/x/libonnxruntime.so",
        ] {
            assert!(e.contains(part), "{part:?} missing from {e}");
        }
        assert!(!e.contains("`onnxruntime`"), "{e}");
    }
}
