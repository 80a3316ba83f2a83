//! `phyllo review` on images the real service counted: the session in doubt
//! comes with its images, and `--overlays` counts them again with the real
//! model (ONNX Runtime) and draws what it found, one PNG per image.

mod common;

use std::time::Duration;

use common::*;

#[test]
fn a_session_in_doubt_lists_its_images_and_draws_their_overlays() {
    let site = Site::new("workers = 1\nintra_threads = 1\n", "");
    let mut d = site.serve();
    site.wait_running(&mut d);
    // One plant, three days, five side views a day.
    for (name, bytes) in image_stream(0..15, 1, "R", 9_000) {
        drop_file(&site.drop.join(name), &bytes, false);
    }
    site.wait_for("15 counts", Duration::from_secs(90), || {
        site.q("SELECT COUNT(*) FROM observations") >= 15
    });
    assert!(d.term().success());

    // Four more side views of the last day, counted elsewhere far higher:
    // most of that session's side views now differ from its fused count.
    let obs = site.tmp.path().join("more-views.csv");
    let mut text = String::from("plant,timestamp,view,leaf_count\n");
    for a in [7, 11, 13, 17] {
        text += &format!("R00,2018-04-03T10:00:{a:02},SV_{a},30\n");
    }
    std::fs::write(&obs, text).unwrap();
    let out = site.phyllo(&["import", obs.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // One image of that session is gone from the drop directory since.
    std::fs::remove_file(site.drop.join(flat_name("R00", 3, 28, 144))).unwrap();

    let overlays = site.tmp.path().join("overlays");
    let out = site.phyllo(&[
        "review",
        "--json",
        "--top",
        "1",
        "--overlays",
        overlays.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let listed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(listed[0]["plant"], "R00", "{listed}");
    assert_eq!(listed[0]["start"], "2018-04-03T10:00:00.000", "{listed}");
    let images: Vec<String> = listed[0]["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    let want: Vec<String> = (0..5).map(|v| flat_name("R00", 3, v * 7, v * 36)).collect();
    assert_eq!(
        images, want,
        "the session's own images, in time order, the gone one too"
    );
    assert!(
        err.contains("4 overlays → ") && err.contains("(1 images no longer in the drop directory)"),
        "{err}"
    );
    let drawn: Vec<_> = std::fs::read_dir(overlays.join("01-R00"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(drawn.len(), 4, "{drawn:?}");
    for png in &drawn {
        let name = png.file_name().unwrap().to_string_lossy();
        assert!(
            name.starts_with("R00_2018-04-03_10-00-") && name.ends_with(".overlay.png"),
            "{name}"
        );
        let (w, h) = image::image_dimensions(png).unwrap();
        assert!(w >= 96 && h >= 96, "{name}: {w}x{h}");
    }
}
