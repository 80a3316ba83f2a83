//! Helpers shared by phyllo's end-to-end tests: paths to the built binaries,
//! the shipped model and the shared development data.

use std::path::PathBuf;

/// Root of the repository.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).parent().expect("tests/ has a parent").to_path_buf()
}
