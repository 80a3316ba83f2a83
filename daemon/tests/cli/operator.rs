//! `phyllo import`, `tail` (in another process), `export`, `timeline` (with
//! plot) and `status` together on one site, as an operator uses them.

use std::path::Path;
use std::time::{Duration, Instant};

use crate::common::{ok, phyllo, spawn_tail};
use crate::site_config;

/// The person-counted sequence of docs/ARCHITECTURE.md ("Facility facts"), five side views and a top view per day.
fn write_obs(path: &Path) {
    let gt = [8, 8, 10, 10, 11, 11, 12, 13, 14, 12, 14];
    let mut s = String::from("plant,timestamp,view,leaf_count\n");
    for (d, c) in gt.iter().enumerate() {
        for (k, a) in [0, 36, 72, 108, 144].iter().enumerate() {
            s += &format!(
                "GT1,2018-04-{:02}T10:00:{:02},SV_{a},{}\n",
                20 + d,
                10 * k,
                c - (k % 2)
            );
        }
        s += &format!("GT1,2018-04-{:02} 10:02:00,TV_90,{}\n", 20 + d, c - 3);
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn operator_commands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg, _) = site_config(d, "");
    let cfg = cfg.as_str();
    let obs = d.join("obs.csv");
    write_obs(&obs);

    // Create the database, then follow it from another process.
    ok(&["import", "-c", cfg, obs.to_str().unwrap()]);
    let tail = spawn_tail(cfg, &["--json", "--plant", "GT2"]);
    std::thread::sleep(Duration::from_millis(700));
    let obs2 = d.join("obs2.csv");
    std::fs::write(
        &obs2,
        std::fs::read_to_string(&obs).unwrap().replace("GT1", "GT2"),
    )
    .unwrap();
    let out = ok(&["import", "-c", cfg, obs2.to_str().unwrap()]);
    assert!(out.contains("imported 66 counts for 1 plants"), "{out}");
    std::thread::sleep(Duration::from_millis(700));
    let t0 = Instant::now();
    let (status, lines) = tail.stop();
    assert!(status.success(), "tail exits cleanly on SIGTERM: {status:?}");
    assert!(t0.elapsed() < Duration::from_secs(5));
    let rows: Vec<serde_json::Value> = lines.iter().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert!(rows.iter().all(|r| r["plant"] == "GT2"), "{lines:?}");
    // Leaves 9-14: the one-day drop 14, 12, 14 is too short to read as leaves lost.
    assert_eq!(
        rows.iter().filter(|r| r["kind"] == "event").count(),
        6,
        "{lines:?}"
    );
    assert_eq!(
        rows.iter().filter(|r| r["kind"] == "import").count(),
        1,
        "{lines:?}"
    );

    // Export: every kind parses as CSV with a header; the file appears whole.
    let out = ok(&["export", "-c", cfg]);
    assert!(out.contains("events: 12 rows"), "{out}");
    // ... and every plant's plot beside the tables, each renamed into place.
    assert!(out.contains("plots: 2 plants"), "{out}");
    let mut drawn: Vec<String> = std::fs::read_dir(d.join("state/exports/plots"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    drawn.sort();
    assert_eq!(drawn, ["GT1.png", "GT2.png"]);
    for (kind, rows) in [
        ("sessions", 22),
        ("timeline", 22),
        ("events", 12),
        ("images", 0),
        ("plants", 2),
    ] {
        let path = d.join(format!("state/exports/{kind}.csv"));
        let mut r = csv::Reader::from_path(&path).unwrap();
        assert!(!r.headers().unwrap().is_empty());
        assert_eq!(
            r.records().collect::<Result<Vec<_>, _>>().unwrap().len(),
            rows,
            "{kind}"
        );
    }
    let events = d.join("out/ev.csv");
    ok(&[
        "export",
        "-c",
        cfg,
        "--what",
        "events",
        "--since",
        "2018-04-25",
        "--out",
        events.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&events).unwrap();
    assert!(
        text.starts_with("plant,leaf,emerged_at,seen_at,phyllochron_days,site_view,site_image,site_x,site_y,site_bbox,site_area\r\n"),
        "{text}"
    );
    assert_eq!(text.lines().count(), 1 + 6, "{text}");
    let leftovers: Vec<_> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "no temporary files left: {leftovers:?}");
    let plants = std::fs::read_to_string(d.join("state/exports/plants.csv")).unwrap();
    assert!(
        plants.starts_with(
            "plant,sessions,first_session,last_session,leaves_emerged,living,leaves_lost,phyllochron_days,events,last_emergence,phyllochron_cd,climate_zone,next_leaf,next_leaf_expected,leaves_emerged_fit\r\n"
        ),
        "{plants}"
    );
    let gt1 = plants.lines().find(|l| l.starts_with("GT1,")).unwrap();
    let cols: Vec<&str> = gt1.split(',').collect();
    assert_eq!((cols[1], cols[6], cols[8]), ("11", "0", "6"), "{gt1}");
    // `--what` alone writes that kind only, into the export folder.
    let plants_csv = d.join("state/exports/plants.csv");
    std::fs::remove_file(&plants_csv).unwrap();
    let out = ok(&["export", "-c", cfg, "--what", "plants"]);
    assert!(
        out.contains("plants: 2 rows") && !out.contains("events:"),
        "{out}"
    );
    assert!(plants_csv.exists());
    let bad = phyllo(&["export", "-c", cfg, "--what", "leaves"]);
    assert!(!bad.status.success());

    // Timeline: table, events, phyllochron, and a PNG.
    let png = d.join("gt1.png");
    let out = ok(&["timeline", "-c", cfg, "GT1", "--plot", png.to_str().unwrap()]);
    assert!(out.contains("leaf 14 emerged about 2018-04-29"), "{out}");
    assert!(out.contains("lost"), "{out}");
    assert!(out.contains("phyllochron:"), "{out}");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (1000, 600));
    // Every plant's plot at once.
    let plots = d.join("plots");
    let out = phyllo(&["timeline", "-c", cfg, "--plots", plots.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("2 plots written"));
    for p in ["GT1", "GT2"] {
        let img = image::open(plots.join(format!("{p}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (1000, 600));
    }
    assert!(
        !phyllo(&["timeline", "-c", cfg]).status.success(),
        "a plant or --plots"
    );
    let out = phyllo(&["timeline", "-c", cfg, "NOPE"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("no plant 'NOPE'"));

    // Status works without a running service.
    let out = ok(&["status", "-c", cfg]);
    assert!(
        out.contains("never started") && out.contains("132 imported counts; 2 plants"),
        "{out}"
    );
    assert!(
        out.contains("timeline:  12 leaves dated; 0 leaves lost on 0 plants\n") && !out.contains("fusion="),
        "{out}"
    );
    // The fit's fingerprint is internal: only --verbose shows it.
    let out = ok(&["status", "-c", cfg, "--verbose"]);
    assert!(out.contains("fit:       fusion=second-max-side;"), "{out}");

    // Bad config: named file, clear problem, non-zero exit.
    let badcfg = d.join("bad.toml");
    std::fs::write(&badcfg, "drop_dir = \"/x\"\ndatabase = \"/y\"\nworkerz = 3\n").unwrap();
    let out = phyllo(&["status", "-c", badcfg.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.toml") && err.contains("workerz"),
        "{err}"
    );
}

/// `phyllo forecast` with nothing to forecast says why instead of printing
/// a bare header (issue 56 item 7).
#[test]
fn forecast_with_nothing_to_forecast_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg, _) = site_config(d, "");
    let cfg = cfg.as_str();
    let obs = d.join("one.csv");
    std::fs::write(
        &obs,
        "plant,timestamp,view,leaf_count\nNEW1,2018-04-20T10:00:00,SV_108,4\n",
    )
    .unwrap();
    ok(&["import", "-c", cfg, obs.to_str().unwrap()]);
    let out = ok(&["forecast", "-c", cfg]);
    assert_eq!(
        out.trim(),
        "no forecast: none of the 1 plants has three dated leaves (or a forward rate) yet"
    );
}
