//! `phyllo groups --config FILE [--csv DIR] [--plot OUT.png] [--json]`.

use std::path::PathBuf;

use anyhow::bail;

use super::ConfigArg;
use crate::groups::{GroupRule, Spread};
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
    let Some(rule) = GroupRule::from_config(&config.groups)? else {
        bail!(
            "no [groups] pattern in {}: set one to read genotype, treatment, ... from plant ids (systemd/phyllo.toml.example)",
            args.config.config.display()
        );
    };
    let store = Store::open_read_only(&config.database)?;
    let rep = crate::groups::summarise(&rule, &store.plant_timelines()?);
    if let Some(dir) = &args.csv {
        let n = group_report::write_groups(&rule, &rep, &dir.join("groups.csv"))?;
        let d = group_report::write_days(&rule, &rep, &dir.join("group_days.csv"))?;
        eprintln!(
            "groups.csv: {n} rows, group_days.csv: {d} rows → {}",
            dir.display()
        );
    }
    if let Some(out) = &args.plot {
        group_report::plot(&rep, out)?;
        eprintln!("plot → {}", out.display());
    }
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
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
        return Ok(());
    }
    println!(
        "{}\tplants\tleaves emerged\tliving\tleaves lost\tphyllochron (days/leaf, n)\tlast session",
        rule.columns().join("\t")
    );
    for g in &rep.summaries {
        println!(
            "{}\t{}\t{}\t{}\t{}\t{} ({})\t{}",
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
    Ok(())
}
