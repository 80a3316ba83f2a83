//! Who owns what phyllo creates.
//!
//! The service runs as its own user; an operator may run `phyllo restore`,
//! `import`, `backup` or `export` as root. A database, lock file, journal
//! entry or snapshot that root creates would be root's, and the service (or
//! its nightly timers) could no longer open or replace it. So every file and
//! folder phyllo creates takes the owner and group of the folder it is
//! created in: under a state directory owned by the service user, everything
//! stays the service user's, whoever ran the command. Run as anyone but
//! root, the owner already matches or cannot be changed, and nothing is done.

use std::os::unix::fs::MetadataExt;
use std::path::Path;

/// Gives `path` (not following a symlink) the owner and group of the folder
/// holding it, where they differ and the process may change them.
pub fn match_parent(path: &Path) {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let (Ok(want), Ok(have)) = (std::fs::metadata(parent), std::fs::symlink_metadata(path)) else {
        return;
    };
    if (have.uid(), have.gid()) != (want.uid(), want.gid()) {
        // Only root may give a file away; anyone else keeps what they made.
        if let Err(e) = std::os::unix::fs::lchown(path, Some(want.uid()), Some(want.gid())) {
            tracing::debug!(path = %path.display(), "ownership left as it is: {e}");
        }
    }
}

/// `std::fs::create_dir_all`, each folder it creates owned as its parent is.
pub fn create_dir_all(dir: &Path) -> std::io::Result<()> {
    let mut missing = Vec::new();
    let mut p = dir;
    while !p.as_os_str().is_empty() && std::fs::symlink_metadata(p).is_err() {
        missing.push(p);
        match p.parent() {
            Some(q) => p = q,
            None => break,
        }
    }
    std::fs::create_dir_all(dir)?;
    for made in missing.iter().rev() {
        match_parent(made);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_folders_and_files_take_their_parents_owner() {
        let dir = tempfile::tempdir().unwrap();
        let deep = dir.path().join("a/b/c");
        create_dir_all(&deep).unwrap();
        let file = deep.join("f");
        std::fs::write(&file, b"x").unwrap();
        match_parent(&file);
        let root = std::fs::metadata(dir.path()).unwrap();
        for p in [dir.path().join("a"), deep.clone(), file] {
            let m = std::fs::metadata(&p).unwrap();
            assert_eq!((m.uid(), m.gid()), (root.uid(), root.gid()), "{}", p.display());
        }
        // Existing folders are left alone, and a second call is a no-op.
        create_dir_all(&deep).unwrap();
    }

    /// As root (CI and this machine run the tests as root), a folder owned by
    /// another user passes its owner on to what is created inside it.
    #[test]
    fn as_root_what_is_created_goes_to_the_folders_owner() {
        let dir = tempfile::tempdir().unwrap();
        let state = dir.path().join("state");
        std::fs::create_dir(&state).unwrap();
        if std::os::unix::fs::chown(&state, Some(65534), Some(65534)).is_err() {
            eprintln!("SKIPPED: not root, so ownership cannot be given away here");
            return;
        }
        create_dir_all(&state.join("imports/entry")).unwrap();
        let file = state.join("imports/entry/x.csv");
        std::fs::write(&file, b"x").unwrap();
        match_parent(&file);
        for p in [state.join("imports"), state.join("imports/entry"), file] {
            let m = std::fs::metadata(&p).unwrap();
            assert_eq!((m.uid(), m.gid()), (65534, 65534), "{}", p.display());
        }
    }
}
