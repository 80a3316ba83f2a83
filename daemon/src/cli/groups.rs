//! `phyllo groups --config FILE [--compare] [--csv DIR] [--plot OUT.png] [--json]`.

use std::path::PathBuf;

use anyhow::bail;

use super::ConfigArg;
use crate::domain::group_compare::Comparison;
use crate::domain::groups::{GroupReport, GroupRule, Spread};
use crate::sinks::group_report;
use crate::store::Store;

/// Arguments of `phyllo groups`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Also write `groups.csv` and `group_days.csv` into this directory.
    #[arg(long, value_name = "DIR")]
    csv: Option<PathBuf>,
    /// Also draw each group's leaves emerged per day into this PNG.
    #[arg(long, value_name = "OUT.png")]
    plot: Option<PathBuf>,
    /// Also test every two groups against each other (Welch's t-test on
    /// phyllochron, in days and in degree-days, and on leaves emerged,
    /// p-values Holm-adjusted).
    #[arg(long)]
    compare: bool,
    /// Print JSON (every group and day) instead of the table.
    #[arg(long)]
    json: bool,
}

fn cell(s: Option<Spread>) -> String {
    s.map_or("-".into(), |s| format!("{:.2} ± {:.2}", s.mean, s.sd))
}

/// Runs `phyllo groups`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let Some(rule) = &config.rules().groups else {
        bail!(
            "no [groups] pattern in {}: set one to read genotype, treatment, ... from plant ids (systemd/phyllo.toml.example)",
            args.config.config.display()
        );
    };
    let store = Store::open_read_only(&config.database)?;
    let timelines = store.plant_timelines()?;
    let rep = crate::domain::groups::summarise(rule, &timelines);
    let pairs = if args.compare || args.csv.is_some() {
        crate::domain::group_compare::compare(rule, &timelines)
    } else {
        Vec::new()
    };
    write_files(&args, rule, &rep, &pairs)?;
    warn_unmatched(&rep);
    if args.json {
        let mut value = serde_json::to_value(&rep)?;
        if args.compare {
            value["pairs"] = serde_json::to_value(&pairs)?;
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    print_summaries(rule, &rep);
    if args.compare {
        print_pairs(rule, &pairs);
    }
    Ok(())
}

/// `--csv` and `--plot`, named on stderr so that stdout stays the table or the JSON.
fn write_files(args: &Args, rule: &GroupRule, rep: &GroupReport, pairs: &[Comparison]) -> anyhow::Result<()> {
    if let Some(dir) = &args.csv {
        let n = group_report::write_groups(rule, rep, &dir.join("groups.csv"))?;
        let d = group_report::write_days(rule, rep, &dir.join("group_days.csv"))?;
        let c = group_report::write_pairs(rule, pairs, &dir.join("group_pairs.csv"))?;
        eprintln!(
            "groups.csv: {n} rows, group_days.csv: {d} rows, group_pairs.csv: {c} rows → {}",
            dir.display()
        );
    }
    if let Some(out) = &args.plot {
        group_report::plot(rep, out)?;
        eprintln!("plot → {}", out.display());
    }
    Ok(())
}

/// Names the first plants no pattern matched: a typo in the pattern or an
/// odd plant id leaves them out of every group.
fn warn_unmatched(rep: &GroupReport) {
    if !rep.unmatched.is_empty() {
        let shown: Vec<&str> = rep.unmatched.iter().take(10).map(String::as_str).collect();
        let more = rep.unmatched.len().saturating_sub(shown.len());
        eprintln!(
            "plants matching no [groups] pattern ({}): {}{}",
            rep.unmatched.len(),
            shown.join(", "),
            if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            }
        );
    }
}

/// One tab-separated row per group, for a spreadsheet's paste.
fn print_summaries(rule: &GroupRule, rep: &GroupReport) {
    // The thermal column only once a temperature log gives one.
    let thermal = rep.summaries.iter().any(|g| g.phyllochron_cd.is_some());
    println!(
        "{}\tplants\tleaves emerged\tliving\tleaves lost\tphyllochron (days/leaf, n)\t{}last session",
        rule.columns().join("\t"),
        if thermal {
            "phyllochron (°Cd/leaf, n)\t"
        } else {
            ""
        }
    );
    for g in &rep.summaries {
        let cd = if thermal {
            format!(
                "{} ({})\t",
                cell(g.phyllochron_cd),
                g.phyllochron_cd.map_or(0, |s| s.n)
            )
        } else {
            String::new()
        };
        println!(
            "{}\t{}\t{}\t{}\t{}\t{} ({})\t{cd}{}",
            g.group.join("\t"),
            g.plants,
            cell(g.leaves_emerged),
            cell(g.living),
            cell(g.leaves_lost),
            cell(g.phyllochron_days),
            g.phyllochron_days.map_or(0, |s| s.n),
            g.last_session.get(..16).unwrap_or(&g.last_session)
        );
    }
}

/// `--compare`: every two groups' difference with its test, starred where
/// it holds after Holm's adjustment.
fn print_pairs(rule: &GroupRule, pairs: &[Comparison]) {
    if let Some(block) = rule.block_name() {
        println!(
            "\ncompared within blocks of {block}: each block's difference of means, tested over the blocks"
        );
    }
    println!("\nmeasure\tgroups\tplants\tdifference (95 % CI)\tp\tp (Holm)");
    for c in pairs {
        println!(
            "{}\t{} − {}\t{} / {}{}\t{:+.2} ({:+.2} to {:+.2})\t{:.3}\t{:.3}{}",
            c.measure,
            c.a.join("/"),
            c.b.join("/"),
            c.n_a,
            c.n_b,
            c.blocks.map_or(String::new(), |n| format!(" in {n} blocks")),
            c.difference,
            c.ci95.0,
            c.ci95.1,
            c.p,
            c.p_holm,
            if c.p_holm < 0.05 { "\t*" } else { "" }
        );
    }
}
