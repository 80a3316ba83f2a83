//! The one door between stored rows and the domain: a plant's stored
//! observations go to [`crate::domain::timeline`], [`crate::domain::leaf_site`],
//! [`crate::domain::thermal`] and [`crate::domain::forecast`], and what they
//! return is written back (sessions, events, the plant's summary, feed rows).
//! Everything here runs inside the caller's transaction.

use std::collections::{BTreeMap, BTreeSet};

use chrono::NaiveDateTime;
use rusqlite::{params, Connection, Transaction};

use super::feed::push_feed;
use rusqlite::TransactionBehavior;

use super::{iso, now_utc, parse_iso, site_rows, FeedRow, Store};
use crate::domain::leaf_site::Site;
use crate::domain::names::View;
use crate::domain::timeline::{self, Obs, Timeline, TimelineParams};

impl Store {
    /// Recomputes every plant's timeline (after `phyllo recount`), with a feed
    /// row for each leaf that newly emerged or was lost.
    pub fn recompute_all(&mut self) -> anyhow::Result<usize> {
        self.refit_every_plant(Announce::Each, None)
    }

    /// Refits every plant after its fit's settings changed, with one feed row
    /// saying so instead of one per leaf: the leaves it renumbers or reads as
    /// lost are not news from the greenhouse, and on a large site they would
    /// flood `phyllo tail` with today's time.
    pub fn refit_all(&mut self, why: &str) -> anyhow::Result<usize> {
        self.refit_every_plant(Announce::Nothing, Some(why))
    }

    fn refit_every_plant(&mut self, announce: Announce, summary: Option<&str>) -> anyhow::Result<usize> {
        let now = now_utc();
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let plants: Vec<(i64, String)> = tx
            .prepare("SELECT id, name FROM plants ORDER BY id")?
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_, _>>()?;
        refit_plants(&tx, &self.fit, &plants, &now, announce, |_, _| None)?;
        if let Some(why) = summary {
            push_feed(
                &tx,
                &FeedRow {
                    kind: "refit".into(),
                    message: Some(format!(
                        "{why}: {} plants refitted; `phyllo timeline` shows their leaves",
                        plants.len()
                    )),
                    ..FeedRow::default()
                },
                &now,
            )?;
        }
        tx.commit()?;
        Ok(plants.len())
    }
}

/// The settings every fit is made with: the domain's parameters and the
/// fusion rule's name as stored with each session.
#[derive(Debug, Clone)]
pub(super) struct Fit {
    /// The timeline's parameters.
    pub params: TimelineParams,
    /// The fusion rule as the config names it.
    pub rule: String,
}

/// Which feed rows a refit writes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Announce {
    /// One per newly emerged or newly lost leaf.
    Each,
    /// None (the caller writes a summary).
    Nothing,
}

/// What a refit changed, for the caller's feed row and reply.
pub(super) struct Diff {
    /// Leaves whose emergence is new.
    pub new_leaves: Vec<u32>,
    /// (fused, emerged, start) per session.
    pub sessions: Vec<(f64, f64, NaiveDateTime)>,
}

impl Diff {
    /// Fused count and leaves emerged of the session holding time `t`.
    pub fn at(&self, t: NaiveDateTime) -> (f64, f64) {
        self.sessions
            .iter()
            .rev()
            .find(|s| s.2 <= t)
            .or(self.sessions.first())
            .map_or((0.0, 0.0), |s| (s.0, s.1))
    }
}

/// Refits each of `plants` in order and pushes the feed row `row_for` makes
/// from the plant's name and what changed (none when it returns `None`).
/// Returns the diffs, in the order of `plants`.
pub(super) fn refit_plants(
    tx: &Transaction,
    fit: &Fit,
    plants: &[(i64, String)],
    now: &str,
    announce: Announce,
    row_for: impl Fn(&str, &Diff) -> Option<FeedRow>,
) -> anyhow::Result<Vec<Diff>> {
    let mut diffs = Vec::with_capacity(plants.len());
    for (id, name) in plants {
        let diff = recompute(tx, fit, *id, name, now, announce)?;
        if let Some(row) = row_for(name, &diff) {
            push_feed(tx, &row, now)?;
        }
        diffs.push(diff);
    }
    Ok(diffs)
}

/// Refits the plants that lost a superseded count, except `skip` (which the
/// caller refits itself).
pub(super) fn refresh(
    tx: &Transaction,
    fit: &Fit,
    plants: &[(i64, String)],
    skip: Option<i64>,
) -> anyhow::Result<()> {
    let stale: Vec<(i64, String)> = plants
        .iter()
        .filter(|(id, _)| Some(*id) != skip)
        .cloned()
        .collect();
    refit_plants(tx, fit, &stale, &now_utc(), Announce::Each, |_, _| None)?;
    Ok(())
}

/// Recomputes one plant's sessions, events and summary from all its current
/// observations, and appends a feed entry for each newly emerged or lost leaf.
fn recompute(
    tx: &Transaction,
    fit: &Fit,
    plant_id: i64,
    plant: &str,
    now: &str,
    announce: Announce,
) -> anyhow::Result<Diff> {
    let (obs, seen) = read_observations(tx, plant_id)?;
    let tl = timeline::compute(&obs, &fit.params);
    let sites = site_rows::event_sites(&tl, &seen);
    let old: BTreeSet<u32> = tx
        .prepare_cached("SELECT leaf FROM events WHERE plant_id = ?1")?
        .query_map([plant_id], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    let old_lost: f64 = tx
        .prepare_cached("SELECT COALESCE(MAX(leaves_lost), 0) FROM sessions WHERE plant_id = ?1")?
        .query_row([plant_id], |r| r.get(0))?;
    write_sessions(tx, plant_id, &tl, &fit.rule)?;
    write_events(tx, plant_id, &tl, &sites)?;
    if announce == Announce::Each {
        for row in leaf_news(plant, &tl, &sites, &old, old_lost) {
            push_feed(tx, &row, now)?;
        }
    }
    write_summary(tx, &fit.params, plant_id, plant, &tl, now)?;
    Ok(Diff {
        new_leaves: tl
            .events
            .iter()
            .map(|e| e.leaf)
            .filter(|l| !old.contains(l))
            .collect(),
        sessions: tl
            .sessions
            .iter()
            .map(|s| (s.fused, s.emerged, s.start))
            .collect(),
    })
}

/// A plant's current observations (superseded image versions left out),
/// and the images' leaf instances, kept as stored text until a site needs them.
fn read_observations(tx: &Transaction, plant_id: i64) -> anyhow::Result<(Vec<Obs>, Vec<site_rows::SeenRow>)> {
    let mut obs: Vec<Obs> = Vec::new();
    let mut seen: Vec<site_rows::SeenRow> = Vec::new();
    let rows = tx
        .prepare_cached(
            "SELECT o.taken_at, o.view, o.leaf_count, i.path, o.instances FROM observations o
             LEFT JOIN images i ON i.id = o.image_id
             WHERE o.plant_id = ?1 AND (o.image_id IS NULL OR i.superseded = 0)",
        )?
        .query_map([plant_id], |r| {
            Ok((
                r.get::<_, String>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, i64>(2)?,
                r.get::<_, Option<String>>(3)?,
                r.get::<_, Option<String>>(4)?,
            ))
        })?
        .collect::<Result<Vec<_>, _>>()?;
    for (t, v, c, path, instances) in rows {
        let taken_at = parse_iso(&t)?;
        if let (Some(image), Some(instances)) = (path, instances) {
            seen.push(site_rows::SeenRow {
                taken_at,
                view: v.clone(),
                image,
                instances,
            });
        }
        obs.push(Obs {
            taken_at,
            view: View::parse(&v),
            count: c as f64,
        });
    }
    Ok((obs, seen))
}

/// Replaces the plant's stored sessions with `tl`'s.
fn write_sessions(tx: &Transaction, plant_id: i64, tl: &Timeline, rule: &str) -> anyhow::Result<()> {
    tx.execute("DELETE FROM sessions WHERE plant_id = ?1", [plant_id])?;
    for s in &tl.sessions {
        let mut views = serde_json::Map::new();
        for (v, c) in &s.views {
            // Counts are integers except for fused imports; keep "9", not "9.0", in exports.
            let c = if c.fract() == 0.0 {
                serde_json::json!(*c as i64)
            } else {
                serde_json::json!(c)
            };
            views.insert(v.to_string(), c);
        }
        tx.prepare_cached(
            "INSERT INTO sessions (plant_id, start, views, n_counts, fused, fusion_rule, leaves_emerged, living, leaves_lost)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
        )?
        .execute(params![
            plant_id,
            iso(s.start),
            serde_json::Value::Object(views).to_string(),
            s.views.len() as i64,
            s.fused,
            rule,
            s.emerged,
            s.living,
            s.lost
        ])?;
    }
    Ok(())
}

/// Replaces the plant's stored emergence events (with their leaf sites) with `tl`'s.
fn write_events(
    tx: &Transaction,
    plant_id: i64,
    tl: &Timeline,
    sites: &[Option<Site>],
) -> anyhow::Result<()> {
    tx.execute("DELETE FROM events WHERE plant_id = ?1", [plant_id])?;
    for (e, site) in tl.events.iter().zip(sites) {
        tx.prepare_cached(
            "INSERT INTO events (plant_id, leaf, emerged_at, seen_at, site_view, site_image, site_x, site_y, site_bbox, site_area)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
        )?
        .execute(params![
            plant_id,
            e.leaf,
            iso(e.at),
            iso(e.seen_at),
            site.as_ref().map(|s| &s.view),
            site.as_ref().map(|s| &s.image),
            site.as_ref().map(|s| f64::from(s.leaf.centre[0])),
            site.as_ref().map(|s| f64::from(s.leaf.centre[1])),
            site.as_ref().map(|s| serde_json::json!(s.leaf.bbox).to_string()),
            site.as_ref().map(|s| s.leaf.area as i64)
        ])?;
    }
    Ok(())
}

/// The feed rows a refit announces: one per leaf that newly emerged, one per
/// leaf announced before that the fit no longer finds, then one per leaf
/// newly read as lost, dated by the session it first shows in.
fn leaf_news(
    plant: &str,
    tl: &Timeline,
    sites: &[Option<Site>],
    old: &BTreeSet<u32>,
    old_lost: f64,
) -> Vec<FeedRow> {
    let mut rows = Vec::new();
    for (e, site) in tl
        .events
        .iter()
        .zip(sites)
        .filter(|(e, _)| !old.contains(&e.leaf))
    {
        rows.push(FeedRow {
            kind: "event".into(),
            plant: Some(plant.to_string()),
            taken_at: Some(iso(e.at)),
            leaves_emerged: Some(e.leaf as f64),
            new_leaves: vec![e.leaf],
            message: Some(format!(
                "leaf {} emerged about {}{}",
                e.leaf,
                e.at.format("%Y-%m-%d %H:%M"),
                site.as_ref().map_or(String::new(), |s| format!(
                    ", seen in {} at ({:.0}, {:.0})",
                    s.view, s.leaf.centre[0], s.leaf.centre[1]
                ))
            )),
            ..FeedRow::default()
        });
    }
    // A refit that no longer finds a leaf announced before takes it back aloud:
    // `tail` said it emerged, so `tail` says it did not.
    let now_found: BTreeSet<u32> = tl.events.iter().map(|e| e.leaf).collect();
    for leaf in old.difference(&now_found) {
        rows.push(FeedRow {
            kind: "withdrawn".into(),
            plant: Some(plant.to_string()),
            message: Some(format!(
                "leaf {leaf} withdrawn: with the newer images the fit no longer finds it"
            )),
            ..FeedRow::default()
        });
    }
    let new_lost = tl.sessions.last().map_or(0.0, |s| s.lost);
    let mut k = old_lost + 1.0;
    while k <= new_lost {
        let at = tl.sessions.iter().find(|s| s.lost >= k).map(|s| s.start);
        rows.push(FeedRow {
            kind: "lost".into(),
            plant: Some(plant.to_string()),
            taken_at: at.map(iso),
            message: Some(format!(
                "a leaf died by {} ({new_lost} lost in all)",
                at.map_or("-".into(), |t| t.format("%Y-%m-%d %H:%M").to_string()),
            )),
            ..FeedRow::default()
        });
        k += 1.0;
    }
    rows
}

/// Updates the plant's summary row: sessions, leaves, phyllochrons (days and,
/// with its zone's temperature log, degree-days) and the next leaf's forecast.
fn write_summary(
    tx: &Transaction,
    params: &TimelineParams,
    plant_id: i64,
    plant: &str,
    tl: &Timeline,
    now: &str,
) -> anyhow::Result<()> {
    let last = tl.sessions.last();
    let events: Vec<(u32, NaiveDateTime)> = tl.events.iter().map(|e| (e.leaf, e.at)).collect();
    let zone = params.zones.zone_of(plant);
    // The log from a day before the first leaf: the phyllochron spans the
    // leaves, the forecast the last leaf and the log's last days after it.
    let clock = match (events.first(), events.last()) {
        (Some(&(_, first)), Some(&(_, last))) => {
            let since = (first - chrono::Duration::days(1))
                .min(last - chrono::Duration::days(crate::domain::forecast::RECENT_DAYS + 1));
            zone_clock(tx, zone, params.base_temp_c, Some(since))?
        }
        _ => None,
    };
    let (phyllochron_cd, next) = thermal_fit(&events, tl.phyllochron_days, clock.as_ref());
    tx.execute(
        "UPDATE plants SET sessions = ?2, last_taken_at = ?3, leaves_emerged = ?4, living = ?5,
             phyllochron_days = ?6, updated_at = ?7, phyllochron_cd = ?8, climate_zone = ?9,
             next_leaf = ?10, next_leaf_at = ?11 WHERE id = ?1",
        params![
            plant_id,
            tl.sessions.len() as i64,
            last.map(|s| iso(s.start)),
            last.map(|s| s.emerged),
            last.map(|s| s.living),
            tl.phyllochron_days,
            now,
            phyllochron_cd,
            zone,
            next.map(|n| n.leaf),
            next.map(|n| iso(n.at))
        ],
    )?;
    Ok(())
}

/// Works out every plant's thermal phyllochron again (after the temperature
/// log changed); returns how many plants have one.
pub(super) fn refresh_thermal(tx: &Transaction, params: &TimelineParams) -> anyhow::Result<usize> {
    let plants: Vec<(i64, String, Option<f64>)> = tx
        .prepare("SELECT id, name, phyllochron_days FROM plants")?
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?
        .collect::<Result<_, _>>()?;
    // Each zone's whole log read once, not once per plant: a log imported
    // hourly would otherwise be parsed again for every plant every hour.
    let mut clocks: BTreeMap<String, Option<crate::domain::thermal::ThermalClock>> = BTreeMap::new();
    let mut with = 0;
    for (id, name, days) in plants {
        let events: Vec<(u32, NaiveDateTime)> = tx
            .prepare_cached("SELECT leaf, emerged_at FROM events WHERE plant_id = ?1 ORDER BY leaf")?
            .query_map([id], |r| Ok((r.get(0)?, r.get::<_, String>(1)?)))?
            .map(|r| {
                let (leaf, at) = r?;
                Ok((leaf, parse_iso(&at)?))
            })
            .collect::<anyhow::Result<_>>()?;
        let zone = params.zones.zone_of(&name);
        if !clocks.contains_key(zone) {
            clocks.insert(zone.to_string(), zone_clock(tx, zone, params.base_temp_c, None)?);
        }
        let (cd, next) = thermal_fit(&events, days, clocks[zone].as_ref());
        with += usize::from(cd.is_some());
        tx.execute(
            "UPDATE plants SET phyllochron_cd = ?2, climate_zone = ?3, next_leaf = ?4, next_leaf_at = ?5 WHERE id = ?1",
            params![id, cd, zone, next.map(|n| n.leaf), next.map(|n| iso(n.at))],
        )?;
    }
    Ok(with)
}

/// A thermal clock over `zone`'s temperature log, from `since` or all of
/// it; `None` without readings.
pub(super) fn zone_clock(
    conn: &Connection,
    zone: &str,
    base_temp_c: f64,
    since: Option<NaiveDateTime>,
) -> anyhow::Result<Option<crate::domain::thermal::ThermalClock>> {
    let readings = conn
        .prepare_cached(
            "SELECT taken_at, temp_c FROM climate WHERE zone = ?1 AND (?2 IS NULL OR taken_at >= ?2)
             ORDER BY taken_at",
        )?
        .query_map(params![zone, since.map(iso)], |r| {
            Ok((r.get::<_, String>(0)?, r.get::<_, f64>(1)?))
        })?
        .map(|r| {
            let (t, c) = r?;
            Ok((parse_iso(&t)?, c))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok((!readings.is_empty()).then(|| crate::domain::thermal::ThermalClock::new(readings, base_temp_c)))
}

/// A plant's degree-days per leaf and next leaf ([`crate::domain::forecast`]),
/// from `clock`, its zone's log where it has one covering its leaves.
fn thermal_fit(
    events: &[(u32, NaiveDateTime)],
    days_per_leaf: Option<f64>,
    clock: Option<&crate::domain::thermal::ThermalClock>,
) -> (Option<f64>, Option<crate::domain::forecast::NextLeaf>) {
    let cd = clock.and_then(|c| crate::domain::thermal::phyllochron(c, events));
    let next = events.last().and_then(|&(leaf, _)| {
        crate::domain::forecast::leaf_due_by_either(events, days_per_leaf, cd, clock, leaf + 1).map(|n| n.0)
    });
    (cd, next)
}
