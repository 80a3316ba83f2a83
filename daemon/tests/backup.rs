//! Backup and restore against the real `phyllo` binary, real inotify and a
//! real SQLite file: a snapshot taken while the service counts, one service
//! per database, and a database lost to a damaged disk restored from the
//! snapshot, after which the service counts again every image dropped since
//! and ends where it would have without the loss.
//!
//! Knob: `PHYLLO_FAULT_IMAGES` (30: images before the snapshot; as many
//! again land while it is taken).

mod common;

use std::time::Duration;

use common::*;

/// Unique images of six plants over several days, five side views each.
fn stream(range: std::ops::Range<usize>) -> Vec<(String, Vec<u8>)> {
    image_stream(range, 6, "B", 7_000)
}

/// Per-image counts and whole timelines: what a restore must bring back.
fn state(db: &std::path::Path) -> Vec<String> {
    let mut out = rows(
        db,
        "SELECT i.path, i.state, o.leaf_count FROM images i
         LEFT JOIN observations o ON o.image_id = i.id ORDER BY i.path",
    );
    out.extend(timelines(db));
    out
}

#[test]
fn snapshot_while_counting_then_restore_recovers_every_count() {
    let n: usize = env_or("PHYLLO_FAULT_IMAGES", 30);
    let site = Site::new("workers = 2\nintra_threads = 1\n", "");
    let mut d = site.serve();
    site.wait_running(&mut d);
    for (name, bytes) in stream(0..n) {
        drop_file(&site.drop.join(name), &bytes, false);
    }
    site.wait_for("the first images", Duration::from_secs(60 + n as u64), || {
        site.q("SELECT COUNT(*) FROM images") >= n as i64
    });

    // The snapshot is taken while more images land and are counted.
    let writer = {
        let drop = site.drop.clone();
        std::thread::spawn(move || {
            for (i, (name, bytes)) in stream(n..2 * n).into_iter().enumerate() {
                drop_file(&drop.join(name), &bytes, i % 2 == 0);
                std::thread::sleep(Duration::from_millis(30));
            }
        })
    };
    std::thread::sleep(Duration::from_millis(200));
    let out = site.phyllo(&["backup"]);
    assert!(
        out.status.success(),
        "phyllo backup: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(printed.contains("integrity ok"), "{printed}");
    writer.join().unwrap();
    // A person's correction, imported after the snapshot: in no snapshot,
    // only in the import journal.
    let fix = site.tmp.path().join("fixes.csv");
    std::fs::write(
        &fix,
        "plant,timestamp,view,leaf_count\nB00,2018-04-01,human,9\nB01,2018-04-01,human:ana,8\n",
    )
    .unwrap();
    let out = site.phyllo(&["import", fix.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::remove_file(&fix).unwrap();
    let backups = site.state.join("backups");
    let snaps: Vec<_> = std::fs::read_dir(&backups)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(snaps.len(), 1, "one snapshot, no work files left: {snaps:?}");
    let snap = &snaps[0];
    let in_snapshot = q(snap, "SELECT COUNT(*) FROM images");
    assert!(
        (n as i64..=2 * n as i64).contains(&in_snapshot),
        "the snapshot holds {in_snapshot} images"
    );
    assert_eq!(integrity(snap), "ok");
    // Consistent: every image in the snapshot has its observation with it.
    assert_eq!(q(snap, "SELECT COUNT(*) FROM observations"), in_snapshot);
    assert_eq!(site.status()["backup"]["snapshots"], 1);
    // What a monitor sees: all well while the service runs with a fresh
    // snapshot and export (the nightly export, taken while images land).
    let check = site.phyllo(&["status", "--check"]);
    assert!(String::from_utf8_lossy(&check.stdout).contains("no nightly export yet"));
    assert!(site.phyllo(&["export"]).status.success());
    let check = site.phyllo(&["status", "--check"]);
    let line = String::from_utf8_lossy(&check.stdout).trim().to_string();
    // A test machine short of space (under 1 GB in its temp directory) may
    // add that one warning; nothing else may be wrong.
    let only_low_disk = check.status.code() == Some(1)
        && line.starts_with("phyllo WARNING: ")
        && line.ends_with("free beside the database")
        && !line.contains(';');
    assert!(
        (line == "phyllo OK" && check.status.code() == Some(0)) || only_low_disk,
        "{line}"
    );

    // One service per database, and no restore under a running one.
    let second = site.phyllo(&["serve"]);
    let why = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success(), "a second service started");
    assert!(
        why.contains(&format!("in use by phyllo serve (pid {})", d.pid())),
        "{why}"
    );
    let refused = site.phyllo(&["restore", snap.to_str().unwrap()]);
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("stop it first"),
        "{}",
        String::from_utf8_lossy(&refused.stderr)
    );

    site.wait_for("every image", Duration::from_secs(60 + 2 * n as u64), || {
        site.q("SELECT COUNT(*) FROM observations WHERE image_id IS NOT NULL") >= 2 * n as i64
    });
    assert!(d.term().success());
    let check = site.phyllo(&["status", "--check"]);
    assert_eq!(
        check.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&check.stdout)
    );
    assert!(String::from_utf8_lossy(&check.stdout).starts_with("phyllo CRITICAL: service stopped"));
    let before = state(&site.db);
    assert_eq!(before.iter().filter(|r| r.contains("|counted|")).count(), 2 * n);
    let fused_b00 = "SELECT s.fused FROM sessions s JOIN plants p ON p.id = s.plant_id
                     WHERE p.name = 'B00' AND s.start LIKE '2018-04-01%'";
    assert_eq!(rows(&site.db, fused_b00), ["9.000000"], "the correction holds");

    // The disk garbles the database; the snapshot comes back, and the service
    // counts what landed after it again.
    let mut garbled = std::fs::read(&site.db).unwrap();
    let len = garbled.len();
    garbled[..len / 2].fill(0x5a);
    std::fs::write(&site.db, garbled).unwrap();
    let out = site.phyllo(&["restore", snap.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "phyllo restore: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(
        printed.contains("imported: ") && printed.contains("fixes.csv again (2 counts for 2 plants"),
        "{printed}"
    );
    assert_eq!(rows(&site.db, fused_b00), ["9.000000"], "the correction is back");
    let aside: Vec<String> = std::fs::read_dir(&site.state)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.contains(".before-restore-"))
        .collect();
    assert!(
        aside
            .iter()
            .any(|f| f.starts_with("phyllo.sqlite.before-restore-")),
        "the garbled file is kept: {aside:?}"
    );
    let mut d = site.serve();
    site.wait_running(&mut d);
    site.wait_for(
        "the images after the snapshot",
        Duration::from_secs(60 + 2 * n as u64),
        || site.q("SELECT COUNT(*) FROM observations WHERE image_id IS NOT NULL") >= 2 * n as i64,
    );
    std::thread::sleep(Duration::from_millis(500));
    assert!(d.term().success());
    assert_eq!(integrity(&site.db), "ok");
    assert_eq!(
        site.q("SELECT COUNT(*) FROM images"),
        2 * n as i64,
        "nothing counted twice"
    );
    assert_eq!(state(&site.db), before, "restored and caught up = never lost");
    eprintln!(
        "backup: {in_snapshot} of {} images in the snapshot, the rest counted again after the restore",
        2 * n
    );
}

/// A snapshot that would leave the disk it lands on too little is refused
/// before anything is written, with the directory and the space named.
#[test]
fn a_snapshot_that_would_fill_its_disk_is_refused() {
    let site = Site::new("", "");
    let small = site.tmp.path().join("small");
    std::fs::create_dir_all(&small).unwrap();
    let Some(_unmount) = mount_tmpfs(&small, "64M") else {
        eprintln!("SKIPPED: cannot mount a tmpfs (not root, or no mount in this sandbox)");
        return;
    };
    let mut cfg = std::fs::read_to_string(&site.cfg).unwrap();
    cfg += &format!("[backup]\ndir = {:?}\n", small.join("backups"));
    std::fs::write(&site.cfg, cfg).unwrap();
    let obs = site.tmp.path().join("obs.csv");
    std::fs::write(
        &obs,
        "plant,timestamp,view,leaf_count\nP1,2026-11-01T10:00:00,SV_0,5\n",
    )
    .unwrap();
    assert!(site.phyllo(&["import", obs.to_str().unwrap()]).status.success());

    let out = site.phyllo(&["backup"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains(&small.join("backups").display().to_string()) && err.contains("free"),
        "{err}"
    );
    let left = std::fs::read_dir(small.join("backups")).unwrap().count();
    assert_eq!(left, 0, "nothing written");
}

/// The imports made after a snapshot are taken again by a restore, from the
/// import journal, or left out with `--no-reimport` (to undo a bad one).
#[test]
fn a_restore_takes_the_later_imports_again_unless_told_not_to() {
    let site = Site::new("", "");
    let csv = |name: &str, body: &str| {
        let p = site.tmp.path().join(name);
        std::fs::write(&p, format!("plant,timestamp,view,leaf_count\n{body}")).unwrap();
        p
    };
    let model = csv(
        "model.csv",
        "P1,2026-11-01T10:00:00,SV_0,5\nP1,2026-11-03T10:00:00,SV_0,6\n",
    );
    assert!(site.phyllo(&["import", model.to_str().unwrap()]).status.success());
    let snap = only_snapshot(&site);
    let fix = csv("fix.csv", "P1,2026-11-03,human,8\n");
    let out = site.phyllo(&["import", fix.to_str().unwrap()]);
    let temps = site.tmp.path().join("temps.csv");
    std::fs::write(
        &temps,
        "timestamp,temp_c\n2026-11-01T00:00:00,21\n2026-11-01T01:00:00,22\n",
    )
    .unwrap();
    assert!(site.phyllo(&["import", temps.to_str().unwrap()]).status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("kept as "));
    let emerged = "SELECT leaves_emerged FROM plants WHERE name = 'P1'";
    assert_eq!(rows(&site.db, emerged), ["8.000000"]);

    let out = site.phyllo(&["restore", "--no-reimport", snap.to_str().unwrap()]);
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        printed.contains("left out: ") && printed.contains("fix.csv (imported after the snapshot)"),
        "{printed}"
    );
    assert_eq!(rows(&site.db, emerged), ["6.000000"], "as in the snapshot");

    assert_eq!(site.q("SELECT COUNT(*) FROM climate"), 0);
    let out = site.phyllo(&["restore", snap.to_str().unwrap()]);
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(
        printed.contains("fix.csv again (1 counts for 1 plants"),
        "{printed}"
    );
    assert!(printed.contains("temps.csv again (2 temperatures"), "{printed}");
    assert_eq!(
        site.q("SELECT COUNT(*) FROM climate"),
        2,
        "the temperature log is back too"
    );
    assert!(
        !printed.contains("model.csv"),
        "in the snapshot already: {printed}"
    );
    assert_eq!(rows(&site.db, emerged), ["8.000000"], "the correction is back");
    assert_eq!(
        site.q("SELECT COUNT(*) FROM observations"),
        3,
        "each count once, under its file's name"
    );

    // Undone after all: a later restore does not bring it back.
    assert!(site.phyllo(&["import", "--undo", "fix.csv"]).status.success());
    assert_eq!(rows(&site.db, emerged), ["6.000000"]);
    let out = site.phyllo(&["restore", snap.to_str().unwrap()]);
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(!printed.contains("fix.csv"), "{printed}");
    assert_eq!(
        rows(&site.db, emerged),
        ["6.000000"],
        "the undone import stays undone"
    );
}

/// A later import that no longer fits the config (its zone renamed since)
/// is named by a restore, which still takes the other imports and fails at
/// the end, so the operator fixes it and imports it again.
#[test]
fn a_restore_names_a_later_import_it_cannot_take_and_takes_the_rest() {
    let site = Site::new("[[timeline.zones]]\nname = 'house-2'\nplants = '^P'\n", "");
    let counts = site.tmp.path().join("counts.csv");
    std::fs::write(
        &counts,
        "plant,timestamp,view,leaf_count\nP1,2026-11-01T10:00:00,SV_0,5\nP1,2026-11-03T10:00:00,SV_0,6\n",
    )
    .unwrap();
    let first = site.tmp.path().join("first.csv");
    std::fs::write(
        &first,
        "plant,timestamp,view,leaf_count\nP2,2026-10-30T10:00:00,SV_0,4\n",
    )
    .unwrap();
    assert!(site.phyllo(&["import", first.to_str().unwrap()]).status.success());
    let snap = only_snapshot(&site);
    let temps = site.tmp.path().join("house2.csv");
    std::fs::write(
        &temps,
        "timestamp,temp_c,zone\n2026-11-01T00:00:00,21,house-2\n2026-11-01T01:00:00,22,house-2\n",
    )
    .unwrap();
    for f in [&temps, &counts] {
        let out = site.phyllo(&["import", f.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    // The zone is renamed in the config: the kept log names one it no longer declares.
    let cfg = std::fs::read_to_string(&site.cfg).unwrap();
    std::fs::write(&site.cfg, cfg.replace("name = 'house-2'", "name = 'house-two'")).unwrap();

    let out = site.phyllo(&["restore", snap.to_str().unwrap()]);
    let printed = String::from_utf8_lossy(&out.stdout);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{printed}");
    assert!(
        printed.contains("house2.csv (")
            && printed.contains("zone 'house-2' is not declared")
            && printed.contains("`phyllo import` it again"),
        "{printed}"
    );
    assert!(
        printed.contains("counts.csv again (2 counts for 1 plants"),
        "{printed}"
    );
    assert!(
        err.contains("1 of 2 imports made after the snapshot could not be taken again"),
        "{err}"
    );
    assert_eq!(site.q("SELECT COUNT(*) FROM observations"), 3);
    assert_eq!(site.q("SELECT COUNT(*) FROM climate"), 0);
}

/// Takes a snapshot with `phyllo backup` and returns it, the only one there.
fn only_snapshot(site: &Site) -> std::path::PathBuf {
    let out = site.phyllo(&["backup"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::read_dir(site.state.join("backups"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path()
}
