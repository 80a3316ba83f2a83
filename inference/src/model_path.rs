//! Where model files are found when the configuration names none: the
//! environment, a packaged install, then this source tree.
//!
//! Both [`crate::counter`] (the side-view model) and [`crate::top_view`] (the
//! top-view model) look here; neither imports the other for it.

use std::path::{Path, PathBuf};

/// Environment variable naming the default model file.
pub const MODEL_ENV: &str = "PHYLLO_MODEL";

/// Environment variable naming the default top-view model file.
pub const TOP_MODEL_ENV: &str = "PHYLLO_TOP_MODEL";

/// File name of the shipped top-view model, beside the side-view model.
pub const TOP_MODEL_FILE: &str = "phyllo-top.onnx";

/// The default model: `$PHYLLO_MODEL`, then `../share/phyllo/phyllo.onnx`
/// beside the executable (a packaged install), then the model shipped in this
/// source tree (`models/phyllo.onnx`, else `models/phyllo-untrained.onnx`).
pub fn default_model_path() -> PathBuf {
    if let Some(p) = path_from_env(MODEL_ENV) {
        return p;
    }
    let mut candidates = shipped_model_candidates("phyllo.onnx");
    candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/phyllo-untrained.onnx"));
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .unwrap_or_else(|| candidates[0].clone())
}

/// The default top-view model: `$PHYLLO_TOP_MODEL`, then
/// `../share/phyllo/phyllo-top.onnx` beside the executable, then
/// `models/phyllo-top.onnx` in this source tree; `None` when none exists
/// (the side-view model then counts top views too).
pub fn default_top_model_path() -> Option<PathBuf> {
    path_from_env(TOP_MODEL_ENV).or_else(|| {
        shipped_model_candidates(TOP_MODEL_FILE)
            .into_iter()
            .find(|p| p.is_file())
    })
}

/// Whether `$PHYLLO_MODEL` names the side-view model: a model chosen by hand
/// counts every view unless a top-view model is named too.
pub fn side_model_from_env() -> bool {
    path_from_env(MODEL_ENV).is_some()
}

/// The path an environment variable names, unless it is unset or empty.
fn path_from_env(var: &str) -> Option<PathBuf> {
    std::env::var_os(var).filter(|v| !v.is_empty()).map(PathBuf::from)
}

/// Where a shipped model file `file` may lie, in the order searched:
/// `../share/phyllo/` beside the executable (a packaged install), then
/// `models/` in this source tree.
fn shipped_model_candidates(file: &str) -> Vec<PathBuf> {
    let mut candidates = Vec::new();
    if let Some(exe_dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        candidates.push(exe_dir.join("../share/phyllo").join(file));
    }
    candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../models").join(file));
    candidates
}
