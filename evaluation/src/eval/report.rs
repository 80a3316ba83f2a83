//! What `phyllo eval` prints: one JSON object, or the text tables.

use std::process::ExitCode;

use anyhow::bail;
use phyllo_inference::postprocess::PostprocessParams;
use phyllo_inference::Counter;
use serde_json::json;

use super::{EvalArgs, Gathered, Summary};
use crate::fingerprint::Fingerprint;
use crate::metrics::{confusion, confusion_table, CountMetrics};

/// `--json`: the whole report as one JSON object.
pub(super) fn print_json(args: &EvalArgs, counter: &Counter, run: &Gathered, s: &Summary) {
    let conf: Vec<_> = confusion(&run.pairs)
        .into_iter()
        .map(|((t, p), n)| json!([t, p, n]))
        .collect();
    let mut v = json!({
        "model": counter.model_id(),
        "tip_output": counter.model_info().has_tips,
        "count_rule": counter.count_rule(),
        "postprocess": counter.config().postprocess,
        "source": run.title,
        "fingerprint": run.fingerprint.hex(),
        "metrics": s.metrics,
        "intervals": s.intervals,
        "per_view": s.views,
        "confusion": conf,
        "failed": run.failed,
    });
    if let Some((miou, pq)) = s.seg {
        v["mean_iou"] = json!(miou);
        v["panoptic_quality"] = json!(pq);
        v["leaf_errors"] = json!(run.leaf_errors);
    }
    if run.tip_errors.images > 0 {
        v["tip_errors"] = json!(run.tip_errors);
    }
    if args.per_image {
        v["images"] = json!(run.pairs);
        if !run.tip_outcomes.is_empty() {
            v["tip_outcomes"] = json!(run
                .tip_outcomes
                .iter()
                .map(|(f, t)| json!({"file": f, "tips": t}))
                .collect::<Vec<_>>());
        }
    }
    println!("{v}");
}

/// The text report: model and data lines, then the tables.
pub(super) fn print_text(args: &EvalArgs, counter: &Counter, run: &Gathered, s: &Summary) {
    print_model_lines(counter);
    println!("source   {}", run.title);
    print_data_line(&run.fingerprint);
    if args.per_image {
        for p in &run.pairs {
            println!(
                "{}\t{}\ttrue {}\tpredicted {}",
                p.file, p.view, p.truth, p.predicted
            );
        }
    }
    println!();
    println!("| images | exact | within ±1 | RMSE | MAE | bias | R² |");
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    print_row(&s.metrics);
    if let Some(i) = &s.intervals {
        println!("\n{}", i.line());
    }
    if let Some((miou, pq)) = s.seg {
        println!("\nmean leaf IoU per image (stem lenient) {miou:.3}\nleaf panoptic quality {pq:.3}");
        println!(
            "\nleaf errors (true leaves by visible area; every visible leaf, whatever the truth rule):\n{}",
            run.leaf_errors.table()
        );
    }
    if run.tip_errors.images > 0 {
        print_tips(args, run);
    }
    println!("\nper view:");
    println!("| view | images | exact | within ±1 | RMSE | MAE | bias | R² |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for (view, m) in &s.views {
        print!("| {view} ");
        print_row(m);
    }
    println!(
        "\nconfusion (rows: true count, columns: predicted):\n{}",
        confusion_table(&run.pairs)
    );
    for f in &run.failed {
        println!("failed: {f}");
    }
}

/// The `model` and `post` lines: which model counted, and how.
fn print_model_lines(counter: &Counter) {
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
}

/// The leaf tips table, and each image's tips with `--per-image`.
fn print_tips(args: &EvalArgs, run: &Gathered) {
    println!(
        "\nleaf tips (tips pair with predicted leaves that have a pixel within {} px, one to one and \
         nearest first; true − predicted = reached by no leaf + fewer leaves − extra):\n{}",
        run.tip_errors.radius,
        run.tip_errors.table()
    );
    if args.per_image {
        for (f, t) in &run.tip_outcomes {
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

/// `--fingerprint-only`: reads the data as an evaluation would and prints its digest.
pub(super) fn print_fingerprint(args: &EvalArgs) -> anyhow::Result<ExitCode> {
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
pub(super) fn exit_code(failed: &[String]) -> ExitCode {
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
fn describe_postprocess(p: &PostprocessParams) -> String {
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
