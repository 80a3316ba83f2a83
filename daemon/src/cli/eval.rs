//! `phyllo eval`: count accuracy (and, with labels, segmentation quality) of
//! the model on a phyllo-gen dataset or on real images with human counts.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use phyllo_contract::Contract;
use phyllo_inference::Counter;
use serde_json::json;

use super::count::{overlay_path, render_overlay};
use super::counter_args::CounterArgs;
use crate::evaluation::fingerprint::Fingerprint;
use crate::evaluation::intervals::MetricIntervals;
use crate::evaluation::leaf_errors::LeafErrors;
use crate::evaluation::metrics::{confusion, confusion_table, per_view, CountMetrics, CountPair};
use crate::evaluation::segment_table::{self, SegmentRow};
use crate::evaluation::segmentation::{panoptic_quality, LeafMatch, Overlaps, PixelMap};
use crate::evaluation::tip_errors::{TipErrors, TipMatch, TipOutcome};
use crate::evaluation::{plots, sources, tip_overlay};

/// Arguments of `phyllo eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model and runtime options.
    #[command(flatten)]
    pub counter: CounterArgs,
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
    /// post-processing rules offline (`python -m phyllo_train.segment_rules`).
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

impl Args {
    /// The manifest split to keep, `None` for `--split all`.
    fn split_filter(&self) -> Option<&str> {
        (self.split != "all").then_some(self.split.as_str())
    }
}

/// Runs the evaluation.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.fingerprint_only {
        return print_fingerprint(&args);
    }
    let c = Contract::embedded();
    let mut config = args.counter.config()?;
    let dataset_mode = args.dataset.is_some();
    if dataset_mode {
        // phyllo-gen renders at the contract's scale; --scale still overrides.
        config.scale = config.scale.or(Some(1.0));
    }
    let counter = Counter::new(config)?;
    if !counter.model_info().trained {
        eprintln!(
            "phyllo: warning: model {} is UNTRAINED: these numbers mean nothing",
            counter.model_id()
        );
    }
    let mut pairs = Vec::new();
    let mut matches: Vec<LeafMatch> = Vec::new();
    let mut leaf_errors = LeafErrors::default();
    let mut segment_rows: Vec<SegmentRow> = Vec::new();
    let mut tip_errors = TipErrors::new(args.tip_radius);
    let mut tip_outcomes: Vec<(String, TipOutcome)> = Vec::new();
    let mut failed = Vec::new();
    let mut fingerprint = Fingerprint::default();
    // The title names the source in full; a plot's caption has room for the
    // folder's name only.
    let (title, caption);
    if let Some(dir) = &args.dataset {
        let split = args.split_filter();
        // Until 2026-11-24 the default was the post-processing's minimum leaf
        // area (96 px), which tied the truth to a tuned parameter and gave
        // seedlings with five visible leaves a truth of 0.
        let min_pixels = args.truth_min_pixels.max(1);
        let detail = format!("({}; truth: leaves of at least {min_pixels} px)", args.split);
        title = format!("{} {detail}", dir.display());
        let folder = dir.file_name().map(|f| f.to_string_lossy().into_owned());
        caption = format!("{} {detail}", folder.unwrap_or_else(|| dir.display().to_string()));
        for item in sources::read_manifest(dir, split)? {
            let outcome = (|| -> anyhow::Result<(CountPair, LeafMatch, Overlaps)> {
                let bytes = std::fs::read(&item.image)
                    .with_context(|| format!("cannot read {}", item.image.display()))?;
                let analysis = counter.analyse_bytes(&item.image, &bytes)?;
                let label_bytes = std::fs::read(&item.label)
                    .with_context(|| format!("cannot read label {}", item.label.display()))?;
                let label = image::load_from_memory(&label_bytes)
                    .with_context(|| format!("cannot decode label {}", item.label.display()))?
                    .into_luma16();
                fingerprint.add_pair(&item, &bytes, &label_bytes);
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
                    segment_rows.extend(segment_table::rows(
                        &item.name,
                        pair.truth,
                        pair.predicted,
                        &overlaps,
                        &analysis.panoptic,
                    ));
                }
                Ok((pair, LeafMatch::of(&overlaps), overlaps))
            })();
            match outcome {
                Ok((p, m, o)) => {
                    pairs.push(p);
                    matches.push(m);
                    leaf_errors.add(&o);
                }
                Err(e) => failed.push(format!("{e:#}")),
            }
        }
    } else if let (Some(csv), Some(images)) = (&args.counts, &args.images) {
        if let Some(dir) = &args.tip_overlays {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create tip overlay directory {}", dir.display()))?;
        }
        title = csv
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        caption = title.clone();
        for hc in sources::read_counts(csv, images)? {
            let outcome = (|| -> anyhow::Result<(u32, Option<TipOutcome>)> {
                let bytes = std::fs::read(&hc.image)
                    .with_context(|| format!("cannot read {}", hc.image.display()))?;
                fingerprint.add_human_count(&hc, &bytes);
                let analysis = counter.analyse_bytes(&hc.image, &bytes)?;
                let Some(tips) = &hc.tips else {
                    return Ok((analysis.result.leaf_count, None));
                };
                let [w, h] = analysis.result.image_size;
                let pred = PixelMap::from_analysis(c, &analysis, w as usize, h as usize);
                let m = TipMatch::of(tips, &pred, args.tip_radius);
                if let Some(dir) = &args.tip_overlays {
                    let mut drawn = render_overlay(&counter, &hc.image, &bytes, &analysis)?;
                    tip_overlay::draw(&mut drawn, tips, &m, &analysis.result.instances);
                    let out = overlay_path(dir, &hc.image, "tips");
                    drawn
                        .save(&out)
                        .with_context(|| format!("cannot write tip overlay {}", out.display()))?;
                }
                Ok((analysis.result.leaf_count, Some(m.outcome)))
            })();
            match outcome {
                Ok((predicted, tips)) => {
                    let file = hc.image.display().to_string();
                    if let Some(t) = tips {
                        tip_errors.add(&t);
                        tip_outcomes.push((file.clone(), t));
                    }
                    pairs.push(CountPair {
                        file,
                        view: hc.view,
                        truth: hc.count,
                        predicted,
                    });
                }
                Err(e) => failed.push(format!("{e:#}")),
            }
        }
    } else {
        bail!("give --dataset DIR, or --counts CSV with --images DIR");
    }

    if let Some(path) = &args.segments {
        segment_table::write_tsv(path, &segment_rows)?;
    }
    let metrics = CountMetrics::of(&pairs);
    let views = per_view(&pairs);
    let intervals = MetricIntervals::of(&pairs);
    let seg = (!matches.is_empty()).then(|| {
        let miou = matches.iter().map(|m| m.mean_iou).sum::<f64>() / matches.len() as f64;
        (miou, panoptic_quality(&matches))
    });
    if let Some(dir) = &args.plots {
        plots::write(&pairs, &metrics, &caption, dir)?;
    }
    if args.json {
        let conf: Vec<_> = confusion(&pairs)
            .into_iter()
            .map(|((t, p), n)| json!([t, p, n]))
            .collect();
        let mut v = json!({
            "model": counter.model_id(),
            "tip_output": counter.model_info().has_tips,
            "count_rule": counter.count_rule(),
            "postprocess": counter.config().postprocess,
            "source": title,
            "fingerprint": fingerprint.hex(),
            "metrics": metrics,
            "intervals": intervals,
            "per_view": views,
            "confusion": conf,
            "failed": failed,
        });
        if let Some((miou, pq)) = seg {
            v["mean_iou"] = json!(miou);
            v["panoptic_quality"] = json!(pq);
            v["leaf_errors"] = json!(leaf_errors);
        }
        if tip_errors.images > 0 {
            v["tip_errors"] = json!(tip_errors);
        }
        if args.per_image {
            v["images"] = json!(pairs);
            if !tip_outcomes.is_empty() {
                v["tip_outcomes"] = json!(tip_outcomes
                    .iter()
                    .map(|(f, t)| json!({"file": f, "tips": t}))
                    .collect::<Vec<_>>());
            }
        }
        println!("{v}");
    } else {
        // Without a tip output every count rule counts centres; say so when
        // another rule was asked for.
        let (used, asked) = (counter.count_rule(), counter.config().postprocess.count_rule);
        println!(
            "model    {}  (tip output: {}; count rule: {used}{})",
            counter.model_id(),
            if counter.model_info().has_tips {
                "yes"
            } else {
                "no"
            },
            if used == asked {
                String::new()
            } else {
                format!(", not {asked}: no tip output")
            }
        );
        println!("post     {}", describe_postprocess(&counter.config().postprocess));
        println!("source   {title}");
        print_data_line(&fingerprint);
        if args.per_image {
            for p in &pairs {
                println!(
                    "{}\t{}\ttrue {}\tpredicted {}",
                    p.file, p.view, p.truth, p.predicted
                );
            }
        }
        println!();
        println!("| images | exact | within ±1 | RMSE | MAE | bias | R² |");
        println!("|---:|---:|---:|---:|---:|---:|---:|");
        print_row(&metrics);
        if let Some(i) = &intervals {
            println!("\n{}", i.line());
        }
        if let Some((miou, pq)) = seg {
            println!("\nmean leaf IoU per image (stem lenient) {miou:.3}\nleaf panoptic quality {pq:.3}");
            println!(
                "\nleaf errors (true leaves by visible area; every visible leaf, whatever the truth rule):\n{}",
                leaf_errors.table()
            );
        }
        if tip_errors.images > 0 {
            println!(
                "\nleaf tips (tips pair with predicted leaves that have a pixel within {} px, one to one and \
                 nearest first; true − predicted = reached by no leaf + fewer leaves − extra):\n{}",
                tip_errors.radius,
                tip_errors.table()
            );
            if args.per_image {
                for (f, t) in &tip_outcomes {
                    println!(
                        "{f}\ttips {}\town {}\tsharing {} (−{})\tunreached {}\textra {}",
                        t.tips,
                        t.own_leaf,
                        t.sharing,
                        t.merged_away,
                        t.unreached,
                        t.extra_total()
                    );
                }
            }
        }
        println!("\nper view:");
        println!("| view | images | exact | within ±1 | RMSE | MAE | bias | R² |");
        println!("|---|---:|---:|---:|---:|---:|---:|---:|");
        for (view, m) in &views {
            print!("| {view} ");
            print_row(m);
        }
        println!(
            "\nconfusion (rows: true count, columns: predicted):\n{}",
            confusion_table(&pairs)
        );
        for f in &failed {
            println!("failed: {f}");
        }
    }
    Ok(exit_code(&failed))
}

/// `--fingerprint-only`: reads the data as an evaluation would and prints its digest.
fn print_fingerprint(args: &Args) -> anyhow::Result<ExitCode> {
    let (source, (fingerprint, failed)) = if let Some(dir) = &args.dataset {
        let split = args.split_filter();
        (dir.display().to_string(), Fingerprint::of_dataset(dir, split)?)
    } else if let (Some(csv), Some(images)) = (&args.counts, &args.images) {
        (csv.display().to_string(), Fingerprint::of_counts(csv, images)?)
    } else {
        bail!("give --dataset DIR, or --counts CSV with --images DIR");
    };
    if args.json {
        let v = json!({
            "source": source,
            "fingerprint": fingerprint.hex(),
            "items": fingerprint.items(),
            "failed": failed,
        });
        println!("{v}");
    } else {
        println!("source   {source}");
        print_data_line(&fingerprint);
        for f in &failed {
            println!("failed: {f}");
        }
    }
    Ok(exit_code(&failed))
}

/// Exit status 1 when any item failed, so that scripts notice.
fn exit_code(failed: &[String]) -> ExitCode {
    if failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

fn print_data_line(fingerprint: &Fingerprint) {
    println!(
        "data     {} ({} items read; sha256 of names, files and truths, models/eval-sets.tsv records each set's)",
        fingerprint.hex(),
        fingerprint.items()
    );
}

fn print_row(m: &CountMetrics) {
    println!(
        "| {} | {:.1}% | {:.1}% | {:.3} | {:.3} | {:+.3} | {:.3} |",
        m.images,
        m.exact * 100.0,
        m.within_1 * 100.0,
        m.rmse,
        m.mae,
        m.bias,
        m.r2
    );
}

/// One line naming the post-processing settings a run counted with.
fn describe_postprocess(p: &phyllo_inference::postprocess::PostprocessParams) -> String {
    let pieces = if p.split_min_area == 0 {
        "off".to_string()
    } else {
        format!(
            "from {} px (gap {}, at most {} of the route on another leaf)",
            p.split_min_area, p.split_gap, p.split_max_leaf_share
        )
    };
    format!(
        "centre threshold {}, NMS {}, min leaf area {}, attach radius {}, separate pieces as leaves {pieces} (output pixels)",
        p.center_threshold, p.nms_kernel, p.min_leaf_area, p.attach_radius
    )
}
