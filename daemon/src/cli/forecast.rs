//! `phyllo forecast --config FILE [--leaf N] [--plant P] [--json]`: when each
//! plant reaches a leaf stage. Physiologists sample and treat plants at a
//! stage ("at six leaves"), so this says, per plant, when leaf N appeared or
//! should appear: by thermal time where the plant's temperature log covers
//! its last leaf, else by days ([`crate::domain::forecast`]). Without `--leaf`, each
//! plant's next leaf, as `plants.csv` gives it.

use anyhow::bail;
use chrono::NaiveDateTime;
use serde::Serialize;

use super::ConfigArg;
use crate::domain::climate_zone::ZoneClocks;
use crate::store::{parse_iso, PlantTimeline, Store};

/// Arguments of `phyllo forecast`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// The leaf stage: when each plant reaches its leaf N (default: each plant's next leaf).
    #[arg(long, value_name = "N")]
    leaf: Option<u32>,
    /// Only this plant.
    #[arg(long)]
    plant: Option<String>,
    /// One JSON array instead of a table.
    #[arg(long)]
    json: bool,
}

/// One plant's answer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Due {
    /// Plant id.
    pub plant: String,
    /// Leaves dated so far.
    pub leaves: u32,
    /// The leaf asked about.
    pub leaf: u32,
    /// When it appeared (`emerged`) or should appear (`expected`), facility local time.
    pub at: String,
    /// `emerged`, `degree-days` (forecast by thermal time) or `days`.
    pub how: &'static str,
}

/// Runs `phyllo forecast`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    let clocks = store.zone_clocks(config.rules().timeline.zones.clone(), config.timeline.base_temp_c)?;
    let timelines = match &args.plant {
        Some(p) => match store.plant_timeline(p)? {
            Some(t) => vec![t],
            None => bail!("no plant {p:?} in {}", config.database.display()),
        },
        None => store.plant_timelines()?,
    };
    let mut rows = Vec::new();
    let mut undated = 0;
    for t in &timelines {
        match due(t, args.leaf, &clocks)? {
            Some(d) => rows.push(d),
            None => undated += 1,
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    if rows.is_empty() {
        println!(
            "no forecast: {}",
            if timelines.is_empty() {
                format!("no plant in {} has a timeline yet", config.database.display())
            } else {
                format!(
                    "none of the {} plants has three dated leaves (or a forward rate) yet",
                    timelines.len()
                )
            }
        );
        return Ok(());
    }
    println!("plant\tleaves\tleaf\twhen\thow");
    for d in &rows {
        println!(
            "{}\t{}\t{}\t{}\t{}",
            d.plant,
            d.leaves,
            d.leaf,
            d.at.get(..16).unwrap_or(&d.at),
            d.how
        );
    }
    if undated > 0 {
        eprintln!("{undated} plants without three dated leaves (or a forward rate) have no forecast");
    }
    Ok(())
}

/// When plant `t` reaches `leaf` (default: its next leaf); `None` without
/// three dated leaves or a forward rate.
pub fn due(t: &PlantTimeline, leaf: Option<u32>, clocks: &ZoneClocks) -> anyhow::Result<Option<Due>> {
    let events: Vec<(u32, NaiveDateTime)> = t
        .events
        .iter()
        .map(|(leaf, at, _)| Ok((*leaf, parse_iso(at)?)))
        .collect::<anyhow::Result<_>>()?;
    let Some(&(last, _)) = events.last() else {
        return Ok(None);
    };
    let leaf = leaf.unwrap_or(last + 1);
    if let Some((_, at, _)) = t.events.iter().find(|e| e.0 == leaf) {
        return Ok(Some(Due {
            plant: t.plant.clone(),
            leaves: last,
            leaf,
            at: at.clone(),
            how: "emerged",
        }));
    }
    let found = crate::domain::forecast::leaf_due_by_either(
        &events,
        t.phyllochron_days,
        t.phyllochron_cd,
        clocks.for_plant(&t.plant),
        leaf,
    );
    Ok(found.map(|(n, basis)| Due {
        plant: t.plant.clone(),
        leaves: last,
        leaf,
        at: crate::store::iso(n.at),
        how: match basis {
            crate::domain::forecast::Basis::DegreeDays => "degree-days",
            crate::domain::forecast::Basis::Days => "days",
        },
    }))
}
