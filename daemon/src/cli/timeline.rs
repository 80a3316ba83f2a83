//! `phyllo timeline --config FILE PLANT [--plot OUT.png [--degree-days]] [--sites DIR] [--json]`,
//! or `phyllo timeline --config FILE --plots DIR [--degree-days]` for every plant's plot.

use std::path::PathBuf;

use anyhow::{bail, Context};

use super::ConfigArg;
use crate::sinks::plot::TimeAxis;
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
    /// Draw every plant's timeline into `DIR/<plant>.png`.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["plant", "plot", "json"])]
    plots: Option<PathBuf>,
    /// Draw where each new leaf emerged on the image it was found in, into
    /// `DIR/<plant>-leaf-<NN>.png` (images read from the drop directory).
    #[arg(long, value_name = "DIR", requires = "plant")]
    sites: Option<PathBuf>,
    /// Plot against the degree-days of the imported temperature log (above
    /// `[timeline] base_temp_c`) instead of days.
    #[arg(long)]
    degree_days: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `phyllo timeline`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    let clocks = if args.degree_days {
        if args.plot.is_none() && args.plots.is_none() {
            bail!("--degree-days sets a plot's axis: give --plot OUT.png or --plots DIR");
        }
        let clocks = store.zone_clocks(config.rules().timeline.zones.clone(), config.timeline.base_temp_c)?;
        if clocks.is_empty() {
            bail!(
                "--degree-days: {} has no temperature log; import one first (phyllo import LOG.csv, columns timestamp,temp_c)",
                config.database.display()
            );
        }
        Some(clocks)
    } else {
        None
    };
    if let Some(dir) = &args.plots {
        let drawn = crate::sinks::plot::plot_all(&store.plant_timelines()?, dir, clocks.as_ref())?;
        eprintln!(
            "{} plots written to {} ({} plants without a counted session{})",
            drawn.files.len(),
            dir.display(),
            drawn.empty,
            if drawn.in_days > 0 {
                format!(
                    "; {} drawn in days, their sessions outside their temperature log",
                    drawn.in_days
                )
            } else {
                String::new()
            }
        );
        return Ok(());
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
        let axis = match &clocks {
            None => TimeAxis::Days,
            Some(c) => TimeAxis::DegreeDays(c.for_plant(plant).with_context(|| {
                format!(
                    "--degree-days: plant {plant} is timed by {}, which has no readings; import it \
                     (a temperature log whose zone column says {:?})",
                    crate::domain::climate_zone::describe(c.zone_of(plant)),
                    c.zone_of(plant)
                )
            })?),
        };
        crate::sinks::plot::plot(&t, out, axis)?;
        eprintln!("plot written to {}", out.display());
    }
    if let Some(dir) = &args.sites {
        let written = crate::sinks::site_overlay::draw_sites(&t, &config.drop_dir, dir)?;
        eprintln!(
            "{} of {} new leaves drawn where they emerged into {}",
            written.len(),
            t.events.len(),
            dir.display()
        );
    }
    Ok(())
}

/// Where a view's column goes: side views by angle, then top views, then
/// people's counts (`human:…`) and anything else by name.
fn view_order(view: &str) -> (u8, u64, &str) {
    let kind_angle = view
        .split_once('_')
        .and_then(|(kind, angle)| Some((kind, angle.parse::<u64>().ok()?)));
    match kind_angle {
        Some(("SV", angle)) => (0, angle, view),
        Some(("TV", angle)) => (1, angle, view),
        _ => (2, 0, view),
    }
}

/// The timeline as a text table.
pub fn render(t: &PlantTimeline) -> String {
    let mut views: Vec<&String> = t.sessions.iter().flat_map(|s| s.views.keys()).collect();
    views.sort_by_key(|v| view_order(v));
    views.dedup();
    let mut s = format!("plant {}\n", t.plant);
    s += &format!("{:<24}", "session");
    // A column as wide as its view's name (`human:ana`), at least 8.
    let width = |v: &str| (v.chars().count() + 1).max(8);
    for v in &views {
        s += &format!("{v:>w$}", w = width(v));
    }
    s += &format!("{:>8}{:>9}{:>8}{:>6}\n", "fused", "emerged", "living", "lost");
    for row in &t.sessions {
        s += &format!("{:<24}", row.start);
        for v in &views {
            let w = width(v);
            match row.views.get(*v) {
                Some(c) => s += &format!("{c:>w$}"),
                None => s += &format!("{:>w$}", "-"),
            }
        }
        s += &format!(
            "{:>8.1}{:>9}{:>8.1}{:>6}\n",
            row.fused,
            crate::domain::timeline::whole_leaves(row.leaves_emerged),
            row.living,
            row.leaves_lost
        );
    }
    s += "emergence events:\n";
    if t.events.is_empty() {
        s += "  (none yet: need a rise in the fitted count after the first session)\n";
    }
    for (leaf, at, seen) in &t.events {
        s += &format!("  leaf {leaf:>2} emerged about {at} (first counted {seen})");
        if let Some(site) = t.sites.iter().find(|x| x.leaf == *leaf) {
            s += &format!(
                "; seen in {} at ({:.0}, {:.0}), {} px",
                site.view, site.centre[0], site.centre[1], site.area
            );
        }
        s += "\n";
    }
    match (t.phyllochron_days, t.phyllochron_cd) {
        (Some(p), Some(cd)) => {
            s += &format!(
                "phyllochron: {p:.2} days per leaf, {cd:.1} degree-days per leaf{}\n",
                if t.climate_zone.is_empty() {
                    String::new()
                } else {
                    format!(" (zone {})", t.climate_zone)
                }
            )
        }
        (Some(p), None) => s += &format!("phyllochron: {p:.2} days per leaf\n"),
        (None, _) => s += "phyllochron: n/a (fewer than two emergence events)\n",
    }
    if let Some(crate::store::NextLeafRow { leaf, expected: at }) = &t.next_leaf {
        s += &format!(
            "next leaf:   {leaf} expected about {} (one phyllochron after the last){}\n",
            at.get(..16).unwrap_or(at),
            overdue(at, t.sessions.last().map(|x| x.start.as_str()))
        );
    }
    s
}

/// "; not counted by the last session, N days after it was due" when the
/// last session is past the expected time: a late leaf, a stressed plant, or
/// the flag leaf.
fn overdue(expected: &str, last_session: Option<&str>) -> String {
    let (Ok(at), Some(Ok(last))) = (
        crate::store::parse_iso(expected),
        last_session.map(crate::store::parse_iso),
    ) else {
        return String::new();
    };
    crate::domain::forecast::days_overdue(at, last).map_or(String::new(), |late| {
        format!("; not counted by the last session, {late:.1} days after it was due")
    })
}

#[cfg(test)]
mod tests {
    use super::view_order;

    #[test]
    fn views_sort_by_angle_then_top_then_people() {
        let mut v = ["human:ana", "SV_36", "TV_90", "SV_108", "SV_0", "SV_144", "SV_72"];
        v.sort_by_key(|v| view_order(v));
        assert_eq!(
            v,
            ["SV_0", "SV_36", "SV_72", "SV_108", "SV_144", "TV_90", "human:ana"]
        );
    }
}
