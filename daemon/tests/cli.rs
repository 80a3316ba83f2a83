//! The operator commands as separate processes on a real database:
//! import, tail (in another process), export, timeline (with plot), status.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_phyllo");

fn phyllo(args: &[&str]) -> std::process::Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = phyllo(args);
    assert!(
        out.status.success(),
        "phyllo {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// A config in `d` (drop directory and database under it) with `extra`
/// appended; returns its path and its text.
fn site_config(d: &Path, extra: &str) -> (String, String) {
    let cfg = d.join("phyllo.toml");
    let text = format!(
        "drop_dir = {:?}\ndatabase = {:?}\n{extra}",
        d.join("drop"),
        d.join("state/phyllo.sqlite")
    );
    std::fs::write(&cfg, &text).unwrap();
    (cfg.to_str().unwrap().to_string(), text)
}

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
    let mut tail = Command::new(BIN)
        .args(["tail", "-c", cfg, "--json", "--plant", "GT2"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = tail.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        BufReader::new(stdout)
            .lines()
            .map(|l| l.unwrap())
            .collect::<Vec<String>>()
    });
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
    assert!(Command::new("kill")
        .args(["-TERM", &tail.id().to_string()])
        .status()
        .unwrap()
        .success());
    let status = tail.wait().unwrap();
    assert!(status.success(), "tail exits cleanly on SIGTERM: {status:?}");
    assert!(t0.elapsed() < Duration::from_secs(5));
    let lines = reader.join().unwrap();
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
            "plant,sessions,first_session,last_session,leaves_emerged,living,leaves_lost,phyllochron_days,events,last_emergence,phyllochron_cd,climate_zone,next_leaf,next_leaf_expected\r\n"
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

/// `phyllo groups` and the nightly export's group files, on plants of two
/// genotypes under two treatments whose leaf numbers are known: genotype A
/// gains a leaf every 2 days, B every 4, both from 4 leaves; one plant id
/// outside the pattern is listed, not grouped.
#[test]
fn groups_summarise_genotypes_and_treatments() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg_s, base) = site_config(d, &format!("[export]\ndir = {:?}\n", d.join("exports")));
    let cfg_s = cfg_s.as_str();
    let cfg = Path::new(cfg_s);
    let mut obs = String::from("plant,timestamp,view,leaf_count\n");
    let plants = [
        "1-A-WW-1", "2-A-WW-2", "3-A-WL-1", "4-B-WW-1", "5-B-WW-2", "6-B-WL-1", "stray",
    ];
    for p in plants {
        let every = if p.contains("-B-") { 4 } else { 2 };
        for day in 0..13 {
            for a in [0, 36, 72, 108, 144] {
                obs += &format!(
                    "{p},2026-11-{:02}T10:00:{:02},SV_{a},{}\n",
                    1 + day,
                    a / 36,
                    4 + day / every
                );
            }
        }
    }
    std::fs::write(d.join("obs.csv"), obs).unwrap();
    ok(&["import", "-c", cfg_s, d.join("obs.csv").to_str().unwrap()]);

    // A monitor asking before the service ever ran, and about a missing database.
    let check = phyllo(&["status", "-c", cfg_s, "--check"]);
    assert_eq!(check.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&check.stdout).starts_with("phyllo CRITICAL: service never started"));
    let other = d.join("other.toml");
    std::fs::write(
        &other,
        format!(
            "drop_dir = {:?}\ndatabase = {:?}\n",
            d.join("drop"),
            d.join("none.sqlite")
        ),
    )
    .unwrap();
    let check = phyllo(&["status", "-c", other.to_str().unwrap(), "--check"]);
    assert_eq!(check.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&check.stdout).starts_with("phyllo UNKNOWN: database"));

    // Without a pattern the command says what to set.
    let out = phyllo(&["groups", "-c", cfg_s]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("[groups] pattern"));

    std::fs::write(
        cfg,
        format!(
            "{base}[groups]\npattern = '^(?P<pot>\\d+)-(?P<genotype>[A-Z]+)-(?P<treatment>WW|WL)-(?P<rep>\\d+)$'\nby = [\"genotype\", \"treatment\"]\n"
        ),
    )
    .unwrap();
    let out = phyllo(&["groups", "-c", cfg_s, "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("plants matching no [groups] pattern (1): stray"));
    let rep: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let groups: Vec<String> = rep["summaries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| {
            g["group"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_str().unwrap())
                .collect::<Vec<_>>()
                .join("/")
        })
        .collect();
    assert_eq!(groups, ["A/WL", "A/WW", "B/WL", "B/WW"]);
    let ww = |i: usize, k: &str| rep["summaries"][i][k]["mean"].as_f64().unwrap();
    // Day 12: A has 4 + 12/2 = 10 leaves, B 4 + 12/4 = 7; A's phyllochron 2 days, B's 4.
    assert_eq!(rep["summaries"][1]["plants"], 2);
    assert!(
        (ww(1, "leaves_emerged") - 10.0).abs() < 1e-9,
        "{}",
        rep["summaries"][1]
    );
    assert!(
        (ww(3, "leaves_emerged") - 7.0).abs() < 1e-9,
        "{}",
        rep["summaries"][3]
    );
    assert!(
        (ww(1, "phyllochron_days") - 2.0).abs() < 0.2,
        "{}",
        rep["summaries"][1]
    );
    assert!(
        (ww(3, "phyllochron_days") - 4.0).abs() < 0.4,
        "{}",
        rep["summaries"][3]
    );
    assert_eq!(rep["unmatched"], serde_json::json!(["stray"]));

    // The nightly export writes both tables and the plot beside the others.
    ok(&["export", "-c", cfg_s]);
    let exports = d.join("exports");
    let groups_csv = std::fs::read_to_string(exports.join("groups.csv")).unwrap();
    let mut lines = groups_csv.lines();
    assert!(lines
        .next()
        .unwrap()
        .starts_with("genotype,treatment,plants,leaves_emerged_mean,leaves_emerged_sd"));
    assert!(lines.nth(1).unwrap().starts_with("A,WW,2,10,0,"), "{groups_csv}");
    let days = std::fs::read_to_string(exports.join("group_days.csv")).unwrap();
    assert_eq!(days.lines().count(), 1 + 4 * 13);
    assert!(days.contains("B,WW,2026-11-13,2,7,0,7,0"), "{days}");
    let png = image::open(exports.join("groups.png")).unwrap();
    assert_eq!((png.width(), png.height()), (1000, 600));
    // One page links it all: each plant to its plot, the groups, the tables.
    let page = std::fs::read_to_string(exports.join("index.html")).unwrap();
    for p in plants {
        assert!(
            page.contains(&format!("<a href=\"plots/{p}.png\">{p}</a>")),
            "{p} in {page}"
        );
        assert!(exports.join("plots").join(format!("{p}.png")).exists());
    }
    for f in [
        "groups.png",
        "groups.csv",
        "group_days.csv",
        "plants.csv",
        "events.csv",
    ] {
        assert!(page.contains(&format!("\"{f}\"")), "{f} in {page}");
    }
    assert!(
        page.contains("<td>B</td><td>WL</td><td>1</td><td>7</td>"),
        "{page}"
    );
    // The page says how the service stood when it was written (here: it never ran).
    assert!(
        page.contains("Service: <code>phyllo CRITICAL: service never started"),
        "{page}"
    );
}

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

/// A config in `d` grouping plants by genotype, and 21 days of counts
/// imported for six plants: a leaf every 2, 2 and 3 days in genotype F,
/// every 4, 4 and 5 in S. Returns the config's path.
fn two_genotypes(d: &Path) -> String {
    two_genotypes_with(d, "")
}

/// [`two_genotypes`] with `extra` at the end of the config.
fn two_genotypes_with(d: &Path, extra: &str) -> String {
    let (cfg, _) = site_config(
        d,
        &format!("[groups]\npattern = '^(?P<genotype>[A-Z]+)-\\d+$'\n{extra}"),
    );
    let mut obs = String::from("plant,timestamp,view,leaf_count\n");
    for (p, every) in [
        ("F-1", 2),
        ("F-2", 2),
        ("F-3", 3),
        ("S-1", 4),
        ("S-2", 4),
        ("S-3", 5),
    ] {
        for day in 0..21 {
            for a in [0, 72, 144] {
                obs += &format!(
                    "{p},2026-11-{:02}T10:00:{:02},SV_{a},{}\n",
                    1 + day,
                    a / 72,
                    4 + day / every
                );
            }
        }
    }
    std::fs::write(d.join("obs.csv"), obs).unwrap();
    ok(&["import", "-c", &cfg, d.join("obs.csv").to_str().unwrap()]);
    cfg
}

/// `phyllo groups --compare`: every two groups tested against each other
/// (Welch), on the terminal, in JSON and as `group_pairs.csv`.
#[test]
fn groups_compare_tests_every_two_groups() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = two_genotypes(d);
    let cfg = cfg.as_str();
    let rep: serde_json::Value =
        serde_json::from_str(&ok(&["groups", "-c", cfg, "--compare", "--json"])).unwrap();
    let pairs = rep["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 2, "{pairs:?}");
    let ph = &pairs[0];
    assert_eq!(
        (ph["measure"].as_str(), ph["a"][0].as_str(), ph["b"][0].as_str()),
        (Some("phyllochron_days"), Some("F"), Some("S"))
    );
    // F averages 2.33 days per leaf, S 4.33: two days apart, well outside chance.
    let diff = ph["difference"].as_f64().unwrap();
    assert!((diff + 2.0).abs() < 0.3, "{ph}");
    let (lo, hi) = (ph["ci95"][0].as_f64().unwrap(), ph["ci95"][1].as_f64().unwrap());
    assert!(lo < diff && diff < hi && hi < 0.0, "{ph}");
    assert!(ph["p"].as_f64().unwrap() < 0.05, "{ph}");
    assert_eq!(pairs[1]["measure"], "leaves_emerged");
    let table = ok(&["groups", "-c", cfg, "--compare"]);
    assert!(table.contains("phyllochron_days\tF − S\t3 / 3\t-2."), "{table}");
    let csv_dir = d.join("csv");
    ok(&["groups", "-c", cfg, "--csv", csv_dir.to_str().unwrap()]);
    let written = std::fs::read_to_string(csv_dir.join("group_pairs.csv")).unwrap();
    assert!(written.starts_with("measure,genotype_a,genotype_b,plants_a,plants_b,mean_a,mean_b,difference,ci95_low,ci95_high,t,df,p,p_holm,blocks\r\n"), "{written}");
    assert_eq!(written.lines().count(), 3, "{written}");
}

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
        text.lines()
            .next()
            .unwrap()
            .ends_with(",last_emergence,phyllochron_cd,climate_zone,next_leaf,next_leaf_expected"),
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

/// `[groups] block`: the same plants compared within replicate blocks (the
/// number in each id), in the table, the JSON and `group_pairs.csv`.
#[test]
fn groups_compare_within_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // two_genotypes' ids are genotype-replicate: F-1 and S-1 stand in block 1.
    let cfg = two_genotypes_with(d, "");
    std::fs::write(
        &cfg,
        std::fs::read_to_string(&cfg).unwrap().replace(
            "pattern = '^(?P<genotype>[A-Z]+)-\\d+$'",
            "pattern = '^(?P<genotype>[A-Z]+)-(?P<rep>\\d+)$'\nby = ['genotype']\nblock = 'rep'",
        ),
    )
    .unwrap();
    let cfg = cfg.as_str();
    let rep: serde_json::Value =
        serde_json::from_str(&ok(&["groups", "-c", cfg, "--compare", "--json"])).unwrap();
    let emerged = rep["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["measure"] == "leaves_emerged")
        .unwrap_or_else(|| panic!("{rep}"));
    assert_eq!(emerged["blocks"], 3, "{emerged}");
    assert_eq!(emerged["df"], 2.0, "{emerged}");
    let table = ok(&["groups", "-c", cfg, "--compare"]);
    assert!(
        table.contains("compared within blocks of rep")
            && table.contains("leaves_emerged\tF − S\t3 / 3 in 3 blocks\t+"),
        "{table}"
    );
    let csv_dir = d.join("csv");
    ok(&["groups", "-c", cfg, "--csv", csv_dir.to_str().unwrap()]);
    let written = std::fs::read_to_string(csv_dir.join("group_pairs.csv")).unwrap();
    assert!(
        written
            .lines()
            .any(|l| l.starts_with("leaves_emerged,F,S,3,3,") && l.ends_with(",3")),
        "{written}"
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
    assert_eq!(q(d, "SELECT COUNT(*) FROM climate"), 1152);
    assert_eq!(q(d, "SELECT COUNT(*) FROM observations"), 2);

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
    assert_eq!(q(d, "SELECT COUNT(*) FROM climate"), 1154);
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
    assert_eq!(q(d, "SELECT COUNT(*) FROM observations"), 0);
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

/// One number from the test site's database.
fn q(d: &Path, sql: &str) -> i64 {
    rusqlite::Connection::open(d.join("state/phyllo.sqlite"))
        .unwrap()
        .query_row(sql, [], |r| r.get(0))
        .unwrap()
}

/// `timestamp,temp_c[,zone]` rows every 30 minutes from 30 October for 24
/// days at `temp(hour)` °C.
fn temperature_log(zone: Option<&str>, temp: impl Fn(u32) -> f64) -> String {
    let start = chrono::NaiveDate::from_ymd_opt(2026, 10, 30)
        .unwrap()
        .and_hms_opt(0, 0, 0)
        .unwrap();
    let mut log = String::from(if zone.is_some() {
        "timestamp,temp_c,zone\n"
    } else {
        "timestamp,temp_c\n"
    });
    for k in 0..(24 * 48) {
        let t = start + chrono::Duration::minutes(30 * k);
        let temp = temp(chrono::Timelike::hour(&t));
        match zone {
            Some(z) => log += &format!("{},{temp},{z}\n", t.format("%Y-%m-%dT%H:%M:%S")),
            None => log += &format!("{},{temp}\n", t.format("%Y-%m-%dT%H:%M:%S")),
        }
    }
    log
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
            .ends_with(",phyllochron_cd,climate_zone,next_leaf,next_leaf_expected"),
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

/// `phyllo timeline --plot/--plots --degree-days`: the x axis in degree-days
/// of the imported temperature log; refused, with the reason, without a log,
/// without a plot to draw, and for a plant whose sessions the log does not
/// cover.
#[test]
fn timelines_plot_against_degree_days() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = two_genotypes(d);
    let cfg = cfg.as_str();
    let png = d.join("F-1.png");
    let png_arg = png.to_str().unwrap();
    let out = phyllo(&["timeline", "-c", cfg, "F-1", "--plot", png_arg, "--degree-days"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("has no temperature log"),
        "{err}"
    );
    let out = phyllo(&["timeline", "-c", cfg, "F-1", "--degree-days"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("give --plot"), "{err}");

    // Hourly from 1 to 15 November only: the last week of sessions is outside it.
    let mut log = String::from("timestamp,temp_c\n");
    for h in 0..(15 * 24) {
        log += &format!("2026-11-{:02}T{:02}:00:00,22\n", 1 + h / 24, h % 24);
    }
    std::fs::write(d.join("log.csv"), &log).unwrap();
    ok(&["import", "-c", cfg, d.join("log.csv").to_str().unwrap()]);
    let out = phyllo(&["timeline", "-c", cfg, "F-1", "--plot", png_arg, "--degree-days"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("plant F-1: the temperature log does not cover"),
        "{err}"
    );
    assert!(!png.exists(), "no half-drawn plot is left");
    // The nightly plots in degree-days: the plants the log does not cover are drawn in days.
    let mut text = std::fs::read_to_string(cfg).unwrap();
    text += "[export]\nplot_axis = \"degree-days\"\n";
    std::fs::write(cfg, text).unwrap();
    let out = ok(&["export", "-c", cfg]);
    assert!(
        out.contains("plots: 6 plants in days, their sessions outside the temperature log"),
        "{out}"
    );
    assert_eq!(
        std::fs::read_dir(d.join("state/exports/plots")).unwrap().count(),
        6
    );

    // The log runs on to the end of November: every session is covered.
    let mut rest = String::from("timestamp,temp_c\n");
    for h in (15 * 24)..(30 * 24) {
        rest += &format!("2026-11-{:02}T{:02}:00:00,22\n", 1 + h / 24, h % 24);
    }
    std::fs::write(d.join("rest.csv"), &rest).unwrap();
    ok(&["import", "-c", cfg, d.join("rest.csv").to_str().unwrap()]);
    ok(&["timeline", "-c", cfg, "F-1", "--plot", png_arg, "--degree-days"]);
    let out = ok(&["export", "-c", cfg]);
    assert!(!out.contains("plants in days"), "{out}");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (1000, 600));
    let days_png = d.join("F-1-days.png");
    ok(&["timeline", "-c", cfg, "F-1", "--plot", days_png.to_str().unwrap()]);
    // Same data, another axis: the drawings differ.
    assert_ne!(std::fs::read(&png).unwrap(), std::fs::read(&days_png).unwrap());
    let plots = d.join("plots");
    ok(&[
        "timeline",
        "-c",
        cfg,
        "--plots",
        plots.to_str().unwrap(),
        "--degree-days",
    ]);
    assert_eq!(std::fs::read_dir(&plots).unwrap().count(), 6);
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
