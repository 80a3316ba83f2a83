//! The file system's edges, with the real binary:
//!
//! - operator commands run as root beside a service that runs as its own user
//!   (issue 57 item 1): whatever `import`, `backup` and `restore` create in
//!   the state directory stays the state directory owner's, so the service
//!   and its timers can still open, lock and replace it (needs root, as CI
//!   and this machine run the tests; skipped, and said so, otherwise);
//! - an image at a path longer than the system can open (issue 57 item 10)
//!   is recorded as failed, named, with a clear error.

mod common;

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{ok as phyllo, signal, BIN};

/// The service user's stand-in: `nobody`.
const SERVICE_UID: u32 = 65534;

/// Every file and folder under `dir`, `dir` included.
fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = vec![dir.to_path_buf()];
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(tree(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[test]
fn import_backup_and_restore_as_root_leave_the_state_directory_to_its_owner() {
    let dir = tempfile::tempdir().unwrap();
    let state = dir.path().join("state");
    std::fs::create_dir_all(&state).unwrap();
    std::fs::create_dir_all(dir.path().join("drop")).unwrap();
    if std::os::unix::fs::chown(&state, Some(SERVICE_UID), Some(SERVICE_UID)).is_err() {
        eprintln!("SKIPPED: not root, so nothing can be created as root for another owner");
        return;
    }
    let config = dir.path().join("phyllo.toml");
    std::fs::write(
        &config,
        "drop_dir = \"drop\"\ndatabase = \"state/phyllo.sqlite\"\n",
    )
    .unwrap();
    let sheet = dir.path().join("counts.csv");
    std::fs::write(
        &sheet,
        "plant,timestamp,view,leaf_count\nP1,2026-11-02T09:00:00,SV_108,5\nP1,2026-11-04T09:00:00,SV_108,6\n",
    )
    .unwrap();
    let cfg = config.to_str().unwrap();
    phyllo(&["import", "--config", cfg, sheet.to_str().unwrap()]);
    phyllo(&["backup", "--config", cfg]);
    let snapshot = std::fs::read_dir(state.join("backups"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "sqlite"))
        .expect("a snapshot");
    phyllo(&["restore", "--config", cfg, snapshot.to_str().unwrap()]);
    let others: Vec<String> = tree(&state)
        .into_iter()
        .filter_map(|p| {
            let m = std::fs::symlink_metadata(&p).unwrap();
            ((m.uid(), m.gid()) != (SERVICE_UID, SERVICE_UID))
                .then(|| format!("{} ({}:{})", p.display(), m.uid(), m.gid()))
        })
        .collect();
    assert!(
        others.is_empty(),
        "owned by someone else than the state directory's owner: {others:#?}"
    );
    // The restored database is one the owner may write.
    let db = std::fs::metadata(state.join("phyllo.sqlite")).unwrap();
    assert!(db.mode() & 0o200 != 0, "mode {:o}", db.mode());
}

#[test]
fn an_image_deeper_than_the_system_can_open_is_recorded_as_failed() {
    let dir = tempfile::tempdir().unwrap();
    let drop = dir.path().join("drop");
    std::fs::create_dir_all(&drop).unwrap();
    // 17 folders of 250 bytes: past Linux's 4096-byte limit on a path, made
    // relative to each other as a deep copy would make them.
    let part = "d".repeat(250);
    {
        use rustix::fs::{mkdirat, openat, Mode, OFlags};
        let dir_flags = OFlags::DIRECTORY | OFlags::RDONLY;
        let mut fd = openat(rustix::fs::CWD, &drop, dir_flags, Mode::empty()).unwrap();
        for _ in 0..17 {
            mkdirat(&fd, part.as_str(), Mode::from_raw_mode(0o755)).unwrap();
            fd = openat(&fd, part.as_str(), dir_flags, Mode::empty()).unwrap();
        }
        let image = openat(
            &fd,
            "P9_2019-05-10_09-18-07_Vis_SV_0.png",
            OFlags::WRONLY | OFlags::CREATE,
            Mode::from_raw_mode(0o644),
        )
        .unwrap();
        rustix::io::write(&image, b"png").unwrap();
    }
    let config = dir.path().join("phyllo.toml");
    std::fs::write(
        &config,
        "drop_dir = \"drop\"\ndatabase = \"state/phyllo.sqlite\"\n[watch]\nstable_secs = 0.2\n",
    )
    .unwrap();
    let mut serve = Command::new(BIN)
        .args(["serve", "-c"])
        .arg(&config)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let db = dir.path().join("state/phyllo.sqlite");
    let t0 = std::time::Instant::now();
    let failed = loop {
        assert!(
            t0.elapsed().as_secs() < 120,
            "nothing recorded under the deep folders"
        );
        std::thread::sleep(std::time::Duration::from_millis(300));
        let Ok(conn) = rusqlite::Connection::open_with_flags(&db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        else {
            continue;
        };
        let rows: Vec<(String, String)> = conn
            .prepare("SELECT path, COALESCE(error, '') FROM images WHERE state = 'failed'")
            .and_then(|mut st| st.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?.collect())
            .unwrap_or_default();
        if !rows.is_empty() {
            break rows;
        }
    };
    signal(serve.id(), "TERM");
    let _ = serve.wait();
    assert_eq!(failed.len(), 1, "{failed:?}");
    let (path, error) = &failed[0];
    assert!(path.starts_with(&part) && path.len() > 4096, "{}", path.len());
    assert!(
        error.contains("longer than the 4096 the system can open"),
        "{error}"
    );
    // An operator who has seen it acknowledges it (issue 56 item 2).
    let cfg = config.to_str().unwrap();
    assert_eq!(
        phyllo(&["status", "--ack", "-c", cfg]).trim(),
        "acknowledged 1 failure: status and --check no longer count them"
    );
    let out = Command::new(BIN)
        .args(["status", "--check", "-c", cfg])
        .output()
        .unwrap();
    let line = String::from_utf8_lossy(&out.stdout);
    assert!(!line.contains("failed in the last 24 h"), "{line}");
}
