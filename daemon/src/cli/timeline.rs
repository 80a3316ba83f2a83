//! `phyllo timeline --config FILE PLANT [--plot OUT.png] [--json]`, or
//! `phyllo timeline --config FILE --plots DIR` for every plant's plot.

use std::path::PathBuf;

use anyhow::{bail, Context};

use super::ConfigArg;
use crate::store::{PlantTimeline, Store};

/// Arguments of `phyllo timeline`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Plant id (leave out with --plots to draw every plant).
    #[arg(required_unless_present = "plots")]
    plant: Option<String>,
    /// Also draw the timeline into this PNG.
    #[arg(long, value_name = "OUT.png", requires = "plant")]
    plot: Option<PathBuf>,
    /// Draw every plant's timeline into DIR/<plant>.png.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["plant", "plot", "json"])]
    plots: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `phyllo timeline`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    if let Some(dir) = &args.plots {
        return plot_all(&store, dir);
    }
    let plant = args
        .plant
        .as_deref()
        .expect("clap requires a plant without --plots");
    let Some(t) = store.plant_timeline(plant)? else {
        let plants = store.plants()?;
        let some: Vec<&str> = plants.iter().take(10).map(|s| s.as_str()).collect();
        bail!(
            "no plant '{}' in {} ({} plants, e.g. {})",
            plant,
            config.database.display(),
            plants.len(),
            some.join(", ")
        );
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&t)?);
    } else {
        print!("{}", render(&t));
    }
    if let Some(out) = &args.plot {
        crate::sinks::plot::plot(&t, out)?;
        eprintln!("plot written to {}", out.display());
    }
    Ok(())
}

/// Draws every plant with a session into `dir`, one PNG per plant.
fn plot_all(store: &Store, dir: &std::path::Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let (mut drawn, mut empty) = (0, 0);
    let mut used = std::collections::HashSet::new();
    for plant in store.plants()? {
        match store.plant_timeline(&plant)? {
            Some(t) if !t.sessions.is_empty() => {
                // Two ids that differ only in replaced characters must not share a file.
                let mut stem = file_stem(&plant);
                let mut n = 1;
                while !used.insert(stem.clone()) {
                    n += 1;
                    stem = format!("{}_{n}", file_stem(&plant));
                }
                crate::sinks::plot::plot(&t, &dir.join(format!("{stem}.png")))?;
                drawn += 1;
            }
            _ => empty += 1,
        }
    }
    eprintln!(
        "{drawn} plots written to {} ({empty} plants without a counted session)",
        dir.display()
    );
    Ok(())
}

/// A plant id as a file name: anything but letters, digits, `-`, `_` and `.` becomes `_`.
fn file_stem(plant: &str) -> String {
    let stem: String = plant
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    // A leading dot would hide the file; `..` would name the parent.
    match stem.strip_prefix('.') {
        Some(rest) => format!("_{rest}"),
        None => stem,
    }
}

/// The timeline as a text table.
pub fn render(t: &PlantTimeline) -> String {
    let mut views: Vec<&String> = t.sessions.iter().flat_map(|s| s.views.keys()).collect();
    views.sort();
    views.dedup();
    let mut s = format!("plant {}\n", t.plant);
    s += &format!("{:<24}", "session");
    for v in &views {
        s += &format!("{v:>8}");
    }
    s += &format!("{:>8}{:>9}{:>8}{:>6}\n", "fused", "emerged", "living", "lost");
    for row in &t.sessions {
        s += &format!("{:<24}", row.start);
        for v in &views {
            match row.views.get(*v) {
                Some(c) => s += &format!("{c:>8}"),
                None => s += &format!("{:>8}", "-"),
            }
        }
        s += &format!(
            "{:>8.1}{:>9.2}{:>8.1}{:>6}\n",
            row.fused, row.leaves_emerged, row.living, row.leaves_lost
        );
    }
    s += "emergence events:\n";
    if t.events.is_empty() {
        s += "  (none yet: need a rise in the fitted count after the first session)\n";
    }
    for (leaf, at, seen) in &t.events {
        s += &format!("  leaf {leaf:>2} emerged about {at} (first counted {seen})\n");
    }
    match t.phyllochron_days {
        Some(p) => s += &format!("phyllochron: {p:.2} days per leaf\n"),
        None => s += "phyllochron: n/a (fewer than two emergence events)\n",
    }
    s
}

#[cfg(test)]
mod tests {
    use super::file_stem;

    #[test]
    fn plant_ids_become_plain_file_names() {
        assert_eq!(file_stem("402-348-N276-WW-1"), "402-348-N276-WW-1");
        assert_eq!(file_stem("a/b c"), "a_b_c");
        assert_eq!(file_stem(".."), "_.");
    }
}
