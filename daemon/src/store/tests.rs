//! Store tests on real SQLite files.

use std::path::PathBuf;

use chrono::{Duration, NaiveDate};

use super::*;
use crate::config::TimelineConfig;
use crate::domain::names::{ParsedName, View};
use crate::files::sha256_hex;

fn open(dir: &tempfile::TempDir) -> Store {
    Store::open(&db(dir), &TimelineParams::default(), 3).unwrap()
}

fn db(dir: &tempfile::TempDir) -> PathBuf {
    dir.path().join("state/phyllo.sqlite")
}

fn day(i: i64) -> NaiveDateTime {
    NaiveDate::from_ymd_opt(2018, 4, 20)
        .unwrap()
        .and_hms_opt(10, 0, 0)
        .unwrap()
        + Duration::days(i)
}

fn name(plant: &str, t: NaiveDateTime, view: View) -> ParsedName {
    ParsedName {
        plant: plant.into(),
        taken_at: t,
        view,
        pattern: "flat".into(),
    }
}

fn facts(rel: &str, content: &str) -> FileFacts {
    FileFacts {
        rel: rel.into(),
        size: content.len() as u64,
        mtime: Some(format!("mtime-of-{content}")),
        sha256: sha256_hex(content.as_bytes()),
    }
}

fn count(n: u32) -> CountRecord {
    CountRecord {
        leaf_count: n,
        instances: serde_json::json!([{"id": 1, "class": 1, "area": 100}]),
        timing: serde_json::json!({"total": 12.5}),
        ms_total: 12.5,
        model_id: "test-model".into(),
        settings: serde_json::json!({"postprocess": {"split_min_area": 128}}),
    }
}

fn n_obs(s: &Store) -> i64 {
    s.conn()
        .query_row("SELECT COUNT(*) FROM observations", [], |r| r.get(0))
        .unwrap()
}

#[test]
fn counted_image_lands_with_timeline_and_feed() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let f = facts("P1_a.png", "a");
    assert_eq!(s.precheck(&f, None).unwrap(), Precheck::Process);
    let r = s
        .record(
            &f,
            Outcome::Counted(&name("P1", day(0), View::Side(0)), &count(8)),
        )
        .unwrap();
    assert_eq!(
        r,
        Recorded::Counted {
            fused: 8.0,
            emerged: 8.0,
            new_leaves: vec![]
        }
    );
    let f2 = facts("P1_b.png", "b");
    let r = s
        .record(
            &f2,
            Outcome::Counted(&name("P1", day(1), View::Side(0)), &count(10)),
        )
        .unwrap();
    assert_eq!(
        r,
        Recorded::Counted {
            fused: 10.0,
            emerged: 10.0,
            new_leaves: vec![9, 10]
        }
    );
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert_eq!(t.sessions.len(), 2);
    assert_eq!(t.events.len(), 2);
    let feed = s.feed_after(0, None, 100).unwrap();
    let kinds: Vec<&str> = feed.iter().map(|r| r.kind.as_str()).collect();
    assert_eq!(kinds, vec!["count", "event", "event", "count"]);
    assert_eq!(feed[3].new_leaves, vec![9, 10]);
    assert_eq!(s.feed_after(0, Some("P2"), 100).unwrap().len(), 0);
    assert_eq!(s.image_counts().unwrap().counted, 2);
}

#[test]
fn pruning_the_feed_keeps_recent_entries_and_every_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    for (i, c) in ["a", "b", "c"].iter().enumerate() {
        let f = facts(&format!("P1_{c}.png"), c);
        s.record(
            &f,
            Outcome::Counted(&name("P1", day(i as i64), View::Side(0)), &count(8 + i as u32)),
        )
        .unwrap();
    }
    // Age the first two entries as if they were written in 2020.
    s.conn()
        .execute(
            "UPDATE feed SET at = '2020-01-01T00:00:00.000Z' WHERE seq IN (SELECT seq FROM feed ORDER BY seq LIMIT 2)",
            [],
        )
        .unwrap();
    let before = s.feed_after(0, None, 100).unwrap();
    assert_eq!(s.prune_feed(std::time::Duration::from_secs(86_400)).unwrap(), 2);
    let after = s.feed_after(0, None, 100).unwrap();
    assert_eq!(after.len(), before.len() - 2);
    assert_eq!(after[0].seq, before[2].seq, "the newest entries stay, in order");
    // `phyllo tail` resumes from its last position past the gap.
    assert_eq!(s.feed_after(before[0].seq, None, 100).unwrap().len(), after.len());
    assert_eq!(s.feed_head().unwrap(), before.last().unwrap().seq);
    // Counts and the timeline are untouched.
    assert_eq!(n_obs(&s), 3);
    assert_eq!(s.plant_timeline("P1").unwrap().unwrap().sessions.len(), 3);
    assert_eq!(s.prune_feed(std::time::Duration::from_secs(86_400)).unwrap(), 0);
}

#[test]
fn same_content_is_never_counted_twice() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let f = facts("P1_a.png", "a");
    s.record(
        &f,
        Outcome::Counted(&name("P1", day(0), View::Side(0)), &count(8)),
    )
    .unwrap();
    // Same path, same content (touched, or rescanned after a restart).
    assert!(matches!(s.precheck(&f, None).unwrap(), Precheck::Skip(_)));
    assert!(s.is_known("P1_a.png", 1, "mtime-of-a", || true).unwrap());
    // Same content copied elsewhere: recorded as a duplicate, not counted.
    let copy = facts("copy/P1_a.png", "a");
    assert!(matches!(s.precheck(&copy, None).unwrap(), Precheck::Skip(why) if why.contains("same content")));
    // Even if two workers raced past the precheck, the write re-checks.
    let copy2 = facts("copy2/P1_a.png", "a");
    let r = s
        .record(
            &copy2,
            Outcome::Counted(&name("P1", day(0), View::Side(0)), &count(8)),
        )
        .unwrap();
    assert_eq!(r, Recorded::Duplicate("P1_a.png".into()));
    assert_eq!(n_obs(&s), 1);
    let c = s.image_counts().unwrap();
    assert_eq!((c.counted, c.duplicate), (1, 2));
    // Across a restart too.
    drop(s);
    let mut s = open(&dir);
    assert!(matches!(s.precheck(&f, None).unwrap(), Precheck::Skip(_)));
    assert_eq!(n_obs(&s), 1);
}

#[test]
fn a_reverted_file_is_counted_again_and_its_plant_keeps_its_session() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let n = name("P1", day(0), View::Side(0));
    let (a, b) = (facts("P1_a.png", "A"), facts("P1_a.png", "B"));
    s.record(&a, Outcome::Counted(&n, &count(8))).unwrap();
    assert_eq!(s.precheck(&b, Some(&n)).unwrap(), Precheck::Process);
    s.record(&b, Outcome::Counted(&n, &count(9))).unwrap();
    // A again at the same path: not a duplicate of the version it replaced.
    let Precheck::Reuse {
        count: again,
        original,
    } = s.precheck(&a, Some(&n)).unwrap()
    else {
        panic!("a reverted file must be counted again");
    };
    assert_eq!((again.leaf_count, original.as_str()), (8, "P1_a.png"));
    assert!(matches!(
        s.record(&a, Outcome::Counted(&n, &again)).unwrap(),
        Recorded::Counted { .. }
    ));
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert_eq!((t.sessions.len(), t.sessions[0].fused), (1, 8.0));
}

#[test]
fn the_same_bytes_under_another_plant_are_an_observation_of_their_own() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let na = name("RA-1", day(0), View::Side(0));
    s.record(&facts("RA-1_x.png", "A"), Outcome::Counted(&na, &count(8)))
        .unwrap();
    // Renamed (or copied) to another plant's name: that plant must exist, with the count.
    let nb = name("RB-1", day(0), View::Side(0));
    let b = facts("RB-1_x.png", "A");
    let Precheck::Reuse {
        count: reused,
        original,
    } = s.precheck(&b, Some(&nb)).unwrap()
    else {
        panic!("another plant's image is not a duplicate");
    };
    assert_eq!(original, "RA-1_x.png");
    assert_eq!(s.images_sharing_bytes().unwrap(), 0);
    s.record(&b, Outcome::Counted(&nb, &reused)).unwrap();
    assert_eq!(s.images_sharing_bytes().unwrap(), 1);
    for plant in ["RA-1", "RB-1"] {
        let t = s.plant_timeline(plant).unwrap().unwrap();
        assert_eq!(t.sessions[0].fused, 8.0, "{plant}");
    }
    // Moved into a folder under the same name: the same image, a duplicate.
    let moved = facts("moved/RA-1_x.png", "A");
    assert!(
        matches!(s.precheck(&moved, Some(&na)).unwrap(), Precheck::Skip(why) if why.contains("same content"))
    );
    assert_eq!(n_obs(&s), 2);
}

#[test]
fn changed_file_is_a_new_version_and_replaces_the_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let n0 = name("P1", day(0), View::Side(0));
    s.record(&facts("P1_a.png", "v1"), Outcome::Counted(&n0, &count(8)))
        .unwrap();
    s.record(
        &facts("P1_b.png", "b"),
        Outcome::Counted(&name("P1", day(1), View::Side(0)), &count(9)),
    )
    .unwrap();
    let v2 = facts("P1_a.png", "v2");
    assert_eq!(s.precheck(&v2, None).unwrap(), Precheck::Process);
    s.record(&v2, Outcome::Counted(&n0, &count(6))).unwrap();
    let versions: Vec<(i64, String, i64)> = s
        .conn()
        .prepare("SELECT version, state, superseded FROM images WHERE path = 'P1_a.png' ORDER BY version")
        .unwrap()
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(versions, vec![(1, "counted".into(), 1), (2, "counted".into(), 0)]);
    // Both observations are kept; the timeline uses only the current version.
    assert_eq!(n_obs(&s), 3);
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert_eq!(t.sessions[0].fused, 6.0);
    // A version that turns out undecodable also takes the old count out.
    s.record(
        &facts("P1_b.png", "broken"),
        Outcome::Failed {
            name: None,
            error: "bad".into(),
            retry: false,
        },
    )
    .unwrap();
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert_eq!(t.sessions.len(), 1);
}

#[test]
fn failures_are_recorded_and_retried_only_when_transient() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let bad = facts("holiday.png", "x");
    let err = "file name holiday.png matches none of the patterns tried: flat = /.../".to_string();
    s.record(
        &bad,
        Outcome::Failed {
            name: None,
            error: err.clone(),
            retry: false,
        },
    )
    .unwrap();
    assert!(s.is_known("holiday.png", 1, "mtime-of-x", || true).unwrap());
    assert!(matches!(s.precheck(&bad, None).unwrap(), Precheck::Skip(_)));
    assert_eq!(s.recent_failures(5).unwrap(), vec![("holiday.png".into(), err)]);
    // A runtime failure is retried up to max_attempts (3).
    let f = facts("P1_a.png", "a");
    let n = name("P1", day(0), View::Side(0));
    for attempt in 1..=3 {
        assert_eq!(
            s.precheck(&f, None).unwrap(),
            Precheck::Process,
            "attempt {attempt}"
        );
        s.record(
            &f,
            Outcome::Failed {
                name: Some(&n),
                error: "runtime busy".into(),
                retry: true,
            },
        )
        .unwrap();
    }
    assert!(matches!(s.precheck(&f, None).unwrap(), Precheck::Skip(_)));
    let attempts: i64 = s
        .conn()
        .query_row("SELECT attempts FROM images WHERE path = 'P1_a.png'", [], |r| {
            r.get(0)
        })
        .unwrap();
    assert_eq!(attempts, 3);
    let feed = s.feed_after(0, None, 100).unwrap();
    assert!(feed.iter().all(|r| r.kind == "failed"));
}

/// Issue 56 item 2: a failure made moot by a count of the same bytes under
/// another name leaves the failures once its file is gone; an operator's
/// acknowledgement clears the rest.
#[test]
fn failures_are_superseded_by_a_count_of_their_bytes_or_acknowledged() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let failed = |s: &mut Store, rel: &str, content: &str| {
        let outcome = Outcome::Failed {
            name: None,
            error: format!("{rel}: matches no pattern"),
            retry: false,
        };
        s.record(&facts(rel, content), outcome).unwrap();
    };
    failed(&mut s, "renamed away.png", "a");
    failed(&mut s, "still here.png", "b");
    let n = name("P1", day(0), View::Side(0));
    s.record(&facts("P1_a.png", "a"), Outcome::Counted(&n, &count(5)))
        .unwrap();
    let since = "2000-01-01T00:00:00Z";
    assert_eq!(s.failures_since(since).unwrap(), 2);
    assert_eq!(
        s.supersede_failures("P1_a.png", &sha256_hex(b"a"), &n, |_| false)
            .unwrap(),
        0,
        "its file is still there"
    );
    assert_eq!(
        s.supersede_failures("P1_a.png", &sha256_hex(b"a"), &n, |_| true)
            .unwrap(),
        1
    );
    assert_eq!(s.recent_failures(5).unwrap().len(), 1);
    assert_eq!(s.acknowledge_failures().unwrap(), 1);
    assert_eq!(s.failures_since(since).unwrap(), 0);
    assert!(s.recent_failures(5).unwrap().is_empty());
    assert!(
        s.is_known("still here.png", 1, "mtime-of-b", || true).unwrap(),
        "left alone, not retried"
    );
}

/// Issue 57 item 11: `chmod` changes neither size nor mtime, so a file that
/// failed for its permissions until its attempts ran out is tried again once
/// it can be read, and only then; other spent failures stay done.
#[test]
fn a_file_that_failed_for_its_permissions_is_tried_again_once_readable() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    for (rel, error) in [
        (
            "P1_a.png",
            format!("P1_a.png{PERMISSION_DENIED}: Permission denied (os error 13)"),
        ),
        ("P1_b.png", "runtime busy".to_string()),
    ] {
        let f = facts(rel, "b");
        for _ in 0..3 {
            let outcome = Outcome::Failed {
                name: None,
                error: error.clone(),
                retry: true,
            };
            s.record(&f, outcome).unwrap();
        }
    }
    assert!(
        s.is_known("P1_a.png", 1, "mtime-of-b", || false).unwrap(),
        "still unreadable"
    );
    assert!(
        !s.is_known("P1_a.png", 1, "mtime-of-b", || true).unwrap(),
        "readable now"
    );
    assert!(
        s.is_known("P1_b.png", 1, "mtime-of-b", || true).unwrap(),
        "spent, not for permissions"
    );
}

#[test]
fn a_failure_replaced_by_a_newer_version_is_not_counted_as_failed() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let failed = |error: &str| Outcome::Failed {
        name: None,
        error: error.into(),
        retry: false,
    };
    s.record(&facts("P1_a.png", "truncated"), failed("truncated PNG"))
        .unwrap();
    s.record(&facts("P2_a.png", "corrupt"), failed("corrupt PNG"))
        .unwrap();
    assert_eq!(s.image_counts().unwrap().failed, 2);
    // The station delivers P1's file again, whole: the failure is history.
    let n = name("P1", day(0), View::Side(0));
    s.record(&facts("P1_a.png", "whole"), Outcome::Counted(&n, &count(8)))
        .unwrap();
    let c = s.image_counts().unwrap();
    assert_eq!((c.failed, c.counted), (1, 1));
    assert_eq!(
        s.recent_failures(5).unwrap(),
        vec![("P2_a.png".to_string(), "corrupt PNG".to_string())]
    );
}

#[test]
fn late_and_out_of_order_images_give_the_same_timeline() {
    let counts = [8u32, 8, 10, 10, 11, 11, 12, 13, 14, 12, 14];
    let mut images: Vec<(usize, u16)> = Vec::new();
    for d in 0..counts.len() {
        for a in [0u16, 72, 144] {
            images.push((d, a));
        }
    }
    let run = |order: &[(usize, u16)]| {
        let dir = tempfile::tempdir().unwrap();
        let mut s = open(&dir);
        for &(d, a) in order {
            let c = counts[d] - u32::from(a == 72);
            let t = day(d as i64) + Duration::seconds(a as i64);
            let f = facts(&format!("P1_{d}_{a}.png"), &format!("{d}-{a}"));
            s.record(&f, Outcome::Counted(&name("P1", t, View::Side(a)), &count(c)))
                .unwrap();
        }
        let events: Vec<u32> = s
            .feed_after(0, None, 1000)
            .unwrap()
            .iter()
            .flat_map(|r| r.new_leaves.clone())
            .collect();
        (
            serde_json::to_string(&s.plant_timeline("P1").unwrap().unwrap()).unwrap(),
            events,
        )
    };
    let (in_order, _) = run(&images);
    let mut shuffled = images.clone();
    shuffled.reverse();
    shuffled.swap(0, 17);
    let (out_of_order, _) = run(&shuffled);
    assert_eq!(in_order, out_of_order);
}

#[test]
fn import_is_fused_like_model_counts_and_idempotent() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    s.record(
        &facts("P1_a.png", "a"),
        Outcome::Counted(&name("P1", day(0), View::Side(0)), &count(8)),
    )
    .unwrap();
    let rows = vec![
        (
            "P1".to_string(),
            day(0) + Duration::minutes(1),
            View::parse("human"),
            9,
        ),
        ("P1".to_string(), day(1), View::parse("human"), 11),
        ("P2".to_string(), day(0), View::parse("SV_108"), 5),
    ];
    assert_eq!(s.import("manual.csv", &rows, None).unwrap(), (3, 2));
    assert_eq!(s.import("manual.csv", &rows, None).unwrap(), (3, 2));
    assert_eq!(s.image_counts().unwrap().imported, 3);
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert_eq!(t.sessions.len(), 2);
    assert_eq!(t.sessions[0].fused, 9.0); // a person's 9 overrides the model's 8
    assert_eq!(t.events.len(), 2); // leaves 10, 11
                                   // An imported model-like view is fused like the model's own.
    assert_eq!(s.plant_timeline("P2").unwrap().unwrap().sessions[0].fused, 5.0);
}

#[test]
fn a_leaf_the_refit_no_longer_finds_is_withdrawn_in_the_feed() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let sheet = |counts: [u32; 3]| -> Vec<(String, NaiveDateTime, View, u32)> {
        counts
            .iter()
            .enumerate()
            .map(|(i, &c)| ("P1".to_string(), day(i as i64), View::Side(0), c))
            .collect()
    };
    let feed = |s: &Store, kind: &str| -> Vec<String> {
        s.conn()
            .prepare("SELECT message FROM feed WHERE kind = ?1 ORDER BY seq")
            .unwrap()
            .query_map([kind], |r| r.get(0))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap()
    };
    s.import("a.csv", &sheet([6, 6, 8]), None).unwrap();
    assert_eq!(feed(&s, "event").len(), 2);
    assert!(feed(&s, "withdrawn").is_empty());
    // The sheet corrected: the last day had 6 leaves, so leaves 7 and 8 did not emerge.
    s.import("a.csv", &sheet([6, 6, 6]), None).unwrap();
    let withdrawn = feed(&s, "withdrawn");
    assert_eq!(withdrawn.len(), 2, "{withdrawn:?}");
    assert!(withdrawn[0].starts_with("leaf 7 withdrawn") && withdrawn[1].starts_with("leaf 8 withdrawn"));
}

#[test]
fn a_leaf_read_as_lost_reaches_the_feed_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    // Five side views a day; the plant loses its oldest leaf on day 4.
    let living = [6u32, 7, 7, 8, 7, 7, 7];
    let rows: Vec<(String, NaiveDateTime, View, u32)> = living
        .iter()
        .enumerate()
        .flat_map(|(i, &c)| {
            [0u16, 36, 72, 108, 144].into_iter().map(move |a| {
                (
                    "P1".to_string(),
                    day(i as i64) + Duration::seconds(a as i64),
                    View::Side(a),
                    c,
                )
            })
        })
        .collect();
    s.import("a.csv", &rows, None).unwrap();
    let lost = |s: &Store| -> Vec<(String, String)> {
        s.conn()
            .prepare("SELECT taken_at, message FROM feed WHERE kind = 'lost'")
            .unwrap()
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap()
    };
    let rows_lost = lost(&s);
    assert_eq!(rows_lost.len(), 1, "{rows_lost:?}");
    assert_eq!(rows_lost[0].0, iso(day(4)));
    assert!(rows_lost[0].1.contains("1 lost in all"), "{rows_lost:?}");
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert_eq!(t.sessions.last().unwrap().leaves_lost, 1.0);
    assert_eq!(t.sessions.last().unwrap().leaves_emerged, 8.0);
    // The same counts again: nothing new is lost.
    s.import("a.csv", &rows, None).unwrap();
    assert_eq!(lost(&s).len(), 1);
}

#[test]
fn migrations_are_versioned_and_readers_check_them() {
    let dir = tempfile::tempdir().unwrap();
    drop(open(&dir));
    let ro = Store::open_read_only(&db(&dir)).unwrap();
    let mode: String = ro
        .conn()
        .query_row("PRAGMA journal_mode", [], |r| r.get(0))
        .unwrap();
    assert_eq!(mode, "wal");
    drop(ro);
    drop(open(&dir)); // re-opening does not re-run migrations
    let conn = Connection::open(db(&dir)).unwrap();
    conn.pragma_update(None, "user_version", 99).unwrap();
    drop(conn);
    let err = format!(
        "{:#}",
        Store::open(&db(&dir), &TimelineParams::default(), 3)
            .err()
            .unwrap()
    );
    assert!(err.contains("newer than this phyllo knows"), "{err}");
    let err = format!(
        "{:#}",
        Store::open_read_only(&dir.path().join("none.sqlite"))
            .err()
            .unwrap()
    );
    assert!(err.contains("does not exist"), "{err}");
}

#[test]
fn opening_with_other_timeline_settings_refits_every_plant() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    for (a, c) in [(0u16, 7u32), (108, 9)] {
        let f = facts(&format!("P1_{a}.png"), &a.to_string());
        s.record(
            &f,
            Outcome::Counted(
                &name("P1", day(0) + Duration::seconds(a as i64), View::Side(a)),
                &count(c),
            ),
        )
        .unwrap();
    }
    drop(s);
    let tl = TimelineConfig {
        fusion: "view:SV_0".into(),
        ..TimelineConfig::default()
    };
    let mut s = Store::open(&db(&dir), &TimelineParams::from_config(&tl).unwrap(), 3).unwrap();
    // Opening with another rule refits at once, so no plant keeps the old fusion.
    let first = s.plant_timeline("P1").unwrap().unwrap().sessions[0].clone();
    assert_eq!(first.fused, 7.0);
    let rule: String = s
        .conn()
        .query_row("SELECT fusion_rule FROM sessions", [], |r| r.get(0))
        .unwrap();
    assert_eq!(rule, "view:SV_0");
    assert_eq!(s.recompute_all().unwrap(), 1);
    assert_eq!(s.plant_timeline("P1").unwrap().unwrap().sessions[0].fused, 7.0);
    drop(s);
    // Any other timeline setting refits too, and the settings are kept for the next open.
    let tl = TimelineConfig {
        fusion: "max-side".into(),
        death_penalty: 0.0,
        ..TimelineConfig::default()
    };
    let s = Store::open(&db(&dir), &TimelineParams::from_config(&tl).unwrap(), 3).unwrap();
    assert_eq!(s.plant_timeline("P1").unwrap().unwrap().sessions[0].fused, 9.0);
    let kept: String = s
        .conn()
        .query_row("SELECT value FROM meta WHERE key = 'timeline'", [], |r| r.get(0))
        .unwrap();
    assert!(
        kept.contains("fusion=max-side;")
            && kept.ends_with("death_penalty=0;base_temp_c=10;leaf_sites=2;next_leaf=1"),
        "{kept}"
    );
}

#[test]
fn a_settings_refit_says_so_once_instead_of_per_leaf() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    // SV_0 sees 5 leaves every day, SV_108 5, 6, 7: the default fusion (the
    // second-largest of two views) dates no new leaf, `max-side` two.
    for d in 0..3 {
        for (a, c) in [(0u16, 5u32), (108, 5 + d as u32)] {
            let t = day(d) + Duration::seconds(a as i64);
            let f = facts(&format!("P1_{d}_{a}.png"), &format!("{d}-{a}"));
            s.record(&f, Outcome::Counted(&name("P1", t, View::Side(a)), &count(c)))
                .unwrap();
        }
    }
    let head = s.feed_head().unwrap();
    drop(s);
    let tl = TimelineConfig {
        fusion: "max-side".into(),
        ..TimelineConfig::default()
    };
    let s = Store::open(&db(&dir), &TimelineParams::from_config(&tl).unwrap(), 3).unwrap();
    let leaves: Vec<u32> = s
        .plant_timeline("P1")
        .unwrap()
        .unwrap()
        .events
        .iter()
        .map(|e| e.0)
        .collect();
    assert_eq!(leaves, [6, 7]);
    let feed = s.feed_after(head, None, 100).unwrap();
    assert_eq!(feed.len(), 1, "{feed:?}");
    assert_eq!(feed[0].kind, "refit");
    let msg = feed[0].message.as_deref().unwrap();
    assert!(
        msg.contains("fusion=max-side") && msg.contains("1 plants refitted"),
        "{msg}"
    );
}

#[test]
fn counts_keep_their_settings_and_older_databases_gain_the_column() {
    // A site's database from before schema 2: one observation already in it.
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(db(&dir).parent().unwrap()).unwrap();
    let conn = Connection::open(db(&dir)).unwrap();
    conn.execute_batch(migrations::MIGRATIONS[0]).unwrap();
    conn.pragma_update(None, "user_version", 1).unwrap();
    conn.execute_batch(
        "INSERT INTO plants (id, name, first_seen) VALUES (1, 'P0', '2026-01-01T00:00:00');
         INSERT INTO observations (plant_id, taken_at, view, leaf_count, model_id, created_at)
         VALUES (1, '2026-01-01T00:00:00', 'SV_0', 5, 'old-model', '2026-01-01T00:00:00');",
    )
    .unwrap();
    drop(conn);
    let mut s = open(&dir);
    let f = facts("P1_a.png", "a");
    s.record(
        &f,
        Outcome::Counted(&name("P1", day(0), View::Side(0)), &count(8)),
    )
    .unwrap();
    let settings: Vec<Option<String>> = s
        .conn()
        .prepare("SELECT settings FROM observations ORDER BY id")
        .unwrap()
        .query_map([], |r| r.get(0))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(settings.len(), 2);
    assert_eq!(settings[0], None, "the older count has no settings");
    let v: serde_json::Value = serde_json::from_str(settings[1].as_deref().unwrap()).unwrap();
    assert_eq!(v["postprocess"]["split_min_area"], 128);
    // `phyllo status` compares the image counts with the service's settings.
    let current = settings[1].as_deref().unwrap();
    assert_eq!(s.counts_with_other_settings(current).unwrap(), 0);
    assert_eq!(s.counts_with_other_settings("{}").unwrap(), 1);
}

#[test]
fn a_temperature_log_gives_the_phyllochron_in_degree_days() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    // A leaf every 3 days for 15 days, five views a day.
    let rows: Vec<(String, NaiveDateTime, View, u32)> = (0..15)
        .flat_map(|d| (0..5).map(move |v| ("P1".to_string(), day(d), View::Side(v * 72), 4 + d as u32 / 3)))
        .collect();
    s.import("counts.csv", &rows, None).unwrap();
    let days = s.plant_timeline("P1").unwrap().unwrap().phyllochron_days.unwrap();
    assert!((days - 3.0).abs() < 0.01, "{days}");
    assert_eq!(
        s.plant_timeline("P1").unwrap().unwrap().phyllochron_cd,
        None,
        "no log yet"
    );
    // A steady 22 °C, hourly, from two days before to two days after: 12 °Cd a day.
    let log = steady_log("", 22.0);
    assert_eq!(
        s.import_climate("log.csv", &log, Some("2026-12-05T101500"))
            .unwrap(),
        1
    );
    let cd = s.plant_timeline("P1").unwrap().unwrap().phyllochron_cd.unwrap();
    assert!((cd - 12.0 * days).abs() < 1e-6, "{cd} vs {days}");
    assert!(s.journaled_imports().unwrap().contains("2026-12-05T101500"));
    // A new count refits the plant, and the thermal phyllochron with it.
    let more = vec![("P1".to_string(), day(15), View::Side(0), 9)];
    s.import("late.csv", &more, None).unwrap();
    let t = s.plant_timeline("P1").unwrap().unwrap();
    assert!((t.phyllochron_cd.unwrap() - 12.0 * t.phyllochron_days.unwrap()).abs() < 1e-6);
    // A log with a hole across the leaves gives none.
    let holed: Vec<Reading> = log
        .iter()
        .filter(|r| r.taken_at < day(6) || r.taken_at > day(8))
        .cloned()
        .collect();
    let other = tempfile::tempdir().unwrap();
    let mut h = open(&other);
    h.import("counts.csv", &rows, None).unwrap();
    assert_eq!(h.import_climate("holed.csv", &holed, None).unwrap(), 0);
}

/// `zone`'s log at a steady `temp_c`, hourly from two days before `day(0)`
/// to two days after `day(15)`.
fn steady_log(zone: &str, temp_c: f64) -> Vec<Reading> {
    (-48..(15 * 24 + 48))
        .map(|h| Reading {
            zone: zone.into(),
            taken_at: day(0) + Duration::hours(h),
            temp_c,
        })
        .collect()
}

/// Two compartments at 16 and 28 °C, each with its own log, and a plant in
/// neither on the facility's: the same leaf rate is 6, 18 and 12 °Cd a day.
/// An older database's readings become the facility's log.
#[test]
fn each_zone_times_its_own_plants() {
    let dir = tempfile::tempdir().unwrap();
    // A schema-6 database with a facility log, as the last release wrote it.
    {
        std::fs::create_dir_all(db(&dir).parent().unwrap()).unwrap();
        let mut conn = Connection::open(db(&dir)).unwrap();
        for (i, sql) in migrations::MIGRATIONS[..6].iter().enumerate() {
            let tx = conn.transaction().unwrap();
            tx.execute_batch(sql).unwrap();
            tx.pragma_update(None, "user_version", (i + 1) as i64).unwrap();
            tx.commit().unwrap();
        }
        let mut insert = conn
            .prepare("INSERT INTO climate (taken_at, temp_c, source) VALUES (?1, 22.0, 'old.csv')")
            .unwrap();
        for r in steady_log("", 22.0) {
            insert.execute([iso(r.taken_at)]).unwrap();
        }
    }
    let tl = TimelineConfig {
        zones: vec![
            crate::config::ZoneConfig {
                name: "cool".into(),
                plants: "^C-".into(),
            },
            crate::config::ZoneConfig {
                name: "warm".into(),
                plants: "^W-".into(),
            },
        ],
        ..TimelineConfig::default()
    };
    let mut s = Store::open(&db(&dir), &TimelineParams::from_config(&tl).unwrap(), 3).unwrap();
    assert_eq!(
        s.climate_summary()
            .unwrap()
            .iter()
            .map(|c| (c.zone.as_str(), c.readings))
            .collect::<Vec<_>>(),
        vec![("", 15 * 24 + 96)]
    );
    // A leaf every 3 days in each plant.
    let rows: Vec<(String, NaiveDateTime, View, u32)> = ["C-1", "W-1", "X-1"]
        .iter()
        .flat_map(|p| {
            (0..15).flat_map(move |d| {
                (0..5).map(move |v| (p.to_string(), day(d), View::Side(v * 72), 4 + d as u32 / 3))
            })
        })
        .collect();
    s.import("counts.csv", &rows, None).unwrap();
    let cd = |s: &Store, p: &str| s.plant_timeline(p).unwrap().unwrap().phyllochron_cd;
    assert!(
        (cd(&s, "X-1").unwrap() - 36.0).abs() < 0.01,
        "{:?}",
        cd(&s, "X-1")
    );
    assert_eq!(cd(&s, "C-1"), None, "the cool zone has no log yet");
    let mut both = steady_log("cool", 16.0);
    both.extend(steady_log("warm", 28.0));
    assert_eq!(s.import_climate("zones.csv", &both, None).unwrap(), 3);
    assert!(
        (cd(&s, "C-1").unwrap() - 18.0).abs() < 0.01,
        "{:?}",
        cd(&s, "C-1")
    );
    assert!(
        (cd(&s, "W-1").unwrap() - 54.0).abs() < 0.01,
        "{:?}",
        cd(&s, "W-1")
    );
    assert!((cd(&s, "X-1").unwrap() - 36.0).abs() < 0.01);
    let zones: Vec<(String, i64)> = s
        .climate_summary()
        .unwrap()
        .into_iter()
        .map(|c| (c.zone, c.readings))
        .collect();
    assert_eq!(
        zones.iter().map(|z| z.0.as_str()).collect::<Vec<_>>(),
        ["", "cool", "warm"]
    );
    assert!(s.thermal_clock(10.0, "warm").unwrap().is_some());
    // Taking the zones' file back leaves the facility's log alone.
    assert_eq!(s.unimport("zones.csv").unwrap().temperatures, 2 * (15 * 24 + 96));
    assert_eq!(cd(&s, "W-1"), None);
    assert!((cd(&s, "X-1").unwrap() - 36.0).abs() < 0.01);
}

/// A count whose leaf instances sit at `leaves` ((x, y) centres, 20 px
/// boxes, areas), every one of them.
fn count_at(leaves: &[(f32, f32, u64)]) -> CountRecord {
    let instances: Vec<serde_json::Value> = leaves
        .iter()
        .enumerate()
        .map(|(i, &(x, y, area))| {
            serde_json::json!({"id": i + 1, "class": 1, "area": area, "score": 0.9, "centre": [x, y],
                               "bbox": [x as u32 - 10, y as u32 - 10, x as u32 + 10, y as u32 + 10]})
        })
        .collect();
    CountRecord {
        instances: serde_json::Value::Array(instances),
        ..count(leaves.len() as u32)
    }
}

#[test]
fn each_new_leaf_is_placed_where_it_appeared() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = open(&dir);
    let old = [(100.0, 400.0, 900), (200.0, 380.0, 800)];
    // Day 1: one new leaf, its tip only; day 2: it has grown, and two more
    // came out, the newest the smaller.
    let days: [Vec<(f32, f32, u64)>; 3] = [
        old.to_vec(),
        vec![old[0], old[1], (150.0, 200.0, 60)],
        vec![
            old[0],
            old[1],
            (150.0, 200.0, 400),
            (260.0, 300.0, 90),
            (140.0, 120.0, 30),
        ],
    ];
    for (d, leaves) in days.iter().enumerate() {
        let f = facts(&format!("P1_{d}.png"), &format!("{d}"));
        s.record(
            &f,
            Outcome::Counted(&name("P1", day(d as i64), View::Side(72)), &count_at(leaves)),
        )
        .unwrap();
    }
    let t = s.plant_timeline("P1").unwrap().unwrap();
    let sites: Vec<(u32, [f64; 2], &str)> = t
        .sites
        .iter()
        .map(|x| (x.leaf, x.centre, x.image.as_str()))
        .collect();
    assert_eq!(
        sites,
        vec![
            (3, [150.0, 200.0], "P1_1.png"),
            (4, [260.0, 300.0], "P1_2.png"),
            (5, [140.0, 120.0], "P1_2.png")
        ]
    );
    assert!(t.sites.iter().all(|x| x.view == "SV_72"));
    assert_eq!(
        t.sites.iter().map(|x| x.area).collect::<Vec<_>>(),
        vec![60, 90, 30]
    );
    // `phyllo tail` says where, too.
    let feed = s.feed_after(0, None, 100).unwrap();
    assert!(
        feed.iter().any(|r| r
            .message
            .as_deref()
            .is_some_and(|m| m.starts_with("leaf 5 emerged about 2018-04-2")
                && m.ends_with(", seen in SV_72 at (140, 120)"))),
        "{feed:?}"
    );
    // The export carries them after the older columns.
    let out = dir.path().join("events.csv");
    crate::sinks::export::export(&s, "events", None, &out).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("plant,leaf,emerged_at,seen_at,phyllochron_days,site_view,site_image,site_x,site_y,site_bbox,site_area\r\n"),
        "{text}"
    );
    assert!(
        text.contains(",SV_72,P1_2.png,140,120,\"[130,110,150,130]\",30\r\n"),
        "{text}"
    );
}
