//! The daemon end to end, as the facility runs it: `phyllo-gen sequence`
//! frames for a few plants over several days are dropped — shuffled, some
//! written slowly, some renamed into place — into the watched directory of a
//! running `phyllo serve` (real model, real ONNX Runtime, real inotify, real
//! SQLite). `phyllo tail` runs in another process. Checks: every image counted
//! exactly once, tail saw every count, SIGTERM stops the service cleanly, the
//! exported CSVs parse; the timeline's emergence dates are compared with
//! `truth.csv` and the error is printed (it measures the model, so it is
//! reported, not asserted).
//!
//! Size: `PHYLLO_E2E_PLANTS` (default 3) × `PHYLLO_E2E_DAYS` (default 4) × 6
//! views. Frames are cached under `target/e2e-cache/` (the generator skips
//! frames that exist), so reruns only pay for counting.

use std::collections::{BTreeMap, HashSet};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use chrono_free::days_between;
use phyllo_e2e::{env_or, signal, spawn_tail, write_config};

/// Date arithmetic on `YYYY-MM-DD` without a date crate.
mod chrono_free {
    fn days(s: &str) -> i64 {
        let p: Vec<i64> = s[..10].split('-').map(|x| x.parse().unwrap()).collect();
        let (y, m, d) = (p[0] - i64::from(p[1] <= 2), p[1], p[2]);
        let era = y.div_euclid(400);
        let yoe = y - era * 400;
        let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + d - 1;
        era * 146_097 + yoe * 365 + yoe / 4 - yoe / 100 + doy
    }

    /// Fractional days from the middle of day `a` (YYYY-MM-DD: truth.csv only
    /// gives the date, so the emergence is anywhere in it) to `b`
    /// (YYYY-MM-DD[THH:MM:SS...]).
    pub fn days_between(a: &str, b: &str) -> f64 {
        let mut t = (days(b) - days(a)) as f64 - 0.5;
        if b.len() >= 19 {
            let h: f64 = b[11..13].parse().unwrap();
            let m: f64 = b[14..16].parse().unwrap();
            t += (h + m / 60.0) / 24.0;
        }
        t
    }
}

/// The target directory and the two binaries, (re)built if stale.
fn binaries() -> (PathBuf, PathBuf, PathBuf) {
    let phyllo = phyllo_e2e::binary("phyllo", "phyllo");
    let gen = phyllo_e2e::binary("phyllo-gen", "phyllo-gen");
    let target = phyllo
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>/phyllo")
        .to_path_buf();
    (target, phyllo, gen)
}

/// A deterministic shuffle (xorshift), so a failure reproduces.
fn shuffle<T>(v: &mut [T], mut seed: u64) {
    for i in (1..v.len()).rev() {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        v.swap(i, (seed % (i as u64 + 1)) as usize);
    }
}

/// Emergence-date errors (days, predicted minus truth) of the exported
/// `events` against `truth.csv`, matched by plant and leaf number, and how many
/// truth emergences are dateable (after a plant's first imaging day).
fn emergence_errors(
    truth: &[BTreeMap<String, String>],
    events: &[BTreeMap<String, String>],
) -> (Vec<f64>, usize) {
    let mut errs = Vec::new();
    let mut dateable = 0;
    let plants: std::collections::BTreeSet<String> = truth.iter().map(|t| t["plant"].clone()).collect();
    for p in plants {
        let first = truth.iter().find(|t| t["plant"] == p).unwrap()["date"].clone();
        let last = truth.iter().rev().find(|t| t["plant"] == p).unwrap();
        let dates: Vec<&str> = last["emergence_dates"]
            .split(';')
            .filter(|s| !s.is_empty())
            .collect();
        // Only emergences after the first imaging day can be dated from images.
        dateable += dates.iter().filter(|d| **d > first.as_str()).count();
        for e in events.iter().filter(|e| e["plant"] == p) {
            let leaf: usize = e["leaf"].parse().unwrap();
            if let Some(d) = dates.get(leaf - 1) {
                errs.push(days_between(d, &e["emerged_at"]));
            }
        }
    }
    (errs, dateable)
}

/// The truth.csv of a growth sequence, rendered (once, cached under `target`)
/// as one tiny view a day: only the truth matters to the timeline tests.
fn sequence_truth(
    target: &Path,
    gen: &Path,
    plants: u32,
    days: u32,
    seed: u32,
    start_age: u32,
) -> Vec<BTreeMap<String, String>> {
    sequence_truth_dir(target, gen, (plants, days, seed, start_age), None).1
}

/// As [`sequence_truth`], with the plants grown under `--climate` when one
/// is given; returns the sequence's folder (climate.csv is there) too.
fn sequence_truth_dir(
    target: &Path,
    gen: &Path,
    (plants, days, seed, start_age): (u32, u32, u32, u32),
    climate: Option<&str>,
) -> (PathBuf, Vec<BTreeMap<String, String>>) {
    let tag = climate.map_or(String::new(), |c| format!("-c{c}"));
    let dir = target.join(format!(
        "e2e-cache/truth-p{plants}-d{days}-s{seed}-a{start_age}{tag}"
    ));
    let age = start_age.to_string();
    let mut extra = vec![
        "--start-age",
        age.as_str(),
        "--views",
        "108",
        "--frame-height",
        "64",
    ];
    if let Some(c) = climate {
        extra.extend(["--climate", c]);
    }
    generate_sequence(gen, &dir, plants, days, seed, &extra);
    let truth = read_csv(&dir.join("truth.csv"));
    (dir, truth)
}

/// Runs `phyllo-gen sequence` into `dir` (a partial render resumes) with `extra` options.
fn generate_sequence(gen: &Path, dir: &Path, plants: u32, days: u32, seed: u32, extra: &[&str]) {
    let out = Command::new(gen)
        .args(["sequence", "--out"])
        .arg(dir)
        .args(["--plants", &plants.to_string(), "--days", &days.to_string()])
        .args(["--seed", &seed.to_string(), "--quiet"])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "phyllo-gen sequence: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A fresh store in a temporary folder, its config ending with `settings`:
/// (the folder, the config's path).
fn fresh_store(settings: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("phyllo.toml");
    write_config(
        &cfg,
        &dir.path().join("drop"),
        &dir.path().join("db.sqlite"),
        settings,
    );
    (dir, cfg)
}

/// The truth's living-leaf counts as a `phyllo import` CSV, the same count
/// in each of the five side views: the model taken out.
fn true_counts_in_five_views(truth: &[BTreeMap<String, String>]) -> String {
    let mut obs = String::from("plant,timestamp,view,leaf_count\n");
    for t in truth {
        for a in [0, 36, 72, 108, 144] {
            obs += &format!(
                "{},{}T{},SV_{a},{}\n",
                t["plant"], t["date"], t["time"], t["living_leaves"]
            );
        }
    }
    obs
}

/// Imports `obs` (a `phyllo import` CSV) into a fresh store whose config ends
/// with `settings`, and returns its exported emergence events.
fn import_and_export_events(phyllo: &Path, settings: &str, obs: &str) -> Vec<BTreeMap<String, String>> {
    let (dir, cfg) = fresh_store(settings);
    let obs_path = dir.path().join("counts.csv");
    std::fs::write(&obs_path, obs).unwrap();
    import(phyllo, &cfg, &obs_path);
    export(phyllo, &cfg, "events")
}

fn read_csv(path: &Path) -> Vec<BTreeMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let headers = r.headers().unwrap().clone();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            headers
                .iter()
                .zip(rec.iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

/// Runs `phyllo ARGS`, failing the test with its stderr unless it succeeds.
fn phyllo_ok(phyllo: &Path, args: &[&std::ffi::OsStr]) {
    let st = Command::new(phyllo).args(args).output().unwrap();
    assert!(
        st.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&st.stderr)
    );
}

/// Imports `csv` into the store of `cfg`.
fn import(phyllo: &Path, cfg: &Path, csv: &Path) {
    phyllo_ok(
        phyllo,
        &["import".as_ref(), "-c".as_ref(), cfg.as_os_str(), csv.as_os_str()],
    );
}

/// The store's `KIND.csv` export (`plants`, `events`, ...), written beside
/// `cfg` and read back.
fn export(phyllo: &Path, cfg: &Path, kind: &str) -> Vec<BTreeMap<String, String>> {
    let out = cfg.with_file_name(format!("{kind}.csv"));
    phyllo_ok(
        phyllo,
        &[
            "export".as_ref(),
            "-c".as_ref(),
            cfg.as_os_str(),
            "--what".as_ref(),
            kind.as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ],
    );
    read_csv(&out)
}

#[test]
fn daemon_counts_a_generated_sequence() {
    let (target, phyllo, gen) = binaries();
    let (plants, days, seed) = (env_or("PHYLLO_E2E_PLANTS", 3), env_or("PHYLLO_E2E_DAYS", 4), 11);
    let frames_dir = target.join(format!("e2e-cache/sequence-p{plants}-d{days}-s{seed}"));
    let t0 = Instant::now();
    generate_sequence(&gen, &frames_dir, plants, days, seed, &[]);
    eprintln!("generated {plants} plants x {days} days in {:.0?}", t0.elapsed());
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&frames_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    frames.sort();
    let n = frames.len();
    assert_eq!(n as u32, plants * days * 6, "frames written");

    let dir = tempfile::tempdir().unwrap();
    let drop_dir = dir.path().join("drop");
    std::fs::create_dir_all(&drop_dir).unwrap();
    let cfg = dir.path().join("phyllo.toml");
    write_config(
        &cfg,
        &drop_dir,
        &dir.path().join("state/phyllo.sqlite"),
        "[watch]\nstable_secs = 2.0\nsettle_ms = 200\npoll_ms = 100\n",
    );
    let log = std::fs::File::create(dir.path().join("serve.log")).unwrap();
    let mut serve = Command::new(&phyllo)
        .arg("serve")
        .arg("-c")
        .arg(&cfg)
        .stderr(log)
        .spawn()
        .unwrap();
    // tail starts before the service has created the database, and waits for it.
    let tail = spawn_tail(&cfg, &["--json"]);
    std::thread::sleep(Duration::from_secs(2));

    // Drop the frames: shuffled; a third written slowly through an open file,
    // a third written hidden and renamed into place, a third copied.
    let mut order = frames.clone();
    shuffle(&mut order, 0x5eed);
    let t_drop = Instant::now();
    for (i, src) in order.iter().enumerate() {
        let name = src.file_name().unwrap();
        let dst = drop_dir.join(name);
        match i % 3 {
            0 => {
                let bytes = std::fs::read(src).unwrap();
                let mut f = std::fs::File::create(&dst).unwrap();
                for chunk in bytes.chunks(bytes.len() / 4 + 1) {
                    f.write_all(chunk).unwrap();
                    f.flush().unwrap();
                    std::thread::sleep(Duration::from_millis(150));
                }
            }
            1 => {
                let tmp = drop_dir.join(format!(".{}.part", name.to_string_lossy()));
                std::fs::copy(src, &tmp).unwrap();
                std::fs::rename(&tmp, &dst).unwrap();
            }
            _ => {
                std::fs::copy(src, &dst).unwrap();
            }
        }
    }
    let status = |field: &str| -> i64 {
        let out = Command::new(&phyllo)
            .args(["status", "--json", "-c"])
            .arg(&cfg)
            .output()
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
        v["images"][field].as_i64().unwrap_or(-1)
    };
    let deadline = Instant::now() + Duration::from_secs(120 + 10 * n as u64);
    while status("counted") + status("failed") + status("duplicate") < n as i64 {
        if let Some(st) = serve.try_wait().unwrap() {
            panic!(
                "phyllo serve exited early ({st}): {}",
                std::fs::read_to_string(dir.path().join("serve.log")).unwrap()
            );
        }
        assert!(
            Instant::now() < deadline,
            "timed out; log:\n{}",
            std::fs::read_to_string(dir.path().join("serve.log")).unwrap()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    let took = t_drop.elapsed();
    std::thread::sleep(Duration::from_secs(1));
    assert_eq!(status("counted"), n as i64, "every image counted");
    assert_eq!(
        status("failed"),
        0,
        "no failures: {}",
        std::fs::read_to_string(dir.path().join("serve.log")).unwrap()
    );
    assert_eq!(status("duplicate"), 0);
    eprintln!(
        "{n} images counted in {took:.1?} after the first drop ({:.2} s/image)",
        took.as_secs_f64() / n as f64
    );

    // SIGTERM: clean stop, reported as such.
    signal(serve.id(), "TERM");
    let st = serve.wait().unwrap();
    assert!(st.success(), "phyllo serve exit status {st}");
    let out = Command::new(&phyllo)
        .args(["status", "--json", "-c"])
        .arg(&cfg)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["state"], "stopped");
    assert_eq!(v["counts_with_other_settings"], 0, "{v}");
    let (_, lines) = tail.stop();
    let counts: Vec<serde_json::Value> = lines
        .iter()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|r| r["kind"] == "count")
        .collect();
    let paths: HashSet<&str> = counts.iter().map(|r| r["path"].as_str().unwrap()).collect();
    assert_eq!(
        (counts.len(), paths.len()),
        (n, n),
        "tail saw every count exactly once"
    );

    // Exports parse, with one image row per frame.
    let out = Command::new(&phyllo)
        .args(["export", "-c"])
        .arg(&cfg)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let exports = dir.path().join("state/exports");
    let images = read_csv(&exports.join("images.csv"));
    assert_eq!(images.len(), n);
    assert!(images
        .iter()
        .all(|r| r["state"] == "counted" && r["version"] == "1"));
    // Each count names the settings it was made with.
    for r in &images {
        let settings: serde_json::Value = serde_json::from_str(&r["settings"]).unwrap();
        assert_eq!(settings["postprocess"]["split_min_area"], 128, "{r:?}");
    }
    // With the daemon stopped, `phyllo recount` reads every frame again and,
    // with the same model and settings, reproduces every count.
    let out = Command::new(&phyllo)
        .args(["recount", "-c"])
        .arg(&cfg)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains(&format!("recounted {n} images with ")) && stdout.contains(": 0 counts changed"),
        "{stdout}"
    );
    let sessions = read_csv(&exports.join("sessions.csv"));
    assert_eq!(
        sessions.len() as u32,
        plants * days,
        "one session per plant and day"
    );
    let timeline = read_csv(&exports.join("timeline.csv"));
    let events = read_csv(&exports.join("events.csv"));
    // Every leaf first counted after a plant's first session is placed on
    // an image of that session, and `timeline --sites` draws it there.
    let first_session = |plant: &str| {
        sessions
            .iter()
            .filter(|r| r["plant"] == plant)
            .map(|r| r["session_start"].clone())
            .min()
            .unwrap()
    };
    let later: Vec<_> = events
        .iter()
        .filter(|e| e["seen_at"] > first_session(&e["plant"]))
        .collect();
    for e in &later {
        assert!(
            e["site_view"].starts_with("SV_") && drop_dir.join(&e["site_image"]).exists(),
            "{e:?}"
        );
        assert!(e["site_image"].contains(&e["seen_at"][..10]), "{e:?}");
    }
    if !later.is_empty() {
        // The nightly export drew each plant's newest placed leaf and links it.
        let drawn = std::fs::read_dir(exports.join("sites")).unwrap().count();
        assert!(drawn >= 1);
        let page = std::fs::read_to_string(exports.join("index.html")).unwrap();
        assert!(
            page.contains("<th>newest leaf seen</th>") && page.contains("href=\"sites/"),
            "{page}"
        );
    }
    if let Some(e) = later.first() {
        let sites = dir.path().join("sites");
        let out = Command::new(&phyllo)
            .args(["timeline", "-c"])
            .arg(&cfg)
            .arg(&e["plant"])
            .arg("--sites")
            .arg(&sites)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let png = sites.join(format!(
            "{}-leaf-{:02}.png",
            e["plant"],
            e["leaf"].parse::<u32>().unwrap()
        ));
        let img = image::open(&png).unwrap_or_else(|err| panic!("{}: {err}", png.display()));
        assert!(img.width() > 0);
    }
    eprintln!(
        "leaf sites: {} events after a plant's first session, every one placed",
        later.len()
    );

    // Compare with the generator's truth.
    let truth = read_csv(&frames_dir.join("truth.csv"));
    let mut sq_living = 0.0;
    let mut sq_emerged = 0.0;
    for t in &truth {
        let row = timeline
            .iter()
            .find(|r| r["plant"] == t["plant"] && r["session_start"].starts_with(&t["date"]))
            .unwrap_or_else(|| panic!("no timeline row for {} {}", t["plant"], t["date"]));
        let f = |r: &BTreeMap<String, String>, k: &str| r[k].parse::<f64>().unwrap();
        sq_living += (f(row, "living") - f(t, "living_leaves")).powi(2);
        sq_emerged += (f(row, "leaves_emerged") - f(t, "leaves_emerged")).powi(2);
    }
    let (errs, truth_events) = emergence_errors(&truth, &events);
    let rows = truth.len() as f64;
    let mae = if errs.is_empty() {
        f64::NAN
    } else {
        errs.iter().map(|e| e.abs()).sum::<f64>() / errs.len() as f64
    };
    let bias = if errs.is_empty() {
        f64::NAN
    } else {
        errs.iter().sum::<f64>() / errs.len() as f64
    };
    eprintln!(
        "E2E vs truth.csv: {} plants x {} days; living leaves RMSE {:.2}, leaves emerged RMSE {:.2}; \
         emergence events: {} predicted, {} dateable in truth, {} matched by leaf number, MAE {:.2} days, bias {:+.2} days",
        plants,
        days,
        (sq_living / rows).sqrt(),
        (sq_emerged / rows).sqrt(),
        events.len(),
        truth_events,
        errs.len(),
        mae,
        bias
    );
}

/// Emergence-date error of the timeline itself, with the model taken out: the
/// generator's true living-leaf counts (exact, then with ±1 noise on a third of
/// the days) go through `phyllo import`, the same fusion and isotonic fit as
/// the model's counts, and the exported events are compared with `truth.csv`.
#[test]
fn timeline_recovers_emergence_dates_from_true_counts() {
    let (target, phyllo, gen) = binaries();
    let (plants, days, seed) = (10u32, 21u32, 11u32);
    let truth = sequence_truth(&target, &gen, plants, days, seed, 14);

    for (label, noisy) in [
        ("exact counts", false),
        ("counts with +-1 noise on 1/3 of days", true),
    ] {
        let mut obs = String::from("plant,timestamp,view,leaf_count\n");
        let mut rng = 0x9e3779b97f4a7c15u64;
        for t in &truth {
            let mut c: i64 = t["living_leaves"].parse().unwrap();
            if noisy {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                c += [0, 0, 0, 0, 1, -1][(rng % 6) as usize];
            }
            obs += &format!("{},{}T{},SV_108,{}\n", t["plant"], t["date"], t["time"], c.max(0));
        }
        let events = import_and_export_events(&phyllo, "", &obs);
        let (errs, dateable) = emergence_errors(&truth, &events);
        let mae = errs.iter().map(|e| e.abs()).sum::<f64>() / errs.len().max(1) as f64;
        let bias = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
        let within1 = errs.iter().filter(|e| e.abs() <= 1.0).count();
        eprintln!(
            "timeline from {label}: {plants} plants x {days} days; {} events predicted, {dateable} dateable in truth, \
             {} matched; emergence date MAE {mae:.2} days, bias {bias:+.2} days, {within1} within 1 day",
            events.len(),
            errs.len()
        );
        assert!(!errs.is_empty(), "{label}: no events matched");
        if !noisy {
            assert!(mae <= 1.5, "{label}: emergence date MAE {mae:.2} days");
        }
    }
}

/// Old plants lose leaves while new ones emerge. Fed the true living-leaf
/// counts in five side views, the timeline that reads lasting drops as leaves
/// lost (`death_penalty`, the default) dates the leaves after a death, where
/// the fit that reads none numbers them one low.
#[test]
fn timeline_reads_lost_leaves_from_true_counts() {
    let (target, phyllo, gen) = binaries();
    let (plants, days, seed, start_age) = (10u32, 18u32, 12u32, 30u32);
    let truth = sequence_truth(&target, &gen, plants, days, seed, start_age);
    let lost_days = truth
        .iter()
        .filter(|t| t["living_leaves"] != t["leaves_emerged"])
        .count();
    assert!(
        lost_days > 0,
        "the sequence should reach the plants' first deaths"
    );
    let obs = true_counts_in_five_views(&truth);
    let mut results = Vec::new();
    for (label, settings) in [
        ("death_penalty 0", "[timeline]\ndeath_penalty = 0.0\n"),
        ("the default death_penalty", ""),
    ] {
        let events = import_and_export_events(&phyllo, settings, &obs);
        let (errs, dateable) = emergence_errors(&truth, &events);
        let mae = errs.iter().map(|e| e.abs()).sum::<f64>() / errs.len().max(1) as f64;
        eprintln!(
            "timeline with {label}: {plants} plants x {days} days from age {start_age} \
             ({lost_days} plant-days after a death); {} of {dateable} leaves dated, MAE {mae:.2} days",
            errs.len()
        );
        results.push((errs.len(), mae));
    }
    let ((n_off, mae_off), (n_on, mae_on)) = (results[0], results[1]);
    assert!(
        n_on > n_off,
        "reading deaths dates more leaves: {n_on} against {n_off}"
    );
    assert!(
        mae_on < mae_off,
        "and dates them better: {mae_on:.2} against {mae_off:.2} days"
    );
    assert!(
        mae_on <= 1.5,
        "emergence date MAE {mae_on:.2} days from true counts"
    );
}

/// The least-squares slope of `ys` on `xs`.
fn slope(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

/// Per plant of a `--climate` sequence's truth, the true (days, degree-days)
/// per leaf over the leaves that emerged after its first imaging session.
fn true_phyllochrons(truth: &[BTreeMap<String, String>]) -> BTreeMap<String, (f64, f64)> {
    let mut out = BTreeMap::new();
    let plants: std::collections::BTreeSet<&String> = truth.iter().map(|t| &t["plant"]).collect();
    for p in plants {
        let first = truth.iter().find(|t| &t["plant"] == p).unwrap();
        let last = truth.iter().rev().find(|t| &t["plant"] == p).unwrap();
        let first_at = format!("{}T{}", first["date"], first["time"]);
        let leaves: Vec<(f64, f64, f64)> = last["emergence_at"]
            .split(';')
            .zip(last["emergence_cd"].split(';'))
            .enumerate()
            .filter(|(_, (at, _))| !at.is_empty() && *at > first_at.as_str())
            .map(|(k, (at, cd))| ((k + 1) as f64, days_between(&first_at, at), cd.parse().unwrap()))
            .collect();
        if leaves.len() >= 3 {
            let xs: Vec<f64> = leaves.iter().map(|l| l.0).collect();
            let days: Vec<f64> = leaves.iter().map(|l| l.1).collect();
            let cd: Vec<f64> = leaves.iter().map(|l| l.2).collect();
            out.insert(p.clone(), (slope(&xs, &days), slope(&xs, &cd)));
        }
    }
    out
}

/// The same plants grown in a cool and a warm compartment (`phyllo-gen
/// sequence --climate`), imaged by one station into one database whose config
/// declares the two as zones: fed their true living-leaf counts and each
/// compartment's temperature log (the zone named in the log's `zone` column),
/// phyllo's phyllochron in days per leaf follows the temperature, while its
/// degree-days per leaf stay with the truth's, which the climate does not
/// change. Both logs cover the same dates, so a plant timed by the other
/// compartment's log would be off by half or double.
#[test]
fn phyllochron_in_degree_days_holds_across_climates() {
    let (target, phyllo, gen) = binaries();
    let (store, cfg) = fresh_store(
        "[[timeline.zones]]\nname = 'cool'\nplants = '^cool-'\n[[timeline.zones]]\nname = 'warm'\nplants = '^warm-'\n",
    );
    // The same stretch of development in both (about 8 to 27 days at 25 °C):
    // the warm plants grow twice as fast, so they are imaged younger and for
    // fewer days, and neither reaches the leaf deaths living counts cannot date.
    let mut truths = Vec::new();
    for (zone, climate, start_age, days) in [("cool", "19", 14, 30), ("warm", "29", 7, 14)] {
        let (dir, truth) = sequence_truth_dir(&target, &gen, (8, days, 13, start_age), Some(climate));
        // The two sequences share plant ids: each compartment's get its name.
        let truth: Vec<BTreeMap<String, String>> = truth
            .into_iter()
            .map(|mut t| {
                let id = format!("{zone}-{}", t["plant"]);
                t.insert("plant".into(), id);
                t
            })
            .collect();
        let obs_path = store.path().join(format!("{zone}-counts.csv"));
        std::fs::write(&obs_path, true_counts_in_five_views(&truth)).unwrap();
        let log = std::fs::read_to_string(dir.join("climate.csv")).unwrap();
        let mut lines = log.lines();
        let mut zoned = format!("{},zone\n", lines.next().unwrap());
        for line in lines {
            zoned += &format!("{line},{zone}\n");
        }
        let log_path = store.path().join(format!("{zone}-climate.csv"));
        std::fs::write(&log_path, zoned).unwrap();
        import(&phyllo, &cfg, &obs_path);
        import(&phyllo, &cfg, &log_path);
        truths.push((zone, climate, truth));
    }
    let exported = export(&phyllo, &cfg, "plants");
    let mut means = Vec::new();
    for (zone, climate, truth) in &truths {
        let truth_values = true_phyllochrons(truth);
        let (mut days, mut cd, mut err) = ((0.0, 0.0), (0.0, 0.0), 0.0);
        let mut n = 0.0;
        for row in &exported {
            let (Some(&(true_days, true_cd)), Ok(got_days), Ok(got_cd)) = (
                truth_values.get(&row["plant"]),
                row["phyllochron_days"].parse::<f64>(),
                row["phyllochron_cd"].parse::<f64>(),
            ) else {
                continue;
            };
            days = (days.0 + got_days, days.1 + true_days);
            cd = (cd.0 + got_cd, cd.1 + true_cd);
            err += (got_cd - true_cd).abs() / true_cd;
            n += 1.0;
        }
        assert!(n >= 4.0, "zone {zone}: only {n} plants with both phyllochrons");
        eprintln!(
            "zone {zone} ({climate} °C): {n} plants; days per leaf {:.2} (truth {:.2}), degree-days per leaf {:.1} \
             (truth {:.1}), mean relative error {:.1} %",
            days.0 / n,
            days.1 / n,
            cd.0 / n,
            cd.1 / n,
            100.0 * err / n
        );
        assert!(
            err / n < 0.12,
            "zone {zone}: degree-days per leaf off by {:.1} %",
            100.0 * err / n
        );
        means.push((days.0 / n, cd.0 / n));
    }
    let (cool, warm) = (means[0], means[1]);
    assert!(
        cool.0 / warm.0 > 1.5,
        "days per leaf should follow the temperature: {cool:?} {warm:?}"
    );
    let cd_ratio = cool.1 / warm.1;
    assert!(
        (0.85..1.18).contains(&cd_ratio),
        "degree-days per leaf should not: {cool:?} {warm:?}"
    );
}

/// Over the plant-cuts of one climate's sequence: the summed absolute errors
/// (days) of phyllo's next-leaf forecast and of the plain one (a phyllochron
/// in days after the last leaf), phyllo's summed signed error, and how many.
/// Each cut also checks that `phyllo forecast` says what `plants.csv` says.
fn next_leaf_errors(climate: &str) -> [f64; 4] {
    let (target, phyllo, gen) = binaries();
    let (dir, truth) = sequence_truth_dir(&target, &gen, (8, 30, 13, 14), Some(climate));
    let log = std::fs::read_to_string(dir.join("climate.csv")).unwrap();
    let first_day = truth.iter().map(|t| t["date"].clone()).min().unwrap();
    let last_of: BTreeMap<&String, &BTreeMap<String, String>> =
        truth.iter().map(|t| (&t["plant"], t)).collect();
    let mut errors = [0.0; 4];
    for cut in [10.0, 12.0, 14.0, 16.0, 18.0, 20.0, 22.0, 24.0, 26.0] {
        let seen: Vec<BTreeMap<String, String>> = truth
            .iter()
            .filter(|t| days_between(&first_day, &t["date"]) < cut)
            .cloned()
            .collect();
        let now = seen
            .iter()
            .map(|t| days_between(&first_day, &format!("{}T{}", t["date"], t["time"])))
            .fold(f64::MIN, f64::max);
        let mut lines = log.lines();
        let mut log_so_far = format!("{}\n", lines.next().unwrap());
        for line in lines.filter(|l| days_between(&first_day, l) <= now) {
            log_so_far += &format!("{line}\n");
        }
        let (store, cfg) = fresh_store("");
        let obs = store.path().join("counts.csv");
        std::fs::write(&obs, true_counts_in_five_views(&seen)).unwrap();
        let log_path = store.path().join("climate.csv");
        std::fs::write(&log_path, log_so_far).unwrap();
        import(&phyllo, &cfg, &obs);
        import(&phyllo, &cfg, &log_path);
        let plants = export(&phyllo, &cfg, "plants");
        let out = Command::new(&phyllo)
            .args(["forecast", "--json", "-c"])
            .arg(&cfg)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let cli: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let cli: BTreeMap<&str, &str> = cli
            .as_array()
            .unwrap()
            .iter()
            .map(|r| (r["plant"].as_str().unwrap(), r["at"].as_str().unwrap()))
            .collect();
        for row in &plants {
            let (Ok(leaf), Ok(rate)) = (
                row["next_leaf"].parse::<usize>(),
                row["phyllochron_days"].parse::<f64>(),
            ) else {
                continue;
            };
            assert_eq!(
                cli.get(row["plant"].as_str()).copied(),
                Some(row["next_leaf_expected"].as_str()),
                "phyllo forecast and plants.csv disagree on {}",
                row["plant"]
            );
            let Some(true_at) = last_of[&row["plant"]]["emergence_at"].split(';').nth(leaf - 1) else {
                continue;
            };
            if true_at.is_empty() {
                continue;
            }
            let truth = days_between(&first_day, true_at);
            let got = days_between(&first_day, &row["next_leaf_expected"]);
            let plain = days_between(&first_day, &row["last_emergence"]) + rate;
            errors[0] += (got - truth).abs();
            errors[1] += (plain - truth).abs();
            errors[2] += got - truth;
            errors[3] += 1.0;
        }
    }
    errors
}

/// `phyllo`'s next-leaf forecast (`crate::forecast`), scored against the
/// generator's true emergence times in a steady cool house (19 °C) and one
/// whose weather wanders five times as far (`19,4,5`): each sequence's true living-leaf
/// counts and its temperature log are cut at every second day from day 10 to
/// 26 (the log at the last session's hour), each cut imported into a fresh
/// store as if that day were today, and every plant's forecast leaf is looked
/// up in the truth. phyllo forecasts by thermal time (one phyllochron in
/// degree-days after the last leaf, past the log's end at its last three
/// days' warmth); the same plants' phyllochron in days after the last leaf
/// is the plain forecast it is set against.
#[test]
fn next_leaf_forecast_against_the_truth() {
    for climate in ["19", "19,4,5"] {
        let [err, plain, bias, n] = next_leaf_errors(climate);
        eprintln!(
            "climate {climate}: next-leaf forecast over {n} plant-cuts off by {:.2} days on average \
             (bias {:+.2}) by thermal time, {:.2} by days",
            err / n,
            bias / n,
            plain / n
        );
        assert!(n >= 40.0, "only {n} forecasts scored");
        assert!(err / n < 1.5, "forecast off by {:.2} days on average", err / n);
        assert!(err < plain, "thermal time should forecast better than days");
    }
}
