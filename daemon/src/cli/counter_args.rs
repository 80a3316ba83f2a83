//! Arguments shared by every command that runs the model.

use std::path::PathBuf;

use anyhow::{bail, Context};
use phyllo_inference::camera_scale::CameraZoom;
use phyllo_inference::postprocess::{PostprocessParams, DEFAULT_ATTACH_RADIUS};
use phyllo_inference::region::RegionMode;
use phyllo_inference::tips::{CountRule, DEFAULT_TIP_REACH};
use phyllo_inference::top_view::{TopModel, TopViewConfig};
use phyllo_inference::zoom::HeightMeasure;
use phyllo_inference::CounterConfig;

/// Model and runtime options.
#[derive(Debug, Clone, clap::Args)]
pub struct CounterArgs {
    /// ONNX model (default: $PHYLLO_MODEL, then the model shipped with phyllo).
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// Model for top views (file names `*_TV_*`, `*_top.*`): `default` (the
    /// shipped one, $PHYLLO_TOP_MODEL, unless --model or $PHYLLO_MODEL names
    /// the side-view model), `none` (the side-view model counts them), or a
    /// file.
    #[arg(long, value_name = "MODEL", default_value = "default")]
    pub top_model: TopModel,
    /// Post-processing of top views: minimum centre heatmap value (default:
    /// the shipped top-view model's).
    #[arg(long, value_name = "VALUE")]
    pub top_center_threshold: Option<f32>,
    /// Post-processing of top views: side of the max-pool window that keeps
    /// one centre per neighbourhood, in output pixels, odd (default: the
    /// shipped top-view model's).
    #[arg(long, value_name = "PIXELS", value_parser = parse_nms_kernel)]
    pub top_nms_kernel: Option<u32>,
    /// ONNX Runtime shared library (default: $PHYLLO_ORT_LIB, then a search).
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// ONNX Runtime intra-op threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Plant region: `auto` (by colour), `full`, or a fixed box `x0,y0,x1,y1` in image pixels.
    #[arg(long, default_value = "auto")]
    pub region: String,
    /// Model pixels per image pixel, overriding the contract's scale rule
    /// (e.g. 0.5 for crops cut from 1227x1028 half-size frames).
    #[arg(long, value_name = "FACTOR", value_parser = parse_scale)]
    pub scale: Option<f32>,
    /// The side camera's zoom: `measure` it on the chamber's back panel
    /// (frames; crops and frames without one take the contract's), assume
    /// the `contract`'s, or a number such as 2 for a camera zoomed in 2×.
    #[arg(long, value_name = "ZOOM", default_value = "measure")]
    pub camera_zoom: CameraZoom,
    /// Count a plant again, enlarged, when its leaves span fewer than this
    /// many model pixels, so that they span it (0: never; default: the
    /// contract's).
    #[arg(long, value_name = "PIXELS")]
    pub zoom_height: Option<u32>,
    /// Largest enlargement of a small plant (default: the contract's).
    #[arg(long, value_name = "FACTOR", value_parser = parse_max_zoom)]
    pub max_zoom: Option<f32>,
    /// What the small-plant rule measures the plant's height on: `all` the
    /// instances of the first pass, or the `plant` without specks on the
    /// chamber.
    #[arg(
        long,
        value_name = "MEASURE",
        default_value_t = HeightMeasure::default(),
        value_parser = parse_height_measure(),
    )]
    pub zoom_height_measure: HeightMeasure,
    /// Also run every tile mirrored left to right and average the two.
    #[arg(long)]
    pub flip: bool,
    /// Post-processing: instances apart from the plant's body by more than
    /// this many model output pixels are dropped (0: keep every instance).
    #[arg(long, value_name = "PIXELS", default_value_t = DEFAULT_ATTACH_RADIUS)]
    pub attach_radius: u32,
    /// Post-processing: smallest leaf that counts, in model output pixels
    /// (default: the contract's).
    #[arg(long, value_name = "PIXELS")]
    pub min_leaf_area: Option<u32>,
    /// Post-processing: minimum centre heatmap value (default: the contract's).
    #[arg(long, value_name = "VALUE")]
    pub center_threshold: Option<f32>,
    /// Post-processing: side of the max-pool window that keeps one centre
    /// per neighbourhood, in output pixels, odd (default: the contract's).
    #[arg(long, value_name = "PIXELS", value_parser = parse_nms_kernel)]
    pub nms_kernel: Option<u32>,
    /// How leaves are counted with a model that has a leaf-tip output:
    /// `centres` (one per leaf segment), `tips` (the tips that lie on a
    /// leaf) or `split` (per leaf segment its tips, at least one). A model
    /// without tips counts centres whatever the rule.
    #[arg(
        long,
        value_name = "RULE",
        default_value_t = PostprocessParams::default().count_rule,
        value_parser = parse_count_rule(),
    )]
    pub count_rule: CountRule,
    /// Post-processing: minimum tip heatmap value of a leaf tip (default:
    /// the contract's).
    #[arg(long, value_name = "VALUE")]
    pub tip_threshold: Option<f32>,
    /// Post-processing: a tip belongs to a leaf with a pixel this many model
    /// output pixels away or nearer.
    #[arg(long, value_name = "PIXELS", default_value_t = DEFAULT_TIP_REACH)]
    pub tip_reach: u32,
    /// Post-processing: a leaf instance's separate pieces of at least this
    /// many model output pixels count as leaves of their own (0: off).
    #[arg(long, value_name = "PIXELS", default_value_t = PostprocessParams::default().split_min_area)]
    pub split_min_area: u32,
    /// Post-processing: pieces of one instance this many model output pixels
    /// apart or nearer are one piece.
    #[arg(long, value_name = "PIXELS", default_value_t = PostprocessParams::default().split_gap)]
    pub split_gap: u32,
    /// Post-processing: a piece stays with its instance when more than this
    /// share of the shortest route to the instance's largest piece runs over
    /// another leaf (1: split every large piece).
    #[arg(
        long,
        value_name = "SHARE",
        default_value_t = PostprocessParams::default().split_max_leaf_share,
        value_parser = parse_share,
    )]
    pub split_max_leaf_share: f32,
    /// Post-processing: crumbs of a leaf instance too small to split off that
    /// lie more than this many model output pixels from its body are taken
    /// from it (specks on the chamber; 0: keep them).
    #[arg(long, value_name = "PIXELS", default_value_t = PostprocessParams::default().speck_distance)]
    pub speck_distance: u32,
}

impl CounterArgs {
    /// The counter configuration these arguments describe.
    pub fn config(&self) -> anyhow::Result<CounterConfig> {
        let defaults = PostprocessParams::default();
        let postprocess = PostprocessParams {
            attach_radius: self.attach_radius,
            min_leaf_area: self.min_leaf_area.unwrap_or(defaults.min_leaf_area),
            center_threshold: self.center_threshold.unwrap_or(defaults.center_threshold),
            nms_kernel: self.nms_kernel.unwrap_or(defaults.nms_kernel),
            count_rule: self.count_rule,
            tip_threshold: self.tip_threshold.unwrap_or(defaults.tip_threshold),
            tip_reach: self.tip_reach,
            split_min_area: self.split_min_area,
            split_gap: self.split_gap,
            split_max_leaf_share: self.split_max_leaf_share,
            speck_distance: self.speck_distance,
            ..defaults
        };
        Ok(CounterConfig {
            model: self.model.clone(),
            ort_lib: self.ort_lib.clone(),
            intra_threads: self.threads,
            region: parse_region(&self.region)?,
            scale: self.scale,
            camera_zoom: self.camera_zoom,
            zoom_plant_height: self.zoom_height,
            max_zoom: self.max_zoom,
            zoom_height_measure: self.zoom_height_measure,
            flip: self.flip,
            postprocess,
            top_views: TopViewConfig {
                model: self.top_model.clone(),
                center_threshold: self.top_center_threshold,
                nms_kernel: self.top_nms_kernel,
            },
            ..CounterConfig::default()
        })
    }
}

/// Parses a `--count-rule`, listing the rules in `--help`.
fn parse_count_rule() -> impl clap::builder::TypedValueParser<Value = CountRule> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(CountRule::ALL.map(CountRule::name))
        .map(|s| s.parse::<CountRule>().expect("a listed rule"))
}

/// Parses a `--zoom-height-measure`, listing the measures in `--help`.
fn parse_height_measure() -> impl clap::builder::TypedValueParser<Value = HeightMeasure> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(HeightMeasure::ALL.map(HeightMeasure::name))
        .map(|s| s.parse::<HeightMeasure>().expect("a listed measure"))
}

/// Parses a `--max-zoom`: 1..=8, the contract's bounds.
fn parse_max_zoom(s: &str) -> Result<f32, String> {
    let z: f32 = s.parse().map_err(|e| format!("{s:?} is not a number: {e}"))?;
    if (1.0..=8.0).contains(&z) {
        Ok(z)
    } else {
        Err(format!("{z} is outside 1..=8"))
    }
}

/// Parses an `--nms-kernel` side: odd, 1..=31.
fn parse_nms_kernel(s: &str) -> Result<u32, String> {
    let v: u32 = s.parse().map_err(|_| format!("{s:?} is not a whole number"))?;
    if v.is_multiple_of(2) || !(1..=31).contains(&v) {
        return Err(format!("{v} must be odd and within 1..=31"));
    }
    Ok(v)
}

/// Parses a share: a number within 0..=1.
fn parse_share(s: &str) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|_| format!("{s:?} is not a number"))?;
    if !(0.0..=1.0).contains(&v) {
        return Err(format!("{v} must lie in 0..=1"));
    }
    Ok(v)
}

/// Parses a `--scale` factor: finite and within 0.01..=8.
fn parse_scale(s: &str) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|_| format!("{s:?} is not a number"))?;
    if !(0.01..=8.0).contains(&v) {
        return Err(format!("{v} must lie in 0.01..=8"));
    }
    Ok(v)
}

/// Parses `auto`, `full` or `x0,y0,x1,y1`.
pub fn parse_region(s: &str) -> anyhow::Result<RegionMode> {
    match s {
        "auto" => Ok(RegionMode::Auto),
        "full" => Ok(RegionMode::Full),
        _ => {
            let v: Vec<u32> = s
                .split(',')
                .map(|p| p.trim().parse::<u32>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--region {s:?}: expected auto, full or x0,y0,x1,y1"))?;
            if v.len() != 4 || v[2] <= v[0] || v[3] <= v[1] {
                bail!("--region {s:?}: expected x0,y0,x1,y1 with x1 > x0 and y1 > y0");
            }
            Ok(RegionMode::Fixed {
                x0: v[0],
                y0: v[1],
                x1: v[2],
                y1: v[3],
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use phyllo_inference::tips::CountRule;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        counter: CounterArgs,
    }

    fn config(args: &[&str]) -> Result<CounterConfig, String> {
        let cli = Cli::try_parse_from(std::iter::once("phyllo").chain(args.iter().copied()))
            .map_err(|e| e.to_string())?;
        cli.counter.config().map_err(|e| e.to_string())
    }

    #[test]
    fn separate_pieces_options_reach_the_post_processing() {
        let p = config(&[
            "--split-min-area",
            "64",
            "--split-gap",
            "3",
            "--split-max-leaf-share",
            "0.5",
        ])
        .unwrap()
        .postprocess;
        assert_eq!(
            (p.split_min_area, p.split_gap, p.split_max_leaf_share),
            (64, 3, 0.5)
        );
        assert!(config(&["--split-max-leaf-share", "1.5"]).is_err());
        assert!(config(&["--split-max-leaf-share", "-0.1"]).is_err());
    }

    #[test]
    fn tip_options_reach_the_post_processing() {
        let p = config(&[
            "--count-rule",
            "split",
            "--tip-threshold",
            "0.45",
            "--tip-reach",
            "4",
        ])
        .unwrap()
        .postprocess;
        assert_eq!(p.count_rule, CountRule::Split);
        assert_eq!(p.tip_threshold, 0.45);
        assert_eq!(p.tip_reach, 4);
        assert_eq!(
            config(&["--count-rule", "tips"]).unwrap().postprocess.count_rule,
            CountRule::Tips
        );
    }

    #[test]
    fn without_tip_options_the_defaults_hold() {
        assert_eq!(config(&[]).unwrap().postprocess, PostprocessParams::default());
    }

    #[test]
    fn max_zoom_is_taken_within_the_contract_bounds_only() {
        assert_eq!(config(&["--max-zoom", "2.5"]).unwrap().max_zoom, Some(2.5));
        assert_eq!(config(&[]).unwrap().max_zoom, None);
        for bad in ["0.5", "9", "NaN", "two"] {
            assert!(config(&["--max-zoom", bad]).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_zoom_height_measure_is_chosen_by_name() {
        use phyllo_inference::zoom::HeightMeasure;
        assert_eq!(config(&[]).unwrap().zoom_height_measure, HeightMeasure::default());
        let plant = config(&["--zoom-height-measure", "plant"]).unwrap();
        assert_eq!(plant.zoom_height_measure, HeightMeasure::Plant);
        assert!(config(&["--zoom-height-measure", "specks"]).is_err());
    }

    #[test]
    fn an_unknown_count_rule_is_refused_with_the_choices() {
        let err = config(&["--count-rule", "centers"]).unwrap_err();
        assert!(err.contains("centres, tips, split"), "{err}");
    }
}
