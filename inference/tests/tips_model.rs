//! Leaf tips with real models through ONNX Runtime: the shipped model has no
//! tip output and counts as before under every rule; the test model with an
//! untrained tip head (`models/phyllo-tips-untrained.onnx`: the shipped
//! network plus a tip head whose heatmap is ~0.01 everywhere) is recognised,
//! finds no tips, and otherwise counts exactly as the shipped model does.

use std::path::{Path, PathBuf};

use phyllo_inference::counter::Analysis;
use phyllo_inference::postprocess::PostprocessParams;
use phyllo_inference::tips::CountRule;
use phyllo_inference::{Counter, CounterConfig, ImageFacts};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn counter(model: &str, rule: CountRule) -> Counter {
    let path = repo().join("models").join(model);
    assert!(path.is_file(), "{} is missing", path.display());
    Counter::new(CounterConfig {
        model: Some(path),
        postprocess: PostprocessParams {
            count_rule: rule,
            ..PostprocessParams::default()
        },
        ..CounterConfig::default()
    })
    .expect("the model loads")
}

/// A real side view from `docs/samples/` whose plant is small enough to be
/// counted twice (enlarged), so both passes see the tip output.
fn sample() -> (PathBuf, Vec<u8>) {
    let path = repo().join("docs/samples/402-204-N132-WW-1_2019-05-28_11-13-20.830_Vis_SV_108.jpg");
    let bytes = std::fs::read(&path).expect("sample image");
    (path, bytes)
}

fn analyse(c: &Counter) -> Analysis {
    let (path, bytes) = sample();
    c.analyse_bytes(&path, &ImageFacts::side(), &bytes)
        .expect("counts")
}

#[test]
fn the_shipped_model_has_no_tip_output_and_counts_centres_under_every_rule() {
    let centres = analyse(&counter("phyllo.onnx", CountRule::Centres));
    assert!(centres.result.leaf_count > 0, "the trained model finds leaves");
    for rule in CountRule::ALL {
        let c = counter("phyllo.onnx", rule);
        assert!(!c.model_info().has_tips);
        assert_eq!(c.count_rule(), CountRule::Centres, "asked for {rule}");
        let a = analyse(&c);
        assert_eq!(a.panoptic.tips, None);
        assert!(a.result.tips.is_empty());
        assert_eq!(a.result.leaf_count, centres.result.leaf_count, "{rule}");
        assert_eq!(a.result.instances, centres.result.instances, "{rule}");
        let json = serde_json::to_value(&a.result).unwrap();
        assert!(json.get("tips").is_none(), "no tips key in JSON: {json}");
    }
}

#[test]
fn an_untrained_tip_head_is_recognised_finds_no_tips_and_changes_nothing_else() {
    let shipped = analyse(&counter("phyllo.onnx", CountRule::Centres)).result;
    for rule in CountRule::ALL {
        let c = counter("phyllo-tips-untrained.onnx", rule);
        assert!(c.model_info().has_tips);
        assert_eq!(c.count_rule(), rule);
        let a = analyse(&c);
        // It looked for tips and found none (its heatmap stays near 0.01).
        assert_eq!(a.panoptic.tips, Some(Vec::new()), "{rule}");
        assert!(a.result.tips.is_empty(), "{rule}");
        // Its other three outputs are the shipped model's.
        assert_eq!(a.result.instances, shipped.instances, "{rule}");
        assert_eq!(a.result.scale, shipped.scale, "{rule}");
        assert_eq!(a.result.tiles, shipped.tiles, "{rule}");
        // No tip lies on a leaf: `tips` counts none, `split` counts each leaf
        // segment once, as `centres` does.
        let expect = match rule {
            CountRule::Centres | CountRule::Split => shipped.leaf_count,
            CountRule::Tips => 0,
        };
        assert_eq!(a.result.leaf_count, expect, "{rule}");
    }
}

#[test]
fn the_tip_output_survives_test_time_flip() {
    let c = Counter::new(CounterConfig {
        model: Some(repo().join("models/phyllo-tips-untrained.onnx")),
        flip: true,
        postprocess: PostprocessParams {
            count_rule: CountRule::Split,
            ..PostprocessParams::default()
        },
        ..CounterConfig::default()
    })
    .expect("the model loads");
    let a = analyse(&c);
    assert_eq!(a.panoptic.tips, Some(Vec::new()));
    assert_eq!(
        a.result.leaf_count as usize,
        a.panoptic.count(phyllo_contract::LEAF)
    );
}
