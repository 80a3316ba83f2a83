//! End-to-end checks of phyllo-gen: determinism, sharding, resumability,
//! label consistency and error reporting.

use phyllo_contract::{Contract, LEAF};
use phyllo_gen::dataset::{self, DatasetArgs, Row};
use phyllo_gen::plant::{growth::PlantTraits, preset::Preset, Plant};
use phyllo_gen::render::{self, look::Look, Quality, Scene, Stage, View, Window};
use phyllo_gen::tips;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

fn stage_for(preset: &str, seed: u64, age: f32, look: &Look) -> (Plant, Stage) {
    let preset = Preset::load(preset).unwrap();
    let plant = Plant::build(&PlantTraits::sample(&preset, seed), age);
    let stage = Stage::new(&plant, &preset.colour, [0.3, 0.3, 0.1], look);
    (plant, stage)
}

fn render_with_threads(threads: usize) -> (Vec<u8>, Vec<u16>) {
    let look = Look::randomised(7);
    let (_, stage) = stage_for("btx623", 3, 30.0, &look);
    let scene = Scene::new(&stage, &look, View::Side(36.0));
    let camera = render::camera_for(View::Side(36.0), &look, 514);
    let window = Window {
        x0: 200,
        y0: 250,
        width: 96,
        height: 80,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let out =
        pool.install(|| render::render(&scene, &camera, &look, window, Quality::default(), 99).unwrap());
    (out.rgb.into_raw(), out.label.data)
}

#[test]
fn same_seed_same_bytes_for_any_thread_count() {
    let one = render_with_threads(1);
    let three = render_with_threads(3);
    assert!(one == three, "render differs between 1 and 3 threads");
}

fn args(out: &Path, shard: (u64, u64)) -> DatasetArgs {
    DatasetArgs {
        out: out.to_path_buf(),
        plants: 4,
        seed: 11,
        views: vec![View::Side(108.0), View::Top],
        size: 64,
        full_frame: false,
        val_fraction: 0.5,
        presets: vec![Preset::load("btx623").unwrap(), Preset::load("maize").unwrap()],
        ages: Default::default(),
        zoom: phyllo_gen::sampling::ZoomRange::NONE,
        shard,
        quality: Quality { spp: 1, max_depth: 2 },
        masks: false,
        quiet: true,
    }
}

fn read_rows(path: &Path) -> Vec<Row> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn shard_union_equals_unsharded_run_and_rerun_is_a_no_op() {
    let whole = tempfile::tempdir().unwrap();
    let parts = tempfile::tempdir().unwrap();
    dataset::run(&args(whole.path(), (0, 1))).unwrap();
    dataset::run(&args(parts.path(), (0, 2))).unwrap();
    dataset::run(&args(parts.path(), (1, 2))).unwrap();
    let all = read_rows(&whole.path().join("manifest.jsonl"));
    assert_eq!(all.len(), 8);
    let mut union = read_rows(&parts.path().join("manifest.shard-0-of-2.jsonl"));
    union.extend(read_rows(&parts.path().join("manifest.shard-1-of-2.jsonl")));
    union.sort_by_key(|r| (r.plant, r.view.clone()));
    let mut sorted = all.clone();
    sorted.sort_by_key(|r| (r.plant, r.view.clone()));
    assert_eq!(union, sorted);
    for r in &all {
        for f in [&r.image, &r.label] {
            let a = std::fs::read(whole.path().join(f)).unwrap();
            let b = std::fs::read(parts.path().join(f)).unwrap();
            assert!(a == b, "{f} differs between sharded and unsharded runs");
        }
    }
    // Resuming: nothing is re-rendered, the manifest is rebuilt identically.
    let img = whole.path().join(&all[0].image);
    let before = std::fs::metadata(&img).unwrap().modified().unwrap();
    dataset::run(&args(whole.path(), (0, 1))).unwrap();
    assert_eq!(std::fs::metadata(&img).unwrap().modified().unwrap(), before);
    assert_eq!(read_rows(&whole.path().join("manifest.jsonl")), all);
    // A crashed item (meta record missing) is redone.
    std::fs::remove_file(whole.path().join("meta/p000001_top.json")).unwrap();
    dataset::run(&args(whole.path(), (0, 1))).unwrap();
    assert_eq!(read_rows(&whole.path().join("manifest.jsonl")), all);
    for r in &all {
        assert!(r.split == "train" || r.split == "val");
        assert!(r.leaf_count >= r.visible_leaf_count);
    }
}

#[test]
fn manifest_counts_match_labels_on_disk() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = args(dir.path(), (0, 1));
    a.size = 512;
    a.plants = 2;
    a.views = vec![View::Side(0.0), View::Side(108.0), View::Top];
    dataset::run(&a).unwrap();
    let c = Contract::embedded();
    for r in read_rows(&dir.path().join("manifest.jsonl")) {
        let label = image::open(dir.path().join(&r.label)).unwrap().into_luma16();
        assert_eq!(label.dimensions(), (512, 512));
        let mut leaves = BTreeMap::new();
        for p in label.pixels() {
            let (class, inst) = c.decode_label(p.0[0]);
            assert!(class <= 3, "bad class {class}");
            if class == LEAF {
                assert!(
                    inst >= 1 && usize::from(inst) <= r.leaf_count,
                    "leaf instance {inst} of {}",
                    r.leaf_count
                );
                *leaves.entry(inst).or_insert(0u32) += 1;
            }
        }
        assert_eq!(leaves.len(), r.visible_leaf_count, "{}", r.label);
        assert_eq!(leaves, r.leaf_pixels);
        // Every visible leaf has a tip, on a pixel of its own in this image.
        assert_eq!(
            r.leaf_tips.keys().collect::<Vec<_>>(),
            r.leaf_pixels.keys().collect::<Vec<_>>(),
            "{}",
            r.label
        );
        for (&k, t) in &r.leaf_tips {
            assert!(
                t[0] >= 0.0 && t[1] >= 0.0 && t[0] < 512.0 && t[1] < 512.0,
                "{t:?}"
            );
            let v = label.get_pixel(t[0] as u32, t[1] as u32).0[0];
            assert_eq!(c.decode_label(v), (LEAF, k), "{} leaf {k}: tip {t:?}", r.label);
        }
    }
}

#[test]
fn every_leaf_facing_the_camera_appears_in_the_label() {
    // A side view with all leaves present: at the 0° view of a plant whose
    // leaves spread left and right, each blade's tip region is unoccluded by
    // construction in at least one of the five side views.
    let look = Look::facility();
    let (plant, stage) = stage_for("btx623", 5, 35.0, &look);
    let mut seen = BTreeSet::new();
    for a in [0.0, 36.0, 72.0, 108.0, 144.0] {
        let view = View::Side(a);
        let scene = Scene::new(&stage, &look, view);
        let camera = render::camera_for(view, &look, 514);
        let window = Window {
            x0: 0,
            y0: 0,
            width: camera.width,
            height: camera.height,
        };
        let out = render::render(
            &scene,
            &camera,
            &look,
            window,
            Quality { spp: 1, max_depth: 1 },
            1,
        )
        .unwrap();
        seen.extend(out.label.leaf_pixels().into_keys());
    }
    let all: BTreeSet<u16> = (1..=plant.leaf_count() as u16).collect();
    assert_eq!(seen, all, "some leaf never appears in any side view");
}

#[test]
fn label_and_rgb_are_registered() {
    // With one sample per pixel the RGB pixel is traced along the label's
    // own ray. Render the plant and the same chamber without it: every
    // labelled plant pixel must differ from the empty chamber, and every
    // chamber pixel away from the pot must be identical.
    let mut look = Look::facility();
    look.noise_sd = 0.0;
    let (plant, stage) = stage_for("btx623", 2, 40.0, &look);
    let mut empty = plant.clone();
    empty.mesh = phyllo_gen::mesh::Mesh::default();
    let preset = Preset::load("btx623").unwrap();
    let empty_stage = Stage::new(&empty, &preset.colour, [0.3, 0.3, 0.1], &look);
    let view = View::Side(0.0);
    let camera = render::camera_for(view, &look, 514);
    let window = Window {
        x0: 0,
        y0: 0,
        width: camera.width,
        height: camera.height,
    };
    let q = Quality { spp: 1, max_depth: 2 };
    let with = render::render(&Scene::new(&stage, &look, view), &camera, &look, window, q, 5).unwrap();
    let without = render::render(
        &Scene::new(&empty_stage, &look, view),
        &camera,
        &look,
        window,
        q,
        5,
    )
    .unwrap();
    let pot_top = camera.project(glam::Vec3::new(0.0, 0.02, 0.0)).unwrap().1;
    let (mut plant_px, mut differs, mut chamber_px, mut same) = (0, 0, 0, 0);
    for (y, ((a, b), &v)) in with
        .rgb
        .pixels()
        .zip(without.rgb.pixels())
        .zip(&with.label.data)
        .enumerate()
        .map(|(i, x)| (i / window.width as usize, x))
    {
        if v != 0 {
            plant_px += 1;
            differs += usize::from(a != b);
        } else if (y as f32) < pot_top {
            chamber_px += 1;
            same += usize::from(a == b);
        }
    }
    assert!(plant_px > 500, "plant too small to test: {plant_px}");
    assert_eq!(same, chamber_px, "chamber pixels changed by the plant");
    assert!(
        differs as f32 > 0.995 * plant_px as f32,
        "{differs} of {plant_px} plant pixels differ from the empty chamber"
    );
}

#[test]
fn labelled_plant_pixels_are_plant_coloured() {
    // At training quality, plant pixels are darker than the chamber and not
    // bluish (anti-aliased edges of thin parts may mix with the wall).
    let look = Look::facility();
    let (_, stage) = stage_for("btx623", 2, 40.0, &look);
    let view = View::Side(0.0);
    let scene = Scene::new(&stage, &look, view);
    let camera = render::camera_for(view, &look, 514);
    let window = Window {
        x0: 0,
        y0: 0,
        width: camera.width,
        height: camera.height,
    };
    let out = render::render(&scene, &camera, &look, window, Quality::default(), 5).unwrap();
    let (mut plant_px, mut green) = (0, 0);
    for (p, &v) in out.rgb.pixels().zip(&out.label.data) {
        let [r, g, b] = p.0.map(i32::from);
        if v != 0 {
            plant_px += 1;
            green += usize::from(r + g + b < 600 && g + 4 >= b);
        }
    }
    assert!(
        green as f32 > 0.95 * plant_px as f32,
        "{green} of {plant_px} plant pixels look like plant"
    );
}

fn run_cli(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_phyllo-gen"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bad_arguments_and_presets_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d");
    let out = out.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &[
                "dataset", "--out", out, "--plants", "1", "--seed", "1", "--shard", "2/2",
            ],
            "--shard",
        ),
        (
            &[
                "dataset", "--out", out, "--plants", "1", "--seed", "1", "--views", "0,400",
            ],
            "400",
        ),
        (
            &[
                "dataset", "--out", out, "--plants", "1", "--seed", "1", "--views", "side",
            ],
            "--views",
        ),
        (
            &[
                "dataset",
                "--out",
                out,
                "--plants",
                "1",
                "--seed",
                "1",
                "--val-fraction",
                "1.5",
            ],
            "--val-fraction",
        ),
        (
            &[
                "dataset", "--out", out, "--plants", "1", "--seed", "1", "--preset", "nosuch",
            ],
            "unknown preset",
        ),
        (
            &["dataset", "--out", out, "--plants", "0", "--seed", "1"],
            "--plants",
        ),
        (
            &[
                "sequence",
                "--out",
                out,
                "--plants",
                "1",
                "--days",
                "1",
                "--seed",
                "1",
                "--start-date",
                "2019-02-30",
            ],
            "--start-date",
        ),
        (
            &["dataset", "--out", out, "--plants", "x", "--seed", "1"],
            "--plants",
        ),
    ];
    for (args, needle) in cases {
        let (code, err) = run_cli(args);
        assert_ne!(code, 0, "{args:?} should fail");
        assert!(
            err.contains(needle),
            "{args:?}: error should mention {needle:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
    let bad = dir.path().join("bad.toml");
    let text = include_str!("../presets/btx623.toml")
        .replace("width_ratio = [0.075, 0.095]", "width_ratio = [0.095, 0.075]");
    std::fs::write(&bad, text).unwrap();
    let (code, err) = run_cli(&["presets", bad.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(
        err.contains("bad.toml") && err.contains("leaf.width_ratio") && err.contains("lower bound"),
        "{err}"
    );
    std::fs::write(&bad, "name = ").unwrap();
    let (code, err) = run_cli(&["presets", bad.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("bad.toml") && !err.contains("panicked"), "{err}");
}

#[test]
fn obj_export_has_one_group_per_leaf() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("p.obj");
    let (code, err) = run_cli(&[
        "mesh",
        "--preset",
        "sc301",
        "--age",
        "42",
        "--out",
        obj.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(obj).unwrap();
    let leaves = text.lines().filter(|l| l.starts_with("g leaf_")).count();
    let preset = Preset::load("sc301").unwrap();
    let plant = Plant::build(&PlantTraits::sample(&preset, 1), 42.0);
    assert_eq!(leaves, plant.leaf_count());
    assert!((4..=13).contains(&leaves));
}

#[test]
fn dataset_plants_span_the_papers_ranges() {
    let presets = Preset::builtins().unwrap();
    let mut ages = Vec::new();
    for i in 0..60 {
        let plan = dataset::plan_plant(&presets, &Default::default(), &Default::default(), 3, i);
        let n = plan.traits.living_on(plan.age);
        assert!((4..=13).contains(&n), "plant {i}: {n} leaves at {} d", plan.age);
        assert!((7.0..=56.0).contains(&plan.age));
        ages.push(plan.age);
        let plant = Plant::build(&plan.traits, plan.age);
        assert_eq!(plant.leaf_count(), n);
        let per_leaf = plant
            .mesh
            .groups
            .iter()
            .filter(|g| g.name.starts_with("leaf_"))
            .map(|g| g.end - g.start)
            .min()
            .unwrap();
        assert!(per_leaf >= 128 * 2, "a leaf has only {per_leaf} triangles");
    }
    let spread =
        ages.iter().cloned().fold(f32::MIN, f32::max) - ages.iter().cloned().fold(f32::MAX, f32::min);
    assert!(spread > 20.0, "ages should spread over weeks: {spread}");
}

#[test]
fn coco_export_round_trips_the_panoptic_labels() {
    let dir = tempfile::tempdir().unwrap();
    dataset::run(&args(dir.path(), (0, 1))).unwrap();
    let summary = phyllo_gen::coco::export(dir.path()).unwrap();
    let rows = read_rows(&dir.path().join("manifest.jsonl"));
    assert_eq!(summary.images.values().sum::<usize>(), rows.len());
    let c = Contract::embedded();
    let mut checked = 0;
    for (split, n) in &summary.images {
        let doc: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("coco/panoptic_{split}.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(doc["images"].as_array().unwrap().len(), *n);
        let cats: Vec<u64> = doc["categories"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["id"].as_u64().unwrap())
            .collect();
        assert_eq!(cats, vec![1, 2, 3]);
        for (img, ann) in doc["images"]
            .as_array()
            .unwrap()
            .iter()
            .zip(doc["annotations"].as_array().unwrap())
        {
            assert_eq!(img["id"], ann["image_id"]);
            let row = rows
                .iter()
                .find(|r| r.image == img["file_name"].as_str().unwrap())
                .unwrap();
            let label = image::open(dir.path().join(&row.label)).unwrap().into_luma16();
            let png = image::open(
                dir.path()
                    .join(format!("coco/panoptic_{split}"))
                    .join(ann["file_name"].as_str().unwrap()),
            )
            .unwrap()
            .into_rgb8();
            // Every pixel's COCO segment id is its contract label value (0 = void).
            for (l, p) in label.pixels().zip(png.pixels()) {
                let id = u32::from(p.0[0]) + 256 * u32::from(p.0[1]) + 65536 * u32::from(p.0[2]);
                let (class, _) = c.decode_label(l.0[0]);
                assert_eq!(id, if class == 0 { 0 } else { u32::from(l.0[0]) });
            }
            let segs = ann["segments_info"].as_array().unwrap();
            let area: u64 = segs.iter().map(|s| s["area"].as_u64().unwrap()).sum();
            assert_eq!(
                area as usize,
                label.pixels().filter(|p| c.decode_label(p.0[0]).0 != 0).count()
            );
            let leaves = segs.iter().filter(|s| s["category_id"] == LEAF).count();
            assert_eq!(leaves, row.visible_leaf_count as usize);
            checked += 1;
        }
    }
    assert_eq!(checked, rows.len());
}

#[test]
fn full_frame_side_views_cover_the_whole_camera_frame() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = args(dir.path(), (0, 1));
    a.plants = 1;
    a.full_frame = true;
    dataset::run(&a).unwrap();
    let rows = read_rows(&dir.path().join("manifest.jsonl"));
    assert_eq!(rows.len(), 2);
    for r in rows {
        assert!(r.generator.starts_with("phyllo-gen "), "{}", r.generator);
        let img = image::open(dir.path().join(&r.image)).unwrap();
        if r.view == "top" {
            assert_eq!((img.width(), img.height()), (64, 64), "top views stay crops");
        } else {
            assert_eq!(
                [img.width(), img.height()],
                r.frame,
                "side view is the whole frame"
            );
            assert_eq!(r.frame, [614, 514]);
            assert_eq!(r.crop, [0, 0]);
        }
    }
}

/// Leaf pixels of a whole side frame: their count and their columns' span.
fn leaf_extent(look: &Look) -> (u32, u32) {
    let (_, stage) = stage_for("maize", 5, 16.0, look);
    let scene = Scene::new(&stage, look, View::Side(108.0));
    let camera = render::camera_for(View::Side(108.0), look, 514);
    let window = Window {
        x0: 0,
        y0: 0,
        width: camera.width,
        height: camera.height,
    };
    let out = render::render(&scene, &camera, look, window, Quality { spp: 1, max_depth: 1 }, 3).unwrap();
    let c = Contract::embedded();
    let (mut n, mut x0, mut x1) = (0, u32::MAX, 0);
    for (i, &v) in out.label.data.iter().enumerate() {
        if c.decode_label(v).0 == LEAF {
            let x = i as u32 % out.label.width;
            (n, x0, x1) = (n + 1, x0.min(x), x1.max(x));
        }
    }
    (n, x1 - x0 + 1)
}

#[test]
fn a_zoomed_camera_magnifies_the_plant_and_keeps_the_pot_in_place() {
    let one = Look::facility();
    let two = Look {
        zoom: 2.0,
        ..one.clone()
    };
    let (n1, w1) = leaf_extent(&one);
    let (n2, w2) = leaf_extent(&two);
    let area = n2 as f32 / n1 as f32;
    let span = w2 as f32 / w1 as f32;
    assert!((3.6..=4.4).contains(&area), "leaf area grew {area}× at zoom 2");
    // A little over 2×: tips thinner than a pixel, missed by the pixel-centre
    // rays at zoom 1, are hit at zoom 2.
    assert!((1.9..=2.3).contains(&span), "leaf span grew {span}× at zoom 2");
    // The soil at the pot's axis stays where it is in the frame.
    let soil = |look: &Look| {
        render::camera_for(View::Side(108.0), look, 514)
            .project(glam::Vec3::ZERO)
            .unwrap()
    };
    let (s1, s2) = (soil(&one), soil(&two));
    assert!(
        (s1.0 - s2.0).abs() < 0.5 && (s1.1 - s2.1).abs() < 0.5,
        "soil {s1:?} → {s2:?}"
    );
    // A dataset records each side view's zoom; the top camera has none.
    let dir = tempfile::tempdir().unwrap();
    let mut a = args(dir.path(), (0, 1));
    a.zoom = phyllo_gen::sampling::ZoomRange::parse("2").unwrap();
    a.plants = 1;
    dataset::run(&a).unwrap();
    for r in read_rows(&dir.path().join("manifest.jsonl")) {
        assert_eq!(r.zoom, if r.view == "top" { 1.0 } else { 2.0 }, "{}", r.view);
    }
}

/// Image position of a plant-space point in a rendered window.
fn to_image(scene: &Scene, camera: &render::camera::Camera, window: Window, p: glam::Vec3) -> [f32; 2] {
    let (x, y) = camera.project(scene.to_chamber(p)).unwrap();
    [x - window.x0 as f32, y - window.y0 as f32]
}

fn dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

#[test]
fn leaf_tips_lie_on_their_leaves_and_visible_tips_are_the_far_ends() {
    let c = Contract::embedded();
    let look = Look::facility();
    let (mut visible, mut hidden, mut moved, mut on_tip) = (0, 0, 0, 0);
    for (preset, seed, age) in [("btx623", 5, 35.0), ("sc301", 2, 45.0), ("maize", 3, 30.0)] {
        let (plant, stage) = stage_for(preset, seed, age, &look);
        for view in [View::Side(0.0), View::Side(72.0), View::Side(144.0), View::Top] {
            let scene = Scene::new(&stage, &look, view);
            let camera = render::camera_for(view, &look, 514);
            // Side views: the frame's middle; top view: a crop off the frame
            // origin, so the window offset matters.
            let window = match view {
                View::Top => Window {
                    x0: 150,
                    y0: 100,
                    width: 320,
                    height: 320,
                },
                _ => Window {
                    x0: 100,
                    y0: 0,
                    width: 420,
                    height: 514,
                },
            };
            let (w, h) = (window.width as usize, window.height as usize);
            let q = Quality { spp: 1, max_depth: 1 };
            let out = render::render(&scene, &camera, &look, window, q, 1).unwrap();
            let label = &out.label;
            let (tips, gaps) = tips::leaf_tips(&plant, &scene, &camera, window, label);
            let projected = tips::projected_tips(&plant, &scene, &camera, window);
            let pixels = label.leaf_pixels();
            assert_eq!(
                tips.keys().collect::<Vec<_>>(),
                pixels.keys().collect::<Vec<_>>(),
                "{preset} {view:?}"
            );
            let in_image = |p: [f32; 2]| p[0] >= 0.0 && p[1] >= 0.0 && p[0] < w as f32 && p[1] < h as f32;
            let holds = |p: [f32; 2], k: u16| {
                in_image(p) && c.decode_label(label.data[p[1] as usize * w + p[0] as usize]) == (LEAF, k)
            };
            let centres = |k: u16| {
                label
                    .data
                    .iter()
                    .enumerate()
                    .filter(move |(_, &v)| c.decode_label(v) == (LEAF, k))
                    .map(move |(i, _)| [(i % w) as f32 + 0.5, (i / w) as f32 + 0.5])
            };
            for (&k, &t) in &tips {
                let ctx = format!("{preset} {view:?} leaf {k}: tip {t:?}");
                assert!(holds(t, k), "{ctx} is not on a pixel of its leaf");
                let p = projected[&k].unwrap();
                if t == p {
                    on_tip += 1;
                    assert!(holds(p, k), "{ctx}");
                } else {
                    // Moved: the projected tip's pixel does not show this
                    // leaf, and no pixel of the leaf is nearer to it.
                    moved += 1;
                    assert!(!holds(p, k), "{ctx}: moved off its own pixel");
                    assert_eq!(t.map(|x| x.fract()), [0.5, 0.5], "{ctx}: not a pixel centre");
                    let d = dist(t, p);
                    assert!(
                        centres(k).all(|q| dist(q, p) >= d - 1e-3),
                        "{ctx}: a nearer pixel exists"
                    );
                }
                // Is the blade's tip itself in sight of the camera?
                let tip = scene.to_chamber(plant.leaf_tip(k).unwrap());
                let to_tip = tip - camera.position;
                let blocked = scene
                    .hit(camera.position, to_tip.normalize())
                    .is_some_and(|hit| hit.t < to_tip.length() - 1e-3);
                let q = [p[0].clamp(0.0, w as f32), p[1].clamp(0.0, h as f32)];
                let gap = if t == p { 0.0 } else { dist(q, t) };
                assert!(
                    (gaps[&k] - gap).abs() < 1e-3,
                    "{ctx}: gap {} against {gap}",
                    gaps[&k]
                );
                if blocked || !in_image(p) {
                    hidden += 1;
                    continue;
                }
                // A visible tip is the far end of its leaf: farther from the
                // blade's base than the leaf's pixel centroid is (unless the
                // leaf points at or away from the camera, its tip then
                // projecting next to its base).
                let g = plant
                    .mesh
                    .groups
                    .iter()
                    .find(|g| g.name == format!("leaf_{k:02}"))
                    .unwrap();
                let first = plant.mesh.tris[g.start..g.end]
                    .iter()
                    .flatten()
                    .min()
                    .copied()
                    .unwrap() as usize;
                // Middle vertex of the blade's first mesh row: the midrib's start.
                let base = to_image(&scene, &camera, window, plant.mesh.positions[first + 3]);
                if dist(p, base) < 20.0 {
                    continue;
                }
                // A leaf seen in a pixel or two (a thin blade far below the
                // wider top camera) has its tip on its centroid.
                if pixels[&k] < 3 {
                    continue;
                }
                visible += 1;
                let n = pixels[&k] as f32;
                let centroid = centres(k).fold([0.0, 0.0], |s, q| [s[0] + q[0] / n, s[1] + q[1] / n]);
                assert!(
                    dist(t, base) > dist(centroid, base),
                    "{ctx} is nearer the base {base:?} than the centroid {centroid:?}"
                );
            }
        }
    }
    // Both kinds of tip, and both rules, are exercised.
    assert!(
        visible >= 30 && hidden >= 5 && moved >= 5 && on_tip >= 1,
        "{visible} visible, {hidden} hidden, {moved} moved, {on_tip} on the projected tip"
    );
}
