//! `phyllo import`: a person's corrections and taking an import back
//! (`--undo`), a folder of sheets (`--dir`), implausible capture times.

use crate::common::{ok, phyllo, q};
use crate::{site_config, temperature_log};

/// A person's count imported for a day (a bare date, as people write it)
/// joins that day's imaging session and overrides the model's views there
/// (view `human`, optionally `human:NAME`); re-importing the correction file
/// replaces it rather than adding a second one.
#[test]
fn a_persons_correction_overrides_the_views() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg, _) = site_config(d, "");
    let cfg = cfg.as_str();
    let mut obs = String::from("plant,timestamp,view,leaf_count\n");
    for (day, c) in [6, 7, 8, 8, 9].iter().enumerate() {
        for a in [0, 36, 72, 108, 144] {
            obs += &format!("P1,2026-11-{:02}T10:00:{:02},SV_{a},{c}\n", day + 1, a / 36);
        }
    }
    std::fs::write(d.join("model.csv"), obs).unwrap();
    ok(&["import", "-c", cfg, d.join("model.csv").to_str().unwrap()]);
    let fix = d.join("fix.csv");
    std::fs::write(
        &fix,
        "plant,timestamp,view,leaf_count\nP1,2026-11-03,human:ana,7\n",
    )
    .unwrap();
    ok(&["import", "-c", cfg, fix.to_str().unwrap()]);
    ok(&["import", "-c", cfg, fix.to_str().unwrap()]);
    let t: serde_json::Value = serde_json::from_str(&ok(&["timeline", "-c", cfg, "P1", "--json"])).unwrap();
    let day3 = &t["sessions"][2];
    assert_eq!(day3["views"]["human:ana"], 7.0, "{day3}");
    assert_eq!(
        day3["views"].as_object().unwrap().len(),
        6,
        "one correction: {day3}"
    );
    assert_eq!(day3["fused"], 7.0, "{day3}");
    let fused: Vec<f64> = t["sessions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["fused"].as_f64().unwrap())
        .collect();
    assert_eq!(fused, [6.0, 7.0, 7.0, 8.0, 9.0]);

    // Imported by mistake: taken back, the model's views decide again.
    let out = ok(&["import", "-c", cfg, "--undo", "fix.csv"]);
    assert!(
        out.starts_with("took back 1 counts and 0 temperatures imported from fix.csv; 1 plants refitted; 2 journal entries set aside"),
        "{out}"
    );
    let t: serde_json::Value = serde_json::from_str(&ok(&["timeline", "-c", cfg, "P1", "--json"])).unwrap();
    assert_eq!(t["sessions"][2]["fused"], 8.0, "{}", t["sessions"][2]);
    assert!(t["sessions"][2]["views"].get("human:ana").is_none());
    // A mistyped plant id is named, and taken back like any import.
    let typo = d.join("typo.csv");
    std::fs::write(
        &typo,
        "plant,timestamp,view,leaf_count\nP1,2026-11-04,human,8\nPl,2026-11-05,human,9\n",
    )
    .unwrap();
    let out = phyllo(&["import", "-c", cfg, typo.to_str().unwrap()]);
    let note = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success()
            && note.contains("note: 1 plants new to the database: Pl (")
            && note.contains("--undo typo.csv"),
        "{note}"
    );
    ok(&["import", "-c", cfg, "--undo", "typo.csv"]);
    let again = phyllo(&["import", "-c", cfg, "--undo", "fix.csv"]);
    assert!(!again.status.success());
    assert!(
        String::from_utf8_lossy(&again.stderr).contains("nothing was imported from a file named \"fix.csv\"")
    );
}

/// `phyllo import --dir`: a folder's new and changed CSVs, each taken once;
/// one still being written waits, a bad one is named while the others are
/// taken, one undone stays out until it changes, hidden and non-CSV files
/// are left alone.
#[test]
fn import_dir_takes_new_and_changed_files_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg, _) = site_config(d, "[watch]\nstable_secs = 1.0\n[import]\ndir = 'inbox'\n");
    let cfg = cfg.as_str();
    let db = d.join("state/phyllo.sqlite");
    let inbox = d.join("inbox");
    std::fs::create_dir_all(&inbox).unwrap();
    let out = phyllo(&["import", "-c", cfg, "--dir", d.join("nowhere").to_str().unwrap()]);
    assert!(
        !out.status.success() && String::from_utf8_lossy(&out.stderr).contains("nowhere"),
        "{out:?}"
    );
    let log = temperature_log(None, |h| if (6..18).contains(&h) { 28.0 } else { 18.0 });
    std::fs::write(inbox.join("climate.csv"), &log).unwrap();
    std::fs::write(
        inbox.join("sheet.csv"),
        "plant,timestamp,view,leaf_count\nP1,2026-11-01,human,5\nP1,2026-11-05,human,7\n",
    )
    .unwrap();
    std::fs::write(
        inbox.join("bad.csv"),
        "timestamp,temp_c\n2026-11-01T00:00:00,21\n2026-11-01T00:30:00,hot\n",
    )
    .unwrap();
    std::fs::write(inbox.join(".~lock.sheet.csv"), "not a sheet").unwrap();
    std::fs::write(inbox.join("notes.txt"), "not a sheet").unwrap();

    let run = || {
        let out = phyllo(&["import", "-c", cfg, "--dir"]);
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    let (ok_now, printed) = run();
    assert!(
        ok_now && printed.contains("waiting:  ") && printed.contains("0 files imported"),
        "{printed}"
    );
    std::thread::sleep(std::time::Duration::from_millis(1100));
    let (ok_now, printed) = run();
    assert!(!ok_now, "bad.csv is refused: {printed}");
    assert!(
        printed.contains("bad.csv: ") && printed.contains("bad.csv:3: temp_c 'hot' is not a number"),
        "{printed}"
    );
    assert!(printed.contains("2 files imported, 1 refused"), "{printed}");
    assert_eq!(q(&db, "SELECT COUNT(*) FROM climate"), 1152);
    assert_eq!(q(&db, "SELECT COUNT(*) FROM observations"), 2);

    std::fs::remove_file(inbox.join("bad.csv")).unwrap();
    let (ok_now, printed) = run();
    assert!(
        ok_now && printed.contains("0 files imported, 0 refused"),
        "unchanged: {printed}"
    );
    // The climate computer rewrites its log with the next hour in it.
    std::fs::write(
        inbox.join("climate.csv"),
        format!("{log}2026-11-23T00:00:00,20\n2026-11-23T00:30:00,20\n"),
    )
    .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1100));
    let (ok_now, printed) = run();
    assert!(ok_now && printed.contains("1 files imported"), "{printed}");
    assert_eq!(q(&db, "SELECT COUNT(*) FROM climate"), 1154);
    // The longer log holds all of the shorter: the journal keeps only it.
    let kept: Vec<_> = std::fs::read_dir(d.join("state/imports"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("climate.csv").exists())
        .collect();
    assert_eq!(kept.len(), 1, "{kept:?}");
    assert!(std::fs::read_to_string(kept[0].join("climate.csv"))
        .unwrap()
        .ends_with("2026-11-23T00:30:00,20\n"));
    // Taken back: it stays out of later runs until it changes.
    ok(&["import", "-c", cfg, "--undo", "sheet.csv"]);
    let (ok_now, printed) = run();
    assert!(
        ok_now && printed.contains("undone:   ") && printed.contains("sheet.csv"),
        "{printed}"
    );
    assert_eq!(q(&db, "SELECT COUNT(*) FROM observations"), 0);
}

/// Issue 57, item 5: an imported row dated decades away is refused as a file
/// name with that date would be, naming the sheet and the plant, before
/// anything is stored.
#[test]
fn imported_capture_times_outside_the_plausible_window_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg, _) = site_config(d, "");
    for (when, says) in [
        ("2091-04-20T10:00:00", "ahead of this computer's clock"),
        ("1919-04-20", "earliest"),
    ] {
        let obs = d.join("obs.csv");
        let sheet =
            format!("plant,timestamp,view,leaf_count\nP1,2018-04-20T10:00:00,SV_0,5\nP1,{when},SV_0,6\n");
        std::fs::write(&obs, sheet).unwrap();
        let out = phyllo(&["import", "-c", &cfg, obs.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "accepted {when}");
        assert!(
            err.contains("obs.csv, plant P1") && err.contains(says),
            "{when}: {err}"
        );
    }
    assert!(
        !d.join("state/phyllo.sqlite").exists(),
        "a refused sheet is refused before the database is touched"
    );
}
