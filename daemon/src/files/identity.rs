//! Which file a path names: where it leads once symlinks are followed
//! ([`resolved`]), and its device and inode ([`DatabaseIdentity`]). Two
//! spellings of one file (a symlink, `..`) must count as one: a lock or a
//! "same folder" check that compared the strings could be walked around.

use std::os::unix::fs::MetadataExt;
use std::path::{Component, Path, PathBuf};

/// Which file the database is: its path, device and inode when opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatabaseIdentity {
    path: PathBuf,
    dev: u64,
    ino: u64,
}

impl DatabaseIdentity {
    /// The identity of the database file at `path` now.
    pub fn of(path: &Path) -> anyhow::Result<DatabaseIdentity> {
        let m = std::fs::metadata(path).map_err(|e| anyhow::anyhow!("database {}: {e}", path.display()))?;
        Ok(DatabaseIdentity {
            path: path.to_path_buf(),
            dev: m.dev(),
            ino: m.ino(),
        })
    }

    /// `dev:ino`, as the service reports it for `phyllo status`.
    pub fn text(&self) -> String {
        format!("{}:{}", self.dev, self.ino)
    }

    /// Why the file at the path is no longer this database, if it is not.
    pub fn changed(&self) -> Option<String> {
        match std::fs::metadata(&self.path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Some(format!(
                "database {} was deleted while the service ran",
                self.path.display()
            )),
            Err(e) => Some(format!("database {}: {e}", self.path.display())),
            Ok(m) if (m.dev(), m.ino()) != (self.dev, self.ino) => Some(format!(
                "database {} was deleted or replaced by another file while the service ran",
                self.path.display()
            )),
            Ok(_) => None,
        }
    }
}

/// Where `path` leads: its longest existing ancestor with symlinks resolved,
/// then the rest as written (`.` and `..` taken out), so a file that does not
/// exist yet still compares by where it will be.
pub fn resolved(path: &Path) -> PathBuf {
    let parts: Vec<Component> = path.components().collect();
    for i in (0..=parts.len()).rev() {
        let head: PathBuf = parts[..i].iter().collect();
        let probe = if head.as_os_str().is_empty() {
            Path::new(".")
        } else {
            &head
        };
        if let Ok(real) = probe.canonicalize() {
            return parts[i..].iter().fold(real, |mut out, part| {
                match part {
                    Component::ParentDir => {
                        out.pop();
                    }
                    Component::CurDir => {}
                    other => out.push(other),
                }
                out
            });
        }
    }
    path.to_path_buf()
}
