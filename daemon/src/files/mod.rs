//! Helpers about files that every layer may use: how a file's content and
//! time are written down, writing a file whole (`atomic`), free space
//! (`disk`), which file a path names (`identity`), who owns what phyllo
//! creates (`owner`) and CSV cells a spreadsheet would run as formulas
//! (`csv_cell`). They know nothing of
//! images, plants or the database, so the pipeline, the operator commands
//! and the sinks share them without importing each other.

pub mod atomic;
pub mod csv_cell;
pub mod disk;
pub mod identity;
pub mod owner;

use sha2::{Digest, Sha256};

/// Formats a file's mtime as stored in the database.
pub fn mtime_string(meta: &std::fs::Metadata) -> String {
    match meta.modified() {
        Ok(t) => chrono::DateTime::<chrono::Utc>::from(t)
            .format("%Y-%m-%dT%H:%M:%S%.9fZ")
            .to_string(),
        Err(_) => String::new(),
    }
}

/// Whether an error says the path is longer than the system allows
/// (`ENAMETOOLONG`: 4096 bytes on Linux). Such a file or folder cannot be
/// read by its path; it is recorded as failed, named, rather than left out.
pub fn too_long(e: &std::io::Error) -> bool {
    e.raw_os_error() == Some(libc::ENAMETOOLONG)
}

/// Whether the file can be opened for reading now.
pub fn readable(path: &std::path::Path) -> bool {
    std::fs::File::open(path).is_ok()
}

/// Hex SHA-256.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}
