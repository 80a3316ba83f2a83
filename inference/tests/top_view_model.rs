//! Top views go to their own model, through ONNX Runtime with real models:
//! the view the caller hands in alone decides (the crate reads no file
//! names), the side views count exactly as the side model alone counts them,
//! and every count names the model that made it.

use std::path::{Path, PathBuf};

use phyllo_inference::postprocess::PostprocessParams;
use phyllo_inference::top_view::{TopModel, TopViewConfig};
use phyllo_inference::{Counter, CounterConfig, ImageFacts, View};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn model(name: &str) -> PathBuf {
    let path = repo().join("models").join(name);
    assert!(path.is_file(), "{} is missing", path.display());
    path
}

fn counter(side: &str, top: TopModel) -> Counter {
    Counter::new(CounterConfig {
        model: Some(model(side)),
        top_views: TopViewConfig {
            model: top,
            ..TopViewConfig::default()
        },
        ..CounterConfig::default()
    })
    .expect("the models load")
}

/// A real frame's bytes, and what makes it a side view and a top view.
fn frame() -> (Vec<u8>, ImageFacts, ImageFacts) {
    let path = repo().join("docs/samples/402-204-N132-WW-1_2019-05-28_11-13-20.830_Vis_SV_108.jpg");
    let bytes = std::fs::read(&path).expect("sample image");
    let side = ImageFacts::of_view(View::Side { angle: Some(108) });
    (bytes, side, ImageFacts::top())
}

#[test]
fn top_views_are_counted_by_the_top_model_and_side_views_as_before() {
    let (bytes, side, top) = frame();
    // The untrained model stands in for a top-view model: it counts
    // differently from the shipped one, so a mix-up shows.
    let pair = counter("phyllo.onnx", TopModel::File(model("phyllo-untrained.onnx")));
    let side_alone = counter("phyllo.onnx", TopModel::Off);
    let top_alone = Counter::new(CounterConfig {
        model: Some(model("phyllo-untrained.onnx")),
        postprocess: PostprocessParams {
            center_threshold: TopViewConfig::default().center_threshold(),
            nms_kernel: TopViewConfig::default().nms_kernel(),
            ..PostprocessParams::default()
        },
        top_views: TopViewConfig {
            model: TopModel::Off,
            ..TopViewConfig::default()
        },
        ..CounterConfig::default()
    })
    .expect("the untrained model loads");

    let count = |c: &Counter, facts: &ImageFacts| {
        let r = c
            .count_bytes(Path::new("frame.jpg"), facts, &bytes)
            .expect("counts");
        (r.leaf_count, r.instances.len(), r.tiles)
    };
    assert_eq!(count(&pair, &side), count(&side_alone, &side));
    assert_eq!(count(&pair, &top), count(&top_alone, &top));
    assert_ne!(
        count(&side_alone, &top),
        count(&top_alone, &top),
        "the two models must count this frame differently for the test to tell them apart"
    );

    assert!(pair.counts_as_top_view(top.view) && !pair.counts_as_top_view(side.view));
    assert_eq!(pair.model_id_for(side.view), side_alone.model_id());
    assert_eq!(pair.model_id_for(top.view), top_alone.model_id());
    assert_eq!(
        pair.model_id(),
        format!("{}+{}", side_alone.model_id(), top_alone.model_id())
    );
}

#[test]
fn a_side_model_named_by_hand_counts_top_views_too() {
    let (_, _, top) = frame();
    let c = counter("phyllo.onnx", TopModel::Default);
    assert!(c.top_model_info().is_none());
    assert!(!c.counts_as_top_view(top.view));
    assert_eq!(c.model_id_for(top.view), c.model_id());
}

#[test]
fn a_missing_top_model_is_refused_by_name() {
    let missing = repo().join("models/no-such-top-model.onnx");
    let err = Counter::new(CounterConfig {
        model: Some(model("phyllo.onnx")),
        top_views: TopViewConfig {
            model: TopModel::File(missing.clone()),
            ..TopViewConfig::default()
        },
        ..CounterConfig::default()
    })
    .err()
    .expect("a missing file is refused")
    .to_string();
    assert!(err.contains("no-such-top-model.onnx"), "{err}");
}
