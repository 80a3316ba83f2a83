//! `phyllo review`: the sessions in doubt, as a sheet a person fills in and
//! imports.

use crate::common::ok;
use crate::site_config;

/// The loop a breeder runs: `phyllo review` lists the sessions most in
/// doubt and writes them as a sheet; the person fills in the counts they
/// made and `phyllo import`s it; those sessions then follow the person and
/// leave the list, and rows left empty are skipped.
#[test]
fn review_lists_the_days_in_doubt_and_the_filled_sheet_settles_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg, _) = site_config(d, "");
    let cfg = cfg.as_str();
    let mut obs = String::from("plant,timestamp,view,leaf_count\n");
    // P1's day 2 reads 9 between 7s and 8s; on P2's day 4 three views differ.
    for (plant, days) in [
        (
            "P1",
            [[7, 7, 7, 7, 6], [9, 9, 8, 8, 8], [7, 7, 7, 7, 7], [8, 8, 8, 8, 8]],
        ),
        (
            "P2",
            [[5, 5, 5, 5, 5], [6, 6, 6, 6, 6], [6, 6, 6, 6, 6], [7, 7, 6, 6, 8]],
        ),
    ] {
        for (day, counts) in days.iter().enumerate() {
            for (v, c) in counts.iter().enumerate() {
                obs += &format!("{plant},2026-11-{:02}T10:00:{v:02},SV_{},{c}\n", day + 1, v * 72);
            }
        }
    }
    std::fs::write(d.join("model.csv"), obs).unwrap();
    ok(&["import", "-c", cfg, d.join("model.csv").to_str().unwrap()]);

    let sheet = d.join("review.csv");
    let out = ok(&["review", "-c", cfg, "--csv", sheet.to_str().unwrap()]);
    let listed: Vec<&str> = out.lines().filter(|l| l.starts_with('P')).collect();
    assert!(
        listed[0].starts_with("P1\t2026-11-02T10:00:00.000\tcount 9 where the timeline has"),
        "{out}"
    );
    assert!(
        out.contains("P2\t2026-11-04T10:00:00.000\t3 of 5 side views differ"),
        "{out}"
    );
    let status: serde_json::Value = serde_json::from_str(&ok(&["status", "-c", cfg, "--json"])).unwrap();
    assert_eq!(status["sessions_in_doubt"], listed.len());
    let json: serde_json::Value =
        serde_json::from_str(&ok(&["review", "-c", cfg, "--json", "--top", "1"])).unwrap();
    assert_eq!(json.as_array().unwrap().len(), 1);
    assert_eq!(json[0]["plant"], "P1");
    assert_eq!(json[0]["views"]["SV_0"], 9.0);
    let since = ok(&["review", "-c", cfg, "--since", "2026-11-04"]);
    assert!(!since.contains("2026-11-02"), "{since}");

    // The person counted P1's day 2 (8 leaves) and nothing else.
    let text = std::fs::read_to_string(&sheet).unwrap();
    assert!(text.starts_with("plant,timestamp,view,leaf_count,phyllo_count,timeline,views,why,images\r\n"));
    let filled = text.replacen(
        "P1,2026-11-02T10:00:00.000,human,,",
        "P1,2026-11-02T10:00:00.000,human,8,",
        1,
    );
    assert_ne!(filled, text);
    std::fs::write(&sheet, filled).unwrap();
    let out = ok(&["import", "-c", cfg, sheet.to_str().unwrap()]);
    let others = listed.len() - 1;
    assert!(
        out.contains("imported 1 counts for 1 plants")
            && out.contains(&format!("; {others} rows without a leaf_count skipped")),
        "{out}"
    );
    let t: serde_json::Value = serde_json::from_str(&ok(&["timeline", "-c", cfg, "P1", "--json"])).unwrap();
    assert_eq!(t["sessions"][1]["fused"], 8.0);
    let again = ok(&["review", "-c", cfg]);
    assert!(
        !again.contains("P1\t2026-11-02"),
        "a checked session is not listed again: {again}"
    );

    // The nightly export writes the sheet and shows it on the page.
    ok(&["export", "-c", cfg]);
    let exported = std::fs::read_to_string(d.join("state/exports/review.csv")).unwrap();
    assert!(
        exported.contains("P2,2026-11-04T10:00:00.000,human,,"),
        "{exported}"
    );
    let page = std::fs::read_to_string(d.join("state/exports/index.html")).unwrap();
    assert!(page.contains("<h2>Days to check</h2>"), "{page}");
}
