//! Temperature logs (`phyllo import` of `timestamp,temp_c[,zone]`): degree-days
//! per leaf in the timeline, the exports, the groups and `phyllo forecast`,
//! per compartment.

use std::path::Path;

use crate::common::{ok, phyllo};
use crate::{temperature_log, two_genotypes, two_genotypes_with};

/// `phyllo import` of a greenhouse temperature log (`timestamp,temp_c`):
/// every plant's phyllochron also in degree-days per leaf, in the timeline,
/// the plants export, the groups and their comparison; a bad reading is
/// named by file and line, and nothing of that file is stored.
#[test]
fn a_temperature_log_gives_degree_days_per_leaf() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = two_genotypes(d);
    let cfg = cfg.as_str();

    // 18 °C at night, 28 °C by day, every 30 minutes from 30 October on
    // (13 °Cd a day above 10 °C, less where the steps are smoothed).
    let start = chrono::NaiveDate::from_ymd_opt(2026, 10, 30)
        .unwrap()
        .and_hms_opt(0, 0, 0)
        .unwrap();
    let mut log = String::from("timestamp,temp_c,humidity\n");
    for k in 0..(24 * 48) {
        let t = start + chrono::Duration::minutes(30 * k);
        let temp = if (6..18).contains(&chrono::Timelike::hour(&t)) {
            28.0
        } else {
            18.0
        };
        log += &format!("{},{temp},60\n", t.format("%Y-%m-%dT%H:%M:%S"));
    }
    let bad = d.join("bad-log.csv");
    std::fs::write(
        &bad,
        "timestamp,temp_c\n2026-11-01T00:00:00,21.5\n2026-11-01T00:30:00,215\n",
    )
    .unwrap();
    let out = phyllo(&["import", "-c", cfg, bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad-log.csv:3") && err.contains("215"),
        "{err}"
    );
    std::fs::write(d.join("log.csv"), log).unwrap();
    let out = ok(&["import", "-c", cfg, d.join("log.csv").to_str().unwrap()]);
    assert!(
        out.contains("1152 temperatures (6 plants with a phyllochron in degree-days)"),
        "{out}"
    );

    let status: serde_json::Value = serde_json::from_str(&ok(&["status", "-c", cfg, "--json"])).unwrap();
    assert_eq!(status["climate"][0]["readings"], 1152, "{status}");
    assert_eq!(status["climate"][0]["zone"], "", "{status}");
    assert_eq!(status["climate"][0]["longest_gap_hours"], 0.5, "{status}");
    assert!(ok(&["status", "-c", cfg]).contains(
        "climate:   1152 temperatures from 2026-10-30T00:00 to 2026-11-22T23:30; longest gap 0.5 h\n"
    ));
    let t: serde_json::Value = serde_json::from_str(&ok(&["timeline", "-c", cfg, "F-1", "--json"])).unwrap();
    let (days, cd) = (
        t["phyllochron_days"].as_f64().unwrap(),
        t["phyllochron_cd"].as_f64().unwrap(),
    );
    // Leaves every two days, each day 13 °Cd: about 26 °Cd a leaf.
    assert!(
        (days - 2.0).abs() < 0.1 && (cd - 26.0).abs() < 2.0,
        "{days} d, {cd} °Cd"
    );
    assert!(ok(&["timeline", "-c", cfg, "F-1"]).contains(" degree-days per leaf"));
    let text = plants_csv(cfg, d);
    assert!(
        text.lines().next().unwrap().ends_with(
            ",last_emergence,phyllochron_cd,climate_zone,next_leaf,next_leaf_expected,leaves_emerged_fit"
        ),
        "{text}"
    );
    // Leaves emerge at the same hour each day, so each day between two adds
    // exactly 13 °Cd: 26 for a leaf every two days, 65 for one every five.
    assert!(
        text.contains("\r\nF-1,") && text.contains(",2026-11-20T22:00:00.000,26,,"),
        "{text}"
    );
    assert!(text.contains(",2026-11-20T22:00:00.000,65,,"), "{text}");
    let rep: serde_json::Value =
        serde_json::from_str(&ok(&["groups", "-c", cfg, "--compare", "--json"])).unwrap();
    let f = &rep["summaries"][0]["phyllochron_cd"];
    assert_eq!(f["n"], 3, "{f}");
    let thermal = rep["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["measure"] == "phyllochron_cd")
        .unwrap();
    assert!(thermal["difference"].as_f64().unwrap() < -20.0, "{thermal}");
}

/// The store's `plants.csv`, exported into `d`.
fn plants_csv(cfg: &str, d: &Path) -> String {
    let plants = d.join("plants.csv");
    ok(&[
        "export",
        "-c",
        cfg,
        "--what",
        "plants",
        "--out",
        plants.to_str().unwrap(),
    ]);
    std::fs::read_to_string(&plants).unwrap()
}

/// Compartments (`[[timeline.zones]]`) with logs of their own: each plant's
/// degree-days come from its zone's log, or the facility's for a plant in
/// none; a log naming an undeclared zone is refused by file and line, and a
/// zone without readings is named where it leaves a plant untimed.
#[test]
fn compartments_keep_their_own_temperature_logs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = two_genotypes_with(
        d,
        "[[timeline.zones]]\nname = 'empty-house'\nplants = '^S-3$'\n\
         [[timeline.zones]]\nname = 'hot-house'\nplants = '^F-'\n",
    );
    let cfg = cfg.as_str();
    // The facility: 18 °C at night, 28 °C by day (13 °Cd a day); the hot house a steady 30 °C (20).
    std::fs::write(
        d.join("facility.csv"),
        temperature_log(None, |h| if (6..18).contains(&h) { 28.0 } else { 18.0 }),
    )
    .unwrap();
    let hot = temperature_log(Some("hot-house"), |_| 30.0);
    std::fs::write(d.join("typo.csv"), hot.replacen(",hot-house\n", ",hot-hous\n", 1)).unwrap();
    std::fs::write(d.join("hot.csv"), hot).unwrap();
    let out = phyllo(&["import", "-c", cfg, d.join("typo.csv").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("typo.csv:2: zone 'hot-hous' is not declared")
            && err.contains("it declares empty-house, hot-house"),
        "{err}"
    );
    ok(&["import", "-c", cfg, d.join("facility.csv").to_str().unwrap()]);
    let out = ok(&["import", "-c", cfg, d.join("hot.csv").to_str().unwrap()]);
    assert!(
        out.contains("1152 temperatures for zones hot-house (5 plants"),
        "{out}"
    );

    let cd = |p: &str| -> Option<f64> {
        let t: serde_json::Value = serde_json::from_str(&ok(&["timeline", "-c", cfg, p, "--json"])).unwrap();
        t["phyllochron_cd"].as_f64()
    };
    // F-1 and S-1 each gain a leaf every 2 and 4 days.
    assert_eq!(
        cd("F-1").map(f64::round),
        Some(40.0),
        "the hot house's 20 °Cd a day"
    );
    assert_eq!(
        cd("S-1").map(f64::round),
        Some(52.0),
        "the facility's 13 °Cd a day"
    );
    assert_eq!(cd("S-3"), None, "the empty house has no log");
    // `phyllo forecast`: a leaf out already, one due by the hot house's log, one by days.
    let how = |args: &[&str]| -> String {
        let mut all = vec!["forecast", "-c", cfg, "--json"];
        all.extend_from_slice(args);
        let v: serde_json::Value = serde_json::from_str(&ok(&all)).unwrap();
        v[0]["how"].as_str().unwrap_or("none").to_string()
    };
    assert_eq!(how(&["--plant", "F-1", "--leaf", "5"]), "emerged");
    assert_eq!(how(&["--plant", "F-1", "--leaf", "30"]), "degree-days");
    assert_eq!(how(&["--plant", "S-3"]), "days", "the empty house has no log");
    let out = phyllo(&["forecast", "-c", cfg, "--plant", "Q-9"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("no plant \"Q-9\""));
    let t: serde_json::Value = serde_json::from_str(&ok(&["timeline", "-c", cfg, "F-1", "--json"])).unwrap();
    assert!(
        t["next_leaf"]["leaf"].as_u64().is_some() && t["next_leaf"]["expected"].as_str().is_some(),
        "{t}"
    );
    assert!(ok(&["timeline", "-c", cfg, "F-1"]).contains(" degree-days per leaf (zone hot-house)\n"));
    let text = plants_csv(cfg, d);
    assert!(
        text.lines()
            .next()
            .unwrap()
            .ends_with(",phyllochron_cd,climate_zone,next_leaf,next_leaf_expected,leaves_emerged_fit"),
        "{text}"
    );
    assert!(
        text.contains(",40,hot-house,") && text.contains(",52,,") && text.contains(",,empty-house,"),
        "{text}"
    );
    let status = ok(&["status", "-c", cfg]);
    assert!(
        status.contains("climate:   1152 temperatures from 2026-10-30T00:00")
            && status.contains("climate:   zone hot-house: 1152 temperatures")
            && status.contains("climate:   zone empty-house: no temperatures yet"),
        "{status}"
    );
    assert!(
        !status.contains("days before its plants' newest session"),
        "{status}"
    );
    // F-1 imaged a week after the hot house's log ends: the log is behind.
    std::fs::write(
        d.join("late.csv"),
        "plant,timestamp,view,leaf_count\nF-1,2026-11-30T10:00:00,SV_0,15\n",
    )
    .unwrap();
    ok(&["import", "-c", cfg, d.join("late.csv").to_str().unwrap()]);
    let check = phyllo(&["status", "-c", cfg, "--check"]);
    let line = String::from_utf8_lossy(&check.stdout);
    assert!(
        line.contains("zone hot-house's temperature log ends 7.4 days before its plants' newest session")
            && !line.contains("the facility's temperature log ends"),
        "{line}"
    );
    let status: serde_json::Value = serde_json::from_str(&ok(&["status", "-c", cfg, "--json"])).unwrap();
    assert_eq!(status["climate_behind_hours"]["hot-house"], 178.5, "{status}");
    // Plain status and its JSON show the --check line too (issue 56 item 4).
    let check_line = line.trim();
    assert_eq!(status["check"], check_line, "{status}");
    let text = ok(&["status", "-c", cfg]);
    assert!(text.contains(&format!("\ncheck:     {check_line}\n")), "{text}");
    ok(&["import", "-c", cfg, "--undo", "late.csv"]);
    let png = d.join("plot.png");
    ok(&[
        "timeline",
        "-c",
        cfg,
        "F-1",
        "--plot",
        png.to_str().unwrap(),
        "--degree-days",
    ]);
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    let out = phyllo(&[
        "timeline",
        "-c",
        cfg,
        "S-3",
        "--plot",
        png.to_str().unwrap(),
        "--degree-days",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("plant S-3 is timed by zone empty-house's temperature log"),
        "{err}"
    );
    let plots = d.join("plots");
    let out = phyllo(&[
        "timeline",
        "-c",
        cfg,
        "--plots",
        plots.to_str().unwrap(),
        "--degree-days",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(plots.join("S-3.png").exists() && plots.join("F-1.png").exists());
}
