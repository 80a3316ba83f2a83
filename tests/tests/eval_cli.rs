//! `phyllo eval` end to end: a fresh phyllo-gen dataset and the real
//! development counts through the real binary.

use std::process::Command;

use phyllo_e2e::{binary, dev_data, phyllo, run, untrained_model};
use serde_json::Value;

#[test]
fn evaluates_a_generated_dataset_against_its_labels() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("ds");
    generate_seed_77(&data);
    let plots = tmp.path().join("plots");
    let (out, stdout, stderr) = run(phyllo()
        .args(["eval", "--split", "all", "--json", "--per-image", "--model"])
        .arg(untrained_model())
        .arg("--dataset")
        .arg(&data)
        .arg("--plots")
        .arg(&plots));
    assert!(out.status.success(), "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["metrics"]["images"], 4);
    // The same command elsewhere renders the same data, and the fingerprint
    // says so: what makes a rerun comparable with a number in MODEL.md. Read
    // without a model (--fingerprint-only), it is the full evaluation's.
    let again = tmp.path().join("again");
    generate_seed_77(&again);
    let fingerprint = |dir: &std::path::Path| {
        let (out, stdout, stderr) = run(phyllo()
            .args(["eval", "--fingerprint-only", "--split", "all", "--json"])
            .arg("--dataset")
            .arg(dir));
        assert!(out.status.success(), "{stderr}");
        let v: Value = serde_json::from_str(stdout.trim()).unwrap();
        assert_eq!(v["items"], 4, "{v}");
        v["fingerprint"].as_str().unwrap().to_string()
    };
    assert_eq!(v["fingerprint"].as_str().unwrap().len(), 16, "{v}");
    assert_eq!(fingerprint(&again), v["fingerprint"].as_str().unwrap());
    assert!(
        v["mean_iou"].as_f64().is_some() && v["panoptic_quality"].as_f64().is_some(),
        "{v}"
    );
    // The eval's truth is read from the label PNGs; by default it must agree
    // with the generator's own list of visible leaves in the manifest.
    let manifest = std::fs::read_to_string(data.join("manifest.jsonl")).unwrap();
    let rows: Vec<Value> = manifest
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    for img in v["images"].as_array().unwrap() {
        let file = img["file"].as_str().unwrap();
        let row = rows
            .iter()
            .find(|r| file.ends_with(r["image"].as_str().unwrap()))
            .unwrap();
        let visible = row["leaf_pixels"].as_object().unwrap().len();
        assert_eq!(img["truth"].as_u64().unwrap() as usize, visible, "{file}");
    }
    // Every true leaf of every image lands in exactly one leaf-error cell.
    let truth_total: u64 = v["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["truth"].as_u64().unwrap())
        .sum();
    let classed: u64 = v["leaf_errors"]["true_leaves"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| ["found", "partly_found", "merged", "not_seen"].map(|k| r[k].as_u64().unwrap()))
        .sum();
    assert_eq!(classed, truth_total, "{}", v["leaf_errors"]);
    for p in ["scatter.png", "error_histogram.png"] {
        let img = image::open(plots.join(p)).unwrap();
        assert!(img.width() > 300, "{p}");
    }

    // `--truth-min-pixels 96` counts only leaves of at least 96 px.
    let (out, stdout, stderr) = run(phyllo()
        .args([
            "eval",
            "--split",
            "all",
            "--json",
            "--per-image",
            "--truth-min-pixels",
            "96",
            "--model",
        ])
        .arg(untrained_model())
        .arg("--dataset")
        .arg(&data));
    assert!(out.status.success(), "{stderr}");
    let large: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert!(
        large["source"].as_str().unwrap().contains("at least 96 px"),
        "{large}"
    );
    let truths = |v: &Value| -> Vec<u64> {
        v["images"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| i["truth"].as_u64().unwrap())
            .collect()
    };
    let countable: Vec<u64> = v["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|img| {
            let file = img["file"].as_str().unwrap();
            let row = rows
                .iter()
                .find(|r| file.ends_with(r["image"].as_str().unwrap()))
                .unwrap();
            row["leaf_pixels"]
                .as_object()
                .unwrap()
                .values()
                .filter(|a| a.as_u64().unwrap() >= 96)
                .count() as u64
        })
        .collect();
    assert_eq!(truths(&large), countable);
}

#[test]
fn evaluates_real_images_with_human_counts() {
    let dev = dev_data().expect("development data beside the repo");
    let (out, stdout, stderr) = run(phyllo()
        .args(["eval", "--json", "--model"])
        .arg(untrained_model())
        .arg("--counts")
        .arg(dev.join("leaf_tips.csv"))
        .arg("--images")
        .arg(dev.join("images")));
    assert!(out.status.success(), "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["metrics"]["images"], 10);
    assert_eq!(
        v["fingerprint"].as_str(),
        Some(recorded_fingerprint("real-frames").as_str()),
        "the development frames or their counts changed: models/eval-sets.tsv no longer names them"
    );
    // The crops' fingerprint, read without a model, is the recorded one too.
    let (out, stdout, stderr) = run(phyllo()
        .args(["eval", "--fingerprint-only", "--counts"])
        .arg(dev.join("crops_counts.csv"))
        .arg("--images")
        .arg(dev.join("crops")));
    assert!(out.status.success(), "{stderr}");
    let data_line = stdout
        .lines()
        .find(|l| l.starts_with("data "))
        .unwrap_or_default();
    assert!(
        data_line.contains(&recorded_fingerprint("real-crops")),
        "{stdout}"
    );
    assert!(v["per_view"]["SV_108"]["images"] == 10, "{v}");
    let confusion_total: u64 = v["confusion"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r[2].as_u64().unwrap())
        .sum();
    assert_eq!(confusion_total, 10);
    // Ten images pin little down: the intervals hold the point estimates and are wide.
    for (metric, share) in [
        ("exact", true),
        ("within_1", true),
        ("rmse", false),
        ("bias", false),
    ] {
        let (lo, hi) = (
            v["intervals"][metric]["lo"].as_f64().unwrap(),
            v["intervals"][metric]["hi"].as_f64().unwrap(),
        );
        let point = v["metrics"][metric].as_f64().unwrap();
        assert!(
            lo <= point && point <= hi,
            "{metric}: {point} outside [{lo}, {hi}]"
        );
        if share {
            assert!(
                hi - lo > 0.2 && (0.0..=1.0).contains(&lo) && hi <= 1.0,
                "{metric}: [{lo}, {hi}]"
            );
        }
    }
}

#[test]
fn real_frames_with_marked_tips_get_a_tip_table() {
    let dev = dev_data().expect("development data beside the repo");
    let overlays = tempfile::tempdir().unwrap();
    let (out, stdout, stderr) = run(phyllo()
        .args(["eval", "--json", "--per-image", "--counts"])
        .arg(dev.join("leaf_tips.csv"))
        .arg("--images")
        .arg(dev.join("images"))
        .arg("--tip-overlays")
        .arg(overlays.path()));
    assert!(out.status.success(), "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    let tips = &v["tip_errors"];
    assert_eq!(tips["images"], 10, "{v}");
    let n = |o: &Value, k: &str| o[k].as_i64().unwrap_or_else(|| panic!("{k} in {o}"));
    let extra = |o: &Value| {
        o["extra"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_i64().unwrap())
            .sum::<i64>()
    };
    // leaf_tips.csv's leaf_count is its number of marked tips.
    let human: i64 = v["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| n(p, "truth"))
        .sum();
    let predicted: i64 = v["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| n(p, "predicted"))
        .sum();
    assert_eq!(n(&tips["total"], "tips"), human);
    assert_eq!(n(&tips["total"], "predicted"), predicted);
    // Each image's count error splits exactly into missed, merged and extra leaves.
    for row in v["tip_outcomes"].as_array().unwrap() {
        let t = &row["tips"];
        assert_eq!(
            n(t, "tips") - n(t, "predicted"),
            n(t, "unreached") + n(t, "merged_away") - extra(t),
            "{row}"
        );
        assert_eq!(
            n(t, "tips"),
            n(t, "own_leaf") + n(t, "sharing") + n(t, "unreached"),
            "{row}"
        );
    }
    // The shipped model reaches most tips with a leaf of their own.
    assert!(n(&tips["total"], "own_leaf") * 2 > human, "{tips}");
    // One overlay per annotated frame, at the frame's size.
    for row in v["tip_outcomes"].as_array().unwrap() {
        let file = std::path::Path::new(row["file"].as_str().unwrap());
        let name = format!("{}.tips.png", file.file_stem().unwrap().to_string_lossy());
        let drawn = image::open(overlays.path().join(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(drawn.width(), image::image_dimensions(file).unwrap().0, "{name}");
    }
}

#[test]
fn segment_table_lists_every_predicted_leaf_with_its_fate() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("ds");
    generate_seed_77(&data);
    let table = tmp.path().join("segments.tsv");
    let (out, stdout, stderr) = run(phyllo()
        .args(["eval", "--split", "all", "--json", "--per-image", "--model"])
        .arg(phyllo_e2e::repo_root().join("models/phyllo.onnx"))
        .arg("--dataset")
        .arg(&data)
        .arg("--segments")
        .arg(&table));
    assert!(out.status.success(), "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    let mut rows = csv::ReaderBuilder::new()
        .delimiter(b'\t')
        .from_path(&table)
        .unwrap();
    let header: Vec<String> = rows.headers().unwrap().iter().map(str::to_string).collect();
    assert_eq!(header[..5], ["image", "truth", "predicted", "segment", "kind"]);
    let rows: Vec<csv::StringRecord> = rows.records().map(Result::unwrap).collect();
    // The shipped model finds leaves on every plant: one row for each.
    let counted: u64 = v["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["predicted"].as_u64().unwrap())
        .sum();
    assert!(counted > 0, "{v}");
    assert!(
        rows.len() as u64 >= counted,
        "{} rows, {counted} leaves counted",
        rows.len()
    );
    for r in &rows {
        let img = v["images"]
            .as_array()
            .unwrap()
            .iter()
            .find(|i| i["file"].as_str().unwrap().ends_with(&r[0]))
            .unwrap_or_else(|| panic!("row for an image eval did not report: {r:?}"));
        assert_eq!(r[1].parse::<u64>().unwrap(), img["truth"].as_u64().unwrap());
        assert_eq!(r[2].parse::<u64>().unwrap(), img["predicted"].as_u64().unwrap());
    }
    // The rows' extra leaves are the leaf-error table's, kind by kind.
    let kinds = |k: &str| rows.iter().filter(|r| &r[4] == k).count() as u64;
    let extra = &v["leaf_errors"]["extra"];
    assert_eq!(kinds("split"), extra["split"].as_u64().unwrap(), "{extra}");
    assert_eq!(kinds("on_stem"), extra["on_stem"].as_u64().unwrap(), "{extra}");
    assert_eq!(
        kinds("on_background"),
        extra["on_background"].as_u64().unwrap(),
        "{extra}"
    );
    assert!(
        kinds("found") + kinds("partner") > 0,
        "the shipped model finds some true leaves: {rows:?}"
    );
}

/// The fingerprint `models/eval-sets.tsv` records for a set.
fn recorded_fingerprint(set: &str) -> String {
    let path = phyllo_e2e::repo_root().join("models/eval-sets.tsv");
    let text = std::fs::read_to_string(&path).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .find_map(|l| {
            let mut cols = l.split('\t');
            (cols.next() == Some(set)).then(|| cols.next().unwrap_or("").to_string())
        })
        .unwrap_or_else(|| panic!("{} has no row {set:?}", path.display()))
}

/// Two plants of seed 77, two views each, into `dir`.
fn generate_seed_77(dir: &std::path::Path) {
    let (out, _, stderr) = run(Command::new(binary("phyllo-gen", "phyllo-gen"))
        .args([
            "dataset", "--plants", "2", "--seed", "77", "--views", "0,108", "--quiet", "--out",
        ])
        .arg(dir));
    assert!(out.status.success(), "phyllo-gen: {stderr}");
}

/// The model-card scripts read `phyllo eval --json` through
/// `scripts/eval_json.py`; its row must be the text table's row.
#[test]
fn script_rows_from_json_match_the_text_table() {
    let dev = dev_data().expect("development data beside the repo");
    let eval = |json: bool| {
        let mut cmd = phyllo();
        cmd.args(["eval", "--model"])
            .arg(untrained_model())
            .arg("--counts")
            .arg(dev.join("crops_counts.csv"))
            .arg("--images")
            .arg(dev.join("crops"));
        if json {
            cmd.arg("--json");
        }
        let (out, stdout, stderr) = run(&mut cmd);
        assert!(out.status.success(), "{stderr}");
        stdout
    };
    let text = eval(false);
    let table_row = text
        .lines()
        .skip_while(|l| !l.starts_with("| images"))
        .nth(2)
        .expect("a metrics row under the table's header")
        .to_string();
    let mut script = Command::new("python3")
        .arg(phyllo_e2e::repo_root().join("scripts/eval_json.py"))
        .args(["row", "LABEL"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs scripts/eval_json.py");
    use std::io::Write;
    script
        .stdin
        .take()
        .unwrap()
        .write_all(eval(true).as_bytes())
        .unwrap();
    let out = script.wait_with_output().unwrap();
    assert!(out.status.success());
    let script_row = String::from_utf8(out.stdout).unwrap();
    assert_eq!(script_row.trim(), format!("| LABEL {}", table_row.trim()));
}

/// The separate-pieces stage (on by default) only ever adds leaves, and every
/// evaluation records whether it ran, in its JSON and on its text `post` line.
#[test]
fn separate_pieces_stage_only_adds_leaves_and_is_recorded() {
    let dev = dev_data().expect("development data beside the repo");
    let eval = |extra: &[&str]| {
        let (out, stdout, stderr) = run(phyllo()
            .args(["eval", "--per-image", "--threads", "2", "--counts"])
            .arg(dev.join("crops_counts.csv"))
            .arg("--images")
            .arg(dev.join("crops"))
            .args(extra));
        assert!(out.status.success(), "{stderr}");
        stdout
    };
    let on: Value = serde_json::from_str(eval(&["--json"]).trim()).unwrap();
    let off = eval(&["--split-min-area", "0"]);
    assert_eq!(on["postprocess"]["split_min_area"], 128, "{}", on["postprocess"]);
    assert!(
        off.lines()
            .any(|l| l.starts_with("post ") && l.contains("separate pieces as leaves off")),
        "{off}"
    );
    let with: Vec<(String, u64)> = on["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            (
                i["file"].as_str().unwrap().to_string(),
                i["predicted"].as_u64().unwrap(),
            )
        })
        .collect();
    // Per-image text lines: file, view, `true N`, `predicted M`.
    let without: Vec<(String, u64)> = off
        .lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('\t').collect();
            let predicted = cells.get(3)?.strip_prefix("predicted ")?.parse().ok()?;
            Some((cells[0].to_string(), predicted))
        })
        .collect();
    assert_eq!((with.len(), without.len()), (60, 60));
    let mut changed = 0;
    for ((file, a), (file_off, b)) in with.iter().zip(&without) {
        assert_eq!(file, file_off);
        assert!(a >= b, "{file}: {b} leaves without the stage, {a} with it");
        changed += usize::from(a > b);
    }
    // Some real crops show a leaf instance in separate pieces.
    assert!(changed > 0);
}
