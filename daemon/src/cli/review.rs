//! `phyllo review --config FILE [--top N] [--since DATE] [--plant P] [--csv SHEET.csv] [--overlays DIR] [--json]`.

use std::path::PathBuf;

use anyhow::Context;

use super::ConfigArg;
use crate::counting::{counter_config, OnnxCounter};
use crate::domain::names::{NamePatterns, View};
use crate::domain::review::{rank, NIGHTLY};
use crate::sinks::review_sheet;
use crate::store::Store;

/// Arguments of `phyllo review`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// How many sessions to list.
    #[arg(long, default_value_t = NIGHTLY)]
    top: usize,
    /// Only sessions from this date (YYYY-MM-DD) or time on.
    #[arg(long, value_name = "DATE", value_parser = crate::ops::import_csv::parse_since)]
    since: Option<String>,
    /// Only this plant's sessions.
    #[arg(long, value_name = "NAME")]
    plant: Option<String>,
    /// Also write them as a sheet to fill in and hand to `phyllo import`.
    #[arg(long, value_name = "SHEET.csv")]
    csv: Option<PathBuf>,
    /// Also count each listed session's images again with the configured
    /// model and draw what it found into DIR, one overlay PNG per image.
    #[arg(long, value_name = "DIR")]
    overlays: Option<PathBuf>,
    /// Print JSON (each session with its views, fit and images) instead of the table.
    #[arg(long)]
    json: bool,
}

/// Runs `phyllo review`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    let timelines = match &args.plant {
        Some(p) => store.plant_timeline(p)?.into_iter().collect::<Vec<_>>(),
        None => store.plant_timelines()?,
    };
    if let (Some(p), true) = (&args.plant, timelines.is_empty()) {
        anyhow::bail!("no plant {p:?} in {}", config.database.display());
    }
    let ranked = rank(&timelines, args.since.as_deref());
    let items = review_sheet::items(&store, &ranked, args.top)?;
    if let Some(out) = &args.csv {
        let n = review_sheet::write(out, &items)?;
        eprintln!(
            "{n} sessions to check → {} (fill in leaf_count, then `phyllo import` it)",
            out.display()
        );
    }
    if let Some(dir) = &args.overlays {
        let (drawn, missing) = draw_overlays(&config, &items, dir)?;
        eprintln!(
            "{drawn} overlays → {}{}",
            dir.display(),
            if missing > 0 {
                format!(" ({missing} images no longer in the drop directory)")
            } else {
                String::new()
            }
        );
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&items)?);
        return Ok(());
    }
    println!(
        "{} of {} sessions in doubt{}:",
        items.len(),
        ranked.len(),
        if items.len() < ranked.len() {
            " (the most doubtful first)"
        } else {
            ""
        }
    );
    for it in &items {
        let d = &it.doubt;
        println!("{}\t{}\t{}", d.plant, d.start, d.why());
        for image in &it.images {
            println!("\t{image}");
        }
    }
    Ok(())
}

/// Counts every image of `items` again and draws its overlay into
/// `dir/<rank>-<plant>/`; returns (overlays drawn, images missing).
fn draw_overlays(
    config: &crate::config::Config,
    items: &[review_sheet::Item],
    dir: &std::path::Path,
) -> anyhow::Result<(usize, usize)> {
    let counter = OnnxCounter::new(counter_config(&config.inference))?;
    let names = NamePatterns::from_config(&config.names)?;
    let (mut drawn, mut missing) = (0, 0);
    for (i, it) in items.iter().enumerate() {
        let out_dir = dir.join(format!("{:02}-{}", i + 1, sanitize(&it.doubt.plant)));
        std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
        for rel in &it.images {
            let path = config.drop_dir.join(crate::domain::rel_path::decode(rel));
            let bytes = match std::fs::read(&path) {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    missing += 1;
                    continue;
                }
                Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
            };
            // The name is read here, once, as the service read it; a name
            // the patterns no longer read is counted as a side view.
            let view = names
                .parse(std::path::Path::new(rel))
                .map_or(View::Other(String::new()), |n| n.view);
            let facts = counter.facts(&path, &view);
            let analysis = counter.inner().analyse_bytes(&path, &facts, &bytes)?;
            let picture = super::count::render_overlay(counter.inner(), &path, &bytes, &analysis)?;
            // Facility layouts reuse file names across folders (`0_0_0.png`),
            // so the whole relative path names the overlay.
            let stem = std::path::Path::new(rel).with_extension("");
            let out = out_dir.join(format!("{}.overlay.png", sanitize(&stem.to_string_lossy())));
            picture
                .save(&out)
                .with_context(|| format!("writing {}", out.display()))?;
            drawn += 1;
        }
    }
    Ok((drawn, missing))
}

/// A path component from `s`: separators and other awkward characters become `_`.
fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}
