//! `phyllo count` end to end: the real binary, real ONNX Runtime, real images.

use std::path::{Path, PathBuf};

use phyllo_e2e::{dev_data, phyllo, run, untrained_model};
use serde_json::Value;

fn json_lines(stdout: &str) -> Vec<Value> {
    stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("bad JSON line {l:?}: {e}")))
        .collect()
}

fn dev_images(sub: &str, n: usize) -> Vec<PathBuf> {
    let Some(dir) = dev_data() else {
        panic!("development data not found: expected ../shared/data/unl-maize-dev beside the repo or PHYLLO_DEV_DATA");
    };
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir.join(sub))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v.truncate(n);
    v
}

/// `phyllo count --json` with the untrained model (fast; the region and the
/// JSON shape do not depend on the weights).
fn count_json_untrained(files: &[PathBuf]) -> (std::process::Output, String, String) {
    run(phyllo()
        .arg("count")
        .arg("--json")
        .arg("--model")
        .arg(untrained_model())
        .args(files))
}

#[test]
fn counts_real_frames_and_crops_as_json() {
    let mut files = dev_images("images", 3);
    files.extend(dev_images("crops", 3));
    let (out, stdout, stderr) = count_json_untrained(&files);
    assert!(out.status.success(), "stderr: {stderr}");
    assert!(
        stderr.contains("UNTRAINED"),
        "an untrained model must be flagged: {stderr}"
    );
    let lines = json_lines(&stdout);
    assert_eq!(lines.len(), files.len());
    for (v, f) in lines.iter().zip(&files) {
        assert_eq!(v["file"].as_str().unwrap(), f.to_str().unwrap());
        assert!(v["leaf_count"].as_u64().is_some(), "{v}");
        assert!(v["instances"].is_array());
        assert!(v["tiles"].as_u64().unwrap() >= 1);
        for stage in ["decode", "tile", "inference", "postprocess", "total"] {
            assert!(v["ms"][stage].as_f64().unwrap() >= 0.0, "{stage} in {v}");
        }
        let n_leaves = v["instances"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|i| i["class"] == 1)
            .count();
        assert_eq!(n_leaves as u64, v["leaf_count"].as_u64().unwrap());
        assert!(v["model"].as_str().unwrap().contains('@'));
    }
    // Full frames are recognised by aspect ratio and crops are not.
    assert_eq!(lines[0]["image_size"], serde_json::json!([1227, 1028]));
}

#[test]
fn bad_inputs_give_error_lines_and_the_others_still_count() {
    let tmp = tempfile::tempdir().unwrap();
    let good = dev_images("crops", 1).remove(0);
    let empty = tmp.path().join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let text = tmp.path().join("notes.jpg");
    std::fs::write(&text, b"plant 12 had 7 leaves\n").unwrap();
    let truncated = tmp.path().join("truncated.jpg");
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 3]).unwrap();
    let dir = tmp.path().join("folder.png");
    std::fs::create_dir(&dir).unwrap();
    let missing = tmp.path().join("missing.png");
    let files = [
        empty.clone(),
        good.clone(),
        text.clone(),
        truncated.clone(),
        dir.clone(),
        missing.clone(),
    ];
    let (out, stdout, _) = run(phyllo()
        .arg("count")
        .arg("--json")
        .arg("--model")
        .arg(untrained_model())
        .args(&files));
    assert_eq!(
        out.status.code(),
        Some(1),
        "any failed input makes the exit status non-zero"
    );
    let lines = json_lines(&stdout);
    assert_eq!(lines.len(), files.len());
    let expect = [
        (&empty, "empty"),
        (&text, "not a PNG, JPEG or TIFF"),
        (&truncated, "corrupt or truncated"),
        (&dir, "directory"),
        (&missing, "cannot read"),
    ];
    for (path, why) in expect {
        let v = lines
            .iter()
            .find(|v| v["file"].as_str() == path.to_str())
            .unwrap();
        let err = v["error"]
            .as_str()
            .unwrap_or_else(|| panic!("expected an error for {}: {v}", path.display()));
        assert!(
            err.contains(path.to_str().unwrap()),
            "error names the file: {err}"
        );
        assert!(err.contains(why), "error says why ({why}): {err}");
    }
    let ok = lines
        .iter()
        .find(|v| v["file"].as_str() == good.to_str())
        .unwrap();
    assert!(ok["leaf_count"].is_u64(), "the good image still counted: {ok}");
}

#[test]
fn overlay_is_a_png_of_the_input_size() {
    let tmp = tempfile::tempdir().unwrap();
    let img = dev_images("images", 1).remove(0);
    let (out, _, stderr) = run(phyllo()
        .arg("count")
        .arg("--model")
        .arg(untrained_model())
        .arg("--overlay")
        .arg(tmp.path())
        .arg(&img));
    assert!(out.status.success(), "{stderr}");
    let stem = img.file_stem().unwrap().to_string_lossy().into_owned();
    let overlay = image::open(tmp.path().join(format!("{stem}.overlay.png"))).unwrap();
    assert_eq!((overlay.width(), overlay.height()), (1227, 1028));
}

/// Backlit lower leaves are dark olive; the plant region must still reach
/// them, or their instances are dropped as lying outside the plant.
#[test]
fn plant_region_reaches_the_dark_lower_leaves_of_a_real_crop() {
    let dir = dev_data().expect("development data");
    // A tall maize plant whose lowest leaves hang down to y = 690 of 751.
    let img = dir.join("crops/81-133-Tzi25_2018-09-18_12-47-11_Vis_SV_108.Crp.jpg");
    let (out, stdout, stderr) = count_json_untrained(&[img]);
    assert!(out.status.success(), "{stderr}");
    let v = &json_lines(&stdout)[0];
    let region: Vec<u64> = v["region"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap())
        .collect();
    assert!(region[3] >= 690, "region {region:?} cuts off the lower leaves");
    assert!(region[1] <= 60, "region {region:?} cuts off the top leaves");
}

fn count_with(model: &Path, envs: &[(&str, &str)]) -> (i32, String) {
    let img = dev_images("crops", 1).remove(0);
    let mut cmd = phyllo();
    cmd.arg("count").arg("--model").arg(model).arg(img);
    for (k, v) in envs {
        cmd.env(k, v);
    }
    let (out, _, stderr) = run(&mut cmd);
    (out.status.code().unwrap_or(-1), stderr)
}

#[test]
fn missing_or_wrong_onnx_runtime_is_a_one_line_error_naming_the_path() {
    let (code, err) = count_with(
        &untrained_model(),
        &[("PHYLLO_ORT_LIB", "/nonexistent/libonnxruntime.so")],
    );
    assert_eq!(code, 2);
    assert!(
        err.contains("/nonexistent/libonnxruntime.so") && err.contains("no such file"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    // A real shared library that is not ONNX Runtime.
    let libc = [
        "/lib/x86_64-linux-gnu/libc.so.6",
        "/usr/lib/x86_64-linux-gnu/libc.so.6",
    ]
    .into_iter()
    .find(|p| Path::new(p).exists());
    if let Some(libc) = libc {
        let (code, err) = count_with(&untrained_model(), &[("PHYLLO_ORT_LIB", libc)]);
        assert_eq!(code, 2);
        assert!(err.contains(libc) && err.contains("OrtGetApiBase"), "{err}");
    }
}

#[test]
fn unreadable_and_wrong_contract_models_are_refused_with_the_reason() {
    let tmp = tempfile::tempdir().unwrap();
    let (code, err) = count_with(&tmp.path().join("nope.onnx"), &[]);
    assert_eq!(code, 2);
    assert!(err.contains("nope.onnx") && err.contains("cannot read"), "{err}");

    let text = tmp.path().join("text.onnx");
    std::fs::write(&text, b"this is not a model").unwrap();
    let (code, err) = count_with(&text, &[]);
    assert_eq!(code, 2);
    assert!(
        err.contains("text.onnx") && err.contains("not a loadable ONNX model"),
        "{err}"
    );

    // The same network stamped with another contract version: patch the
    // metadata value that follows the key in the protobuf.
    let mut bytes = std::fs::read(untrained_model()).unwrap();
    let key = b"phyllo.contract_version";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("metadata key present");
    let value_at = at + key.len() + 2; // field tag + length byte of the value
    assert_eq!(bytes[value_at], b'1');
    bytes[value_at] = b'7';
    let wrong = tmp.path().join("wrong-contract.onnx");
    std::fs::write(&wrong, &bytes).unwrap();
    let (code, err) = count_with(&wrong, &[]);
    assert_eq!(code, 2);
    assert!(
        err.contains("wrong-contract.onnx") && err.contains("does not follow phyllo contract"),
        "{err}"
    );
    assert!(
        err.contains("\"7\"") && err.contains("needs"),
        "says what differs: {err}"
    );
}

/// Renders plant seed 3 with `phyllo-gen render` and `args` into `dir`;
/// returns the frame's path and what the generator said of it.
fn render_frame(dir: &Path, args: &[&str]) -> (PathBuf, String) {
    let gen = phyllo_e2e::binary("phyllo-gen", "phyllo-gen");
    let out = dir.join(format!("{}.png", args.join("").replace('-', "")));
    let (o, stdout, e) = run(std::process::Command::new(&gen)
        .args(["render", "--seed", "3", "--spp", "4"])
        .args(args)
        .arg("--out")
        .arg(&out));
    assert!(o.status.success(), "phyllo-gen render: {e}");
    (out, stdout)
}

/// `phyllo count --json` with the shipped model and `extra` arguments on
/// `files`, one JSON object per file.
fn count_shipped(extra: &[&str], files: &[&Path]) -> Vec<Value> {
    let model = phyllo_e2e::repo_root().join("models/phyllo.onnx");
    let (out, stdout, stderr) = run(phyllo()
        .args(["count", "--json", "--threads", "1", "--model"])
        .arg(&model)
        .args(extra)
        .args(files));
    assert!(out.status.success(), "{stderr}");
    json_lines(&stdout)
}

/// The contract's zoom with the shipped model: a seedling (its leaves span
/// far fewer than `zoom_plant_height` rows) is counted a second time,
/// enlarged to the cap, a grown plant less, and a plant that already spans
/// the zoom height not at all; `--zoom-height 0` turns it off.
#[test]
fn seedlings_are_counted_again_enlarged_and_grown_plants_are_not() {
    let tmp = tempfile::tempdir().unwrap();
    let (seedling, _) = render_frame(tmp.path(), &["--age", "20"]);
    let (grown, _) = render_frame(tmp.path(), &["--age", "50"]);
    let count = |extra: &[&str]| count_shipped(extra, &[&seedling, &grown]);
    let zoomed = count(&[]);
    let seed_scale = zoomed[0]["scale"].as_f64().unwrap();
    assert!(seed_scale > 1.5 && seed_scale <= 2.0 + 1e-6, "{}", zoomed[0]);
    assert!(
        zoomed[0]["tiles"].as_u64().unwrap() >= 2,
        "two passes: {}",
        zoomed[0]
    );
    assert!(zoomed[0]["leaf_count"].as_u64().unwrap() >= 3, "{}", zoomed[0]);
    let grown_scale = zoomed[1]["scale"].as_f64().unwrap();
    assert!(grown_scale < seed_scale, "{}", zoomed[1]);
    // The grown plant spans about 360 rows: past a 320-row zoom height.
    let low = count(&["--zoom-height", "320"]);
    assert_eq!(low[1]["scale"].as_f64().unwrap(), 1.0, "{}", low[1]);
    // Instances map back to the original frame whatever the enlargement.
    for inst in zoomed[0]["instances"].as_array().unwrap() {
        let b = inst["bbox"].as_array().unwrap();
        assert!(
            b[2].as_u64().unwrap() <= 614 && b[3].as_u64().unwrap() <= 514,
            "{inst}"
        );
    }
    let off = count(&["--zoom-height", "0"]);
    assert_eq!(off[0]["scale"].as_f64().unwrap(), 1.0, "{}", off[0]);
    assert_eq!(off[0]["tiles"].as_u64().unwrap(), 1, "{}", off[0]);
}

/// Issue 41: the same plant rendered at camera zoom 1 and 2 is brought to
/// the same scale by the back panel measured in each frame, and counted
/// alike; `--camera-zoom contract` leaves the zoomed frame at twice the
/// size, and a pinned zoom is taken as given.
#[test]
fn a_zoomed_camera_is_measured_and_counted_as_the_unzoomed_one() {
    let tmp = tempfile::tempdir().unwrap();
    // Four weeks old: at zoom 2 the whole plant still fits in the frame.
    let frame = |zoom: &str| {
        let (out, said) = render_frame(tmp.path(), &["--age", "28", "--zoom", zoom]);
        assert!(said.contains("8 visible"), "{said}");
        out
    };
    let (one, two) = (frame("1"), frame("2"));
    let count = |extra: &[&str]| count_shipped(extra, &[&one, &two]);
    let measured = count(&[]);
    let camera = |v: &Value| v["camera"].clone();
    for v in &measured {
        assert_eq!(camera(v)["source"], "back-panel", "{v}");
    }
    assert_eq!(camera(&measured[0])["camera_zoom"].as_f64().unwrap(), 1.0);
    let z = camera(&measured[1])["camera_zoom"].as_f64().unwrap();
    assert!((z / 2.0 - 1.0).abs() < 0.06, "measured zoom {z}");
    // The plant's size at the model: the scale times the true zoom.
    let s1 = camera(&measured[0])["scale"].as_f64().unwrap();
    let s2 = camera(&measured[1])["scale"].as_f64().unwrap() * 2.0;
    assert!((s2 / s1 - 1.0).abs() < 0.06, "{s1} against {s2}");
    assert_eq!(measured[0]["leaf_count"], measured[1]["leaf_count"]);
    // The panel's edges lie about twice as far apart in the zoomed frame.
    let width = |v: &Value| {
        let p = &camera(v)["panel"];
        p["right"].as_f64().unwrap() - p["left"].as_f64().unwrap()
    };
    assert!((width(&measured[1]) / width(&measured[0]) / 2.0 - 1.0).abs() < 0.03);

    let contract = count(&["--camera-zoom", "contract"]);
    assert_eq!(camera(&contract[1])["source"], "contract");
    assert_eq!(camera(&contract[1])["scale"].as_f64().unwrap(), 1.0);
    let pinned = count(&["--camera-zoom", "2"]);
    assert_eq!(camera(&pinned[1])["source"], "pinned");
    assert_eq!(camera(&pinned[1])["scale"].as_f64().unwrap(), 0.5);
}

/// A frame stored on its side with an EXIF orientation tag is counted as the
/// upright frame: same size, same leaves (PNG keeps the pixels exact).
#[test]
fn exif_orientation_is_applied_before_counting() {
    use image::{codecs::png::PngEncoder, ImageEncoder};
    let src = dev_images("images", 1).remove(0);
    let upright = image::open(&src).unwrap().to_rgb8();
    let on_side = image::imageops::rotate270(&upright);
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, img: &image::RgbImage, orientation: Option<u8>| {
        let path = dir.path().join(name);
        let mut bytes = Vec::new();
        let mut enc = PngEncoder::new(&mut bytes);
        if let Some(o) = orientation {
            // Little-endian TIFF header, one IFD entry: Orientation (0x0112), SHORT, 1, value.
            let mut exif = b"II*\0\x08\0\0\0\x01\0\x12\x01\x03\0\x01\0\0\0".to_vec();
            exif.extend_from_slice(&[o, 0, 0, 0, 0, 0, 0, 0]);
            enc.set_exif_metadata(exif).unwrap();
        }
        enc.write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
        std::fs::write(&path, bytes).unwrap();
        path
    };
    let files = [
        write("upright.png", &upright, None),
        write("side.png", &on_side, Some(6)),
    ];
    let model = phyllo_e2e::repo_root().join("models/phyllo.onnx");
    let (out, stdout, stderr) = run(phyllo()
        .args(["count", "--json", "--threads", "1", "--model"])
        .arg(&model)
        .args(&files));
    assert!(out.status.success(), "{stderr}");
    let lines = json_lines(&stdout);
    assert_eq!(lines[1]["image_size"], lines[0]["image_size"], "{stdout}");
    assert_eq!(lines[1]["leaf_count"], lines[0]["leaf_count"], "{stdout}");
    assert!(lines[0]["leaf_count"].as_u64().unwrap() >= 4, "{stdout}");
}

/// `phyllo count … | head -1`: the reader leaves after one line and the
/// command ends without a panic or a "Broken pipe" message.
#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    use std::io::{BufRead, BufReader};
    let files = dev_images("crops", 6);
    let mut child = phyllo()
        .args(["count", "--json", "--threads", "1", "--model"])
        .arg(untrained_model())
        .args(&files)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("leaf_count"), "{first}");
    // The reader is gone now: the next line's write hits a closed pipe.
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !stderr.contains("Broken pipe") && !stderr.contains("panicked"),
        "{stderr}"
    );
    assert_ne!(out.status.code(), Some(101), "a panic's exit code: {stderr}");
}

/// The shipped pair, as a user runs it (no `--model`): a top view, told by
/// its name, is counted by `models/phyllo-top.onnx`, a side view by the side
/// model, and each JSON line names the model that counted it;
/// `--top-model none` hands the top view back to the side model.
#[test]
fn top_views_are_counted_by_the_shipped_top_model() {
    let tmp = tempfile::tempdir().unwrap();
    let (rendered, _) = render_frame(tmp.path(), &["--view", "top", "--age", "40"]);
    let top = tmp.path().join("p000003_top.png");
    let side = tmp.path().join("p000003_108.png");
    std::fs::copy(&rendered, &top).unwrap();
    std::fs::copy(&rendered, &side).unwrap();
    let count = |extra: &[&str]| {
        let (out, stdout, stderr) = run(phyllo()
            .env_remove("PHYLLO_MODEL")
            .env_remove("PHYLLO_TOP_MODEL")
            .args(["count", "--json", "--threads", "1"])
            .args(extra)
            .arg(&top)
            .arg(&side));
        assert!(out.status.success(), "{stderr}");
        json_lines(&stdout)
    };
    let pair = count(&[]);
    let model = |v: &Value| v["model"].as_str().unwrap().to_string();
    assert!(model(&pair[0]).starts_with("phyllo-top-t1-cpu@"), "{}", pair[0]);
    assert!(model(&pair[1]).starts_with("phyllo-s10-cpu@"), "{}", pair[1]);
    let side_only = count(&["--top-model", "none"]);
    assert_eq!(model(&side_only[0]), model(&pair[1]));
    assert_eq!(side_only[1]["leaf_count"], pair[1]["leaf_count"]);
    // The same pixels: the side model finds fewer of a top view's leaves.
    assert!(
        pair[0]["leaf_count"].as_u64() > side_only[0]["leaf_count"].as_u64(),
        "top model {} against side model {}",
        pair[0]["leaf_count"],
        side_only[0]["leaf_count"]
    );
}
