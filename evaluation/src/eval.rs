//! `phyllo eval`: count accuracy (and, with labels, segmentation quality) of
//! the model on a phyllo-gen dataset or on real images with human counts.
//!
//! [`run`] reads the data item by item, sums it up and prints the report
//! (the `report` module: one JSON object, or the text tables).

mod report;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use phyllo_contract::Contract;
use phyllo_inference::{overlay, Counter, CounterConfig};

use crate::fingerprint::Fingerprint;
use crate::image_names::facts_for;
use crate::intervals::MetricIntervals;
use crate::leaf_errors::LeafErrors;
use crate::metrics::{per_view, CountMetrics, CountPair};
use crate::segment_table::{self, SegmentRow};
use crate::segmentation::{panoptic_quality, LeafMatch, Overlaps, PixelMap};
use crate::sources::{self, DatasetItem, HumanCount};
use crate::tip_errors::{TipErrors, TipMatch, TipOutcome};
use crate::{plots, tip_overlay};

/// What `phyllo eval` evaluates and how it reports it: every option but the
/// model's, which the caller turns into a [`CounterConfig`].
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {
    /// A phyllo-gen dataset directory (with manifest.jsonl).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["counts", "images"])]
    pub dataset: Option<PathBuf>,
    /// Dataset split to evaluate (`all` for every row).
    #[arg(long, default_value = "val")]
    pub split: String,
    /// Dataset truth: the smallest visible leaf area, in image pixels, that
    /// counts as a leaf (default 1: every leaf visible in the label, as a
    /// person counting on the camera's full-resolution frame would).
    #[arg(long, value_name = "PIXELS", default_value_t = 1, requires = "dataset")]
    pub truth_min_pixels: usize,
    /// CSV of human counts with `file` and `leaf_count` columns.
    #[arg(long, value_name = "CSV", requires = "images")]
    pub counts: Option<PathBuf>,
    /// Directory holding the CSV's images.
    #[arg(long, value_name = "DIR", requires = "counts")]
    pub images: Option<PathBuf>,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Write scatter.png and error_histogram.png here.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Also print each image's true and predicted count.
    #[arg(long)]
    pub per_image: bool,
    /// Write one row per predicted leaf (what it is against the truth, its
    /// area, score and contact with other leaves) to this TSV, for scoring
    /// post-processing rules offline (`python -m phyllo_train.experiments.segment_rules`).
    #[arg(long, value_name = "TSV", requires = "dataset")]
    pub segments: Option<PathBuf>,
    /// With a `tips_xy` column in the CSV: a marked tip belongs to the
    /// predicted leaf with a pixel this near, in the image's pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = 24.0, requires = "counts")]
    pub tip_radius: f32,
    /// With marked tips: write each image's overlay with its tips ringed
    /// (white: own leaf, yellow: sharing a leaf, red: reached by none) and
    /// its extra leaves crossed, as `<name>.tips.png` in this directory.
    #[arg(long, value_name = "DIR", requires = "counts")]
    pub tip_overlays: Option<PathBuf>,
    /// Only read the data and print its fingerprint (the `data` line, or
    /// `source`, `fingerprint` and `items` with --json): no model is loaded,
    /// so a set can be checked against models/eval-sets.tsv in seconds.
    #[arg(long)]
    pub fingerprint_only: bool,
}

impl EvalArgs {
    /// The manifest split to keep, `None` for `--split all`.
    fn split_filter(&self) -> Option<&str> {
        (self.split != "all").then_some(self.split.as_str())
    }
}

/// Runs the evaluation and prints its report; exit status 1 when any item
/// failed. `config` gives the model's configuration (the caller's model
/// options); it is not called with `--fingerprint-only`, which loads no model.
pub fn run(
    args: &EvalArgs,
    config: impl FnOnce() -> anyhow::Result<CounterConfig>,
) -> anyhow::Result<ExitCode> {
    if args.fingerprint_only {
        return report::print_fingerprint(args);
    }
    let counter = load_counter(args, config()?)?;
    let mut run = Gathered::new(args.tip_radius);
    if let Some(dir) = &args.dataset {
        run.dataset(args, &counter, dir)?;
    } else if let (Some(csv), Some(images)) = (&args.counts, &args.images) {
        run.human_counts(args, &counter, csv, images)?;
    } else {
        bail!("give --dataset DIR, or --counts CSV with --images DIR");
    }
    if let Some(path) = &args.segments {
        segment_table::write_tsv(path, &run.segment_rows)?;
    }
    let summary = Summary::of(&run);
    if let Some(dir) = &args.plots {
        plots::write(&run.pairs, &summary.metrics, &run.caption, dir)?;
    }
    if args.json {
        report::print_json(args, &counter, &run, &summary);
    } else {
        report::print_text(args, &counter, &run, &summary);
    }
    Ok(report::exit_code(&run.failed))
}

/// Loads the model, at the contract's scale on a dataset of crops (phyllo-gen
/// renders them at it; `--scale` still overrides), warning when it is
/// untrained. Whole frames go through the scale rule as a camera's would.
fn load_counter(args: &EvalArgs, mut config: CounterConfig) -> anyhow::Result<Counter> {
    if args
        .dataset
        .as_deref()
        .is_some_and(|d| !sources::holds_whole_frames(d))
    {
        config.scale = config.scale.or(Some(1.0));
    }
    let counter = Counter::new(config)?;
    if !counter.model_info().trained {
        eprintln!(
            "phyllo: warning: model {} is UNTRAINED: these numbers mean nothing",
            counter.model_id()
        );
    }
    Ok(counter)
}

/// Everything an evaluation collected, item by item.
struct Gathered {
    /// True and predicted count of each item read.
    pairs: Vec<CountPair>,
    /// Leaf segmentation scores of each dataset item.
    matches: Vec<LeafMatch>,
    /// True and predicted leaves by kind of error (datasets).
    leaf_errors: LeafErrors,
    /// One row per predicted leaf, for `--segments`.
    segment_rows: Vec<SegmentRow>,
    /// Marked tips against the predicted leaves (human counts with tips).
    tip_errors: TipErrors,
    /// Each image's tip outcome, by file.
    tip_outcomes: Vec<(String, TipOutcome)>,
    /// Each failed item's error.
    failed: Vec<String>,
    /// Digest of the data read.
    fingerprint: Fingerprint,
    /// The source named in full, for the report.
    title: String,
    /// The source in a plot caption's room: the folder's name only.
    caption: String,
}

impl Gathered {
    fn new(tip_radius: f32) -> Self {
        Self {
            pairs: Vec::new(),
            matches: Vec::new(),
            leaf_errors: LeafErrors::default(),
            segment_rows: Vec::new(),
            tip_errors: TipErrors::new(tip_radius),
            tip_outcomes: Vec::new(),
            failed: Vec::new(),
            fingerprint: Fingerprint::default(),
            title: String::new(),
            caption: String::new(),
        }
    }

    /// Evaluates each item of the phyllo-gen dataset `dir` against its label.
    fn dataset(&mut self, args: &EvalArgs, counter: &Counter, dir: &Path) -> anyhow::Result<()> {
        // Until 2026-11-24 the default was the post-processing's minimum leaf
        // area (96 px), which tied the truth to a tuned parameter and gave
        // seedlings with five visible leaves a truth of 0.
        let min_pixels = args.truth_min_pixels.max(1);
        let detail = format!("({}; truth: leaves of at least {min_pixels} px)", args.split);
        self.title = format!("{} {detail}", dir.display());
        let folder = dir.file_name().map(|f| f.to_string_lossy().into_owned());
        self.caption = format!("{} {detail}", folder.unwrap_or_else(|| dir.display().to_string()));
        for item in sources::read_manifest(dir, args.split_filter())? {
            match self.dataset_item(args, counter, &item, min_pixels) {
                Ok((p, m, o)) => {
                    self.pairs.push(p);
                    self.matches.push(m);
                    self.leaf_errors.add(&o);
                }
                Err(e) => self.failed.push(format!("{e:#}")),
            }
        }
        Ok(())
    }

    /// Counts one dataset image and compares its leaves with the label's.
    fn dataset_item(
        &mut self,
        args: &EvalArgs,
        counter: &Counter,
        item: &DatasetItem,
        min_pixels: usize,
    ) -> anyhow::Result<(CountPair, LeafMatch, Overlaps)> {
        let c = Contract::embedded();
        let bytes =
            std::fs::read(&item.image).with_context(|| format!("cannot read {}", item.image.display()))?;
        let analysis = counter.analyse_bytes(&item.image, &facts_for(&item.image), &bytes)?;
        let label_bytes = std::fs::read(&item.label)
            .with_context(|| format!("cannot read label {}", item.label.display()))?;
        let label = image::load_from_memory(&label_bytes)
            .with_context(|| format!("cannot decode label {}", item.label.display()))?
            .into_luma16();
        self.fingerprint.add_pair(item, &bytes, &label_bytes);
        let (w, h) = (label.width() as usize, label.height() as usize);
        if [w as u32, h as u32] != analysis.result.image_size {
            bail!(
                "label {} is {w}x{h}, its image is {:?}",
                item.label.display(),
                analysis.result.image_size
            );
        }
        let truth = PixelMap::from_label(c, w, h, label.as_raw());
        let pred = PixelMap::from_analysis(c, &analysis, w, h);
        let pair = CountPair {
            file: item.image.display().to_string(),
            view: item.view.clone(),
            truth: truth.countable_leaves(min_pixels),
            predicted: analysis.result.leaf_count,
        };
        let overlaps = Overlaps::of(&truth, &pred);
        if args.segments.is_some() {
            self.segment_rows.extend(segment_table::rows(
                &item.name,
                pair.truth,
                pair.predicted,
                &overlaps,
                &analysis.panoptic,
            ));
        }
        Ok((pair, LeafMatch::of(&overlaps), overlaps))
    }

    /// Counts each image of the CSV `csv` (files in `images`) against the
    /// person's count, and against the person's marked tips where it has them.
    fn human_counts(
        &mut self,
        args: &EvalArgs,
        counter: &Counter,
        csv: &Path,
        images: &Path,
    ) -> anyhow::Result<()> {
        if let Some(dir) = &args.tip_overlays {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create tip overlay directory {}", dir.display()))?;
        }
        self.title = csv
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        self.caption = self.title.clone();
        for hc in sources::read_counts(csv, images)? {
            match self.human_count(args, counter, &hc) {
                Ok((predicted, tips)) => {
                    let file = hc.image.display().to_string();
                    if let Some(t) = tips {
                        self.tip_errors.add(&t);
                        self.tip_outcomes.push((file.clone(), t));
                    }
                    self.pairs.push(CountPair {
                        file,
                        view: hc.view,
                        truth: hc.count,
                        predicted,
                    });
                }
                Err(e) => self.failed.push(format!("{e:#}")),
            }
        }
        Ok(())
    }

    /// Counts one human-counted image; with marked tips, matches them to the
    /// predicted leaves (and draws them with `--tip-overlays`).
    fn human_count(
        &mut self,
        args: &EvalArgs,
        counter: &Counter,
        hc: &HumanCount,
    ) -> anyhow::Result<(u32, Option<TipOutcome>)> {
        let bytes =
            std::fs::read(&hc.image).with_context(|| format!("cannot read {}", hc.image.display()))?;
        self.fingerprint.add_human_count(hc, &bytes);
        let analysis = counter.analyse_bytes(&hc.image, &facts_for(&hc.image), &bytes)?;
        let Some(tips) = &hc.tips else {
            return Ok((analysis.result.leaf_count, None));
        };
        let [w, h] = analysis.result.image_size;
        let pred = PixelMap::from_analysis(Contract::embedded(), &analysis, w as usize, h as usize);
        let m = TipMatch::of(tips, &pred, args.tip_radius);
        if let Some(dir) = &args.tip_overlays {
            let mut drawn = overlay::render_encoded(counter, &hc.image, &bytes, &analysis)?;
            tip_overlay::draw(&mut drawn, tips, &m, &analysis.result.instances);
            let out = crate::image_names::overlay_path(dir, &hc.image, "tips");
            drawn
                .save(&out)
                .with_context(|| format!("cannot write tip overlay {}", out.display()))?;
        }
        Ok((analysis.result.leaf_count, Some(m.outcome)))
    }
}

/// The numbers the report gives, worked out from what was gathered.
struct Summary {
    /// Count metrics over every item.
    metrics: CountMetrics,
    /// Count metrics per view.
    views: std::collections::BTreeMap<String, CountMetrics>,
    /// 95 % intervals of the metrics (none without items).
    intervals: Option<MetricIntervals>,
    /// Mean leaf IoU per image and leaf panoptic quality (datasets only).
    seg: Option<(f64, f64)>,
}

impl Summary {
    fn of(run: &Gathered) -> Self {
        let matches = &run.matches;
        Self {
            metrics: CountMetrics::of(&run.pairs),
            views: per_view(&run.pairs),
            intervals: MetricIntervals::of(&run.pairs),
            seg: (!matches.is_empty()).then(|| {
                let miou = matches.iter().map(|m| m.mean_iou).sum::<f64>() / matches.len() as f64;
                (miou, panoptic_quality(matches))
            }),
        }
    }
}
