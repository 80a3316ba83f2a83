//! Read queries used by the operator commands (tail, status, timeline).

use std::collections::BTreeMap;

use anyhow::Context;
use rusqlite::{params, OptionalExtension};
use serde::Serialize;

use super::Store;
use crate::domain::climate_zone::{ZoneClocks, ZoneRules};
use crate::domain::plant::{LeafSiteRow, NextLeafRow, PlantTimeline, SessionRow};

/// One entry of the feed `phyllo tail` follows.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FeedRow {
    /// Position in the feed.
    pub seq: i64,
    /// When it was written (UTC).
    pub at: String,
    /// `count`, `import`, `event`, `duplicate`, `failed` or `recount`.
    pub kind: String,
    /// Plant id.
    pub plant: Option<String>,
    /// Image time (count) or estimated emergence time (event).
    pub taken_at: Option<String>,
    /// View of the image.
    pub view: Option<String>,
    /// Leaves counted in the image.
    pub leaf_count: Option<i64>,
    /// Fused count of the image's session.
    pub fused: Option<f64>,
    /// Leaves emerged at that session (fit), or the leaf number of an event.
    pub leaves_emerged: Option<f64>,
    /// Leaf numbers newly emerged.
    pub new_leaves: Vec<u32>,
    /// Image path relative to the drop directory.
    pub path: Option<String>,
    /// Human-readable detail (errors name the file and problem).
    pub message: Option<String>,
}

/// Images per state.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ImageCounts {
    /// Counted.
    pub counted: i64,
    /// Same content as a counted image.
    pub duplicate: i64,
    /// Failed, current versions only (a failed version replaced by a newer
    /// one is not counted).
    pub failed: i64,
    /// Imported observations.
    pub imported: i64,
    /// Plants.
    pub plants: i64,
}

/// Where the timelines stand, for `phyllo status`.
#[derive(Debug, Clone, Default, Serialize)]
pub struct TimelineSummary {
    /// Leaf emergence events over every plant.
    pub events: i64,
    /// Plants with at least one leaf read as lost.
    pub plants_with_lost_leaves: i64,
    /// Leaves read as lost over every plant.
    pub leaves_lost: f64,
    /// The `[timeline]` settings the stored fits were made with.
    pub settings: Option<String>,
}

/// The most recently recorded image.
#[derive(Debug, Clone, Serialize)]
pub struct LastImage {
    /// Path relative to the drop directory.
    pub path: String,
    /// `counted`, `duplicate` or `failed`.
    pub state: String,
    /// When it was recorded (UTC).
    pub at: String,
    /// Why it failed, if it did.
    pub error: Option<String>,
}

/// What one zone's temperature log holds ([`Store::climate_summary`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClimateSummary {
    /// The zone ([`crate::domain::climate_zone`]); `""` for the facility's log.
    pub zone: String,
    /// Readings.
    pub readings: i64,
    /// First reading (facility local time).
    pub first: String,
    /// Last reading.
    pub last: String,
    /// Longest time between two readings, hours.
    pub longest_gap_hours: f64,
}

fn feed_row(r: &rusqlite::Row<'_>) -> rusqlite::Result<FeedRow> {
    let new_leaves: Option<String> = r.get(9)?;
    Ok(FeedRow {
        seq: r.get(0)?,
        at: r.get(1)?,
        kind: r.get(2)?,
        plant: r.get(3)?,
        taken_at: r.get(4)?,
        view: r.get(5)?,
        leaf_count: r.get(6)?,
        fused: r.get(7)?,
        leaves_emerged: r.get(8)?,
        new_leaves: new_leaves
            .and_then(|s| serde_json::from_str(&s).ok())
            .unwrap_or_default(),
        path: r.get(10)?,
        message: r.get(11)?,
    })
}

impl Store {
    /// Feed entries after `seq`, oldest first, optionally for one plant.
    pub fn feed_after(&self, seq: i64, plant: Option<&str>, limit: usize) -> anyhow::Result<Vec<FeedRow>> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT seq, at, kind, plant, taken_at, view, leaf_count, fused, leaves_emerged, new_leaves, path, message
             FROM feed WHERE seq > ?1 AND (?2 IS NULL OR plant = ?2) ORDER BY seq LIMIT ?3",
        )?;
        let rows = stmt
            .query_map(params![seq, plant, limit as i64], feed_row)?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// The newest feed position (0 when empty).
    pub fn feed_head(&self) -> anyhow::Result<i64> {
        Ok(self
            .conn
            .query_row("SELECT COALESCE(MAX(seq), 0) FROM feed", [], |r| r.get(0))?)
    }

    /// Images per state, imported observations and plants.
    pub fn image_counts(&self) -> anyhow::Result<ImageCounts> {
        let mut c = ImageCounts::default();
        let mut stmt = self
            .conn
            // A failed version that a newer one replaced is history, not a failure to fix.
            .prepare(
                "SELECT state, COUNT(*) FROM images WHERE state != 'failed' OR superseded = 0 GROUP BY state",
            )?;
        for row in stmt.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)?)))? {
            let (state, n) = row?;
            match state.as_str() {
                "counted" => c.counted = n,
                "duplicate" => c.duplicate = n,
                "failed" => c.failed = n,
                _ => {}
            }
        }
        c.imported = self.conn.query_row(
            "SELECT COUNT(*) FROM observations WHERE image_id IS NULL",
            [],
            |r| r.get(0),
        )?;
        c.plants = self
            .conn
            .query_row("SELECT COUNT(*) FROM plants", [], |r| r.get(0))?;
        Ok(c)
    }

    /// Events, leaves lost and the fit's settings over every plant.
    pub fn timeline_summary(&self) -> anyhow::Result<TimelineSummary> {
        let events = self
            .conn
            .query_row("SELECT COUNT(*) FROM events", [], |r| r.get(0))?;
        // A plant's leaves lost by its last session: the largest of its sessions'.
        let (plants_with_lost_leaves, leaves_lost) = self.conn.query_row(
            "SELECT COUNT(*), COALESCE(SUM(lost), 0) FROM
               (SELECT MAX(leaves_lost) AS lost FROM sessions GROUP BY plant_id) WHERE lost > 0",
            [],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )?;
        Ok(TimelineSummary {
            events,
            plants_with_lost_leaves,
            leaves_lost,
            settings: self.stored_timeline_settings()?,
        })
    }

    /// The `[timeline]` settings the stored fits were made with (`meta`), if any.
    pub fn stored_timeline_settings(&self) -> anyhow::Result<Option<String>> {
        Ok(self
            .conn
            .query_row("SELECT value FROM meta WHERE key = 'timeline'", [], |r| r.get(0))
            .optional()?)
    }

    /// The most recently recorded image.
    pub fn last_image(&self) -> anyhow::Result<Option<LastImage>> {
        Ok(self
            .conn
            .query_row(
                "SELECT path, state, updated_at, error FROM images ORDER BY updated_at DESC, id DESC LIMIT 1",
                [],
                |r| {
                    Ok(LastImage {
                        path: r.get(0)?,
                        state: r.get(1)?,
                        at: r.get(2)?,
                        error: r.get(3)?,
                    })
                },
            )
            .optional()?)
    }

    /// Hours since the newest image file was first seen; `None` before any.
    pub fn hours_since_newest_image(&self) -> anyhow::Result<Option<f64>> {
        Ok(self
            .conn
            .query_row(
                // The newest row is the newest file (rows are only appended),
                // found by its id rather than by scanning every image; bookkeeping
                // times are UTC with a `Z`, which julianday reads.
                "SELECT ROUND((julianday('now') - julianday(first_seen)) * 24, 1) FROM images
                 ORDER BY id DESC LIMIT 1",
                [],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// The most recent failures: (path, error).
    pub fn recent_failures(&self, n: usize) -> anyhow::Result<Vec<(String, String)>> {
        let mut stmt = self.conn.prepare(
            "SELECT path, COALESCE(error, '') FROM images WHERE state = 'failed' AND superseded = 0
             ORDER BY updated_at DESC LIMIT ?1",
        )?;
        let rows = stmt
            .query_map([n as i64], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// The counted images of `plant` taken at or after `from` and before
    /// `until` (one session's, with the next session's start): (path, view).
    pub fn session_images(
        &self,
        plant: &str,
        from: &str,
        until: Option<&str>,
    ) -> anyhow::Result<Vec<(String, String)>> {
        let mut stmt = self.conn.prepare(
            "SELECT i.path, COALESCE(i.view, '') FROM images i JOIN plants p ON p.id = i.plant_id
             WHERE p.name = ?1 AND i.state = 'counted' AND i.superseded = 0
               AND i.taken_at >= ?2 AND (?3 IS NULL OR i.taken_at < ?3)
             ORDER BY i.taken_at, i.view",
        )?;
        let rows = stmt
            .query_map(rusqlite::params![plant, from, until], |r| {
                Ok((r.get(0)?, r.get(1)?))
            })?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// Images recorded as failed at or after `since` (UTC, as `updated_at` is stored).
    pub fn failures_since(&self, since: &str) -> anyhow::Result<i64> {
        Ok(self.conn.query_row(
            "SELECT COUNT(*) FROM images WHERE state = 'failed' AND superseded = 0 AND updated_at >= ?1",
            [since],
            |r| r.get(0),
        )?)
    }

    /// Counted, current images whose bytes equal an earlier counted image's
    /// (a copy or rename under another plant, time or view).
    pub fn images_sharing_bytes(&self) -> anyhow::Result<i64> {
        Ok(self.conn.query_row(
            "SELECT COUNT(*) FROM images a WHERE a.state = 'counted' AND a.superseded = 0
               AND EXISTS (SELECT 1 FROM images b WHERE b.sha256 = a.sha256 AND b.id < a.id
                           AND b.state = 'counted' AND b.superseded = 0)",
            [],
            |r| r.get(0),
        )?)
    }

    /// The service's self-report (key → value).
    pub fn service(&self) -> anyhow::Result<BTreeMap<String, String>> {
        let mut stmt = self.conn.prepare("SELECT key, value FROM service")?;
        let rows = stmt
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// How many current image counts were made with settings other than
    /// `settings` (JSON text as stored), those from before schema 2 included.
    pub fn counts_with_other_settings(&self, settings: &str) -> anyhow::Result<i64> {
        Ok(self.conn.query_row(
            "SELECT COUNT(*) FROM observations o JOIN images i ON i.id = o.image_id
             WHERE i.superseded = 0 AND (o.settings IS NULL OR o.settings != ?1)",
            [settings],
            |r| r.get(0),
        )?)
    }

    /// Each zone's temperature log, the facility's first: readings, first and
    /// last reading, and the longest time between two readings in hours.
    /// Empty without a log.
    pub fn climate_summary(&self) -> anyhow::Result<Vec<ClimateSummary>> {
        let mut stmt = self.conn.prepare(
            // julianday is a float of days: rounded to a few seconds.
            "SELECT zone, COUNT(*), MIN(taken_at), MAX(taken_at),
                    ROUND(MAX((julianday(taken_at) - julianday(prev)) * 24), 3)
             FROM (SELECT zone, taken_at,
                          LAG(taken_at) OVER (PARTITION BY zone ORDER BY taken_at) AS prev FROM climate)
             GROUP BY zone ORDER BY zone",
        )?;
        let rows = stmt
            .query_map([], |r| {
                Ok(ClimateSummary {
                    zone: r.get(0)?,
                    readings: r.get(1)?,
                    first: r.get(2)?,
                    last: r.get(3)?,
                    longest_gap_hours: r.get::<_, Option<f64>>(4)?.unwrap_or(0.0),
                })
            })?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// Each zone's logs that end well before its plants' newest session:
    /// (zone, hours from the log's last reading to that session), for the
    /// zones with a log whose plants were imaged more than `hours` after it.
    /// A log not imported lately stops timing new leaves without a word.
    pub fn temperature_logs_behind(&self, hours: f64) -> anyhow::Result<Vec<(String, f64)>> {
        let mut stmt = self.conn.prepare(
            "SELECT c.zone, ROUND((julianday(p.newest) - julianday(c.last)) * 24, 1)
             FROM (SELECT zone, MAX(taken_at) AS last FROM climate GROUP BY zone) c
             JOIN (SELECT COALESCE(climate_zone, '') AS zone, MAX(last_taken_at) AS newest FROM plants
                   GROUP BY 1) p ON p.zone = c.zone
             WHERE (julianday(p.newest) - julianday(c.last)) * 24 > ?1
             ORDER BY c.zone",
        )?;
        let rows = stmt
            .query_map([hours], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// A thermal clock over `zone`'s whole temperature log above
    /// `base_temp_c`; `None` when that zone has no log.
    pub fn thermal_clock(
        &self,
        base_temp_c: f64,
        zone: &str,
    ) -> anyhow::Result<Option<crate::domain::thermal::ThermalClock>> {
        super::derive::zone_clock(&self.conn, zone, base_temp_c, None)
    }

    /// The thermal clocks of every zone this store holds a log for, above
    /// `base_temp_c`, with the rules that pick each plant's zone.
    pub fn zone_clocks(&self, rules: ZoneRules, base_temp_c: f64) -> anyhow::Result<ZoneClocks> {
        let mut clocks = BTreeMap::new();
        for summary in self.climate_summary()? {
            if let Some(clock) = self.thermal_clock(base_temp_c, &summary.zone)? {
                clocks.insert(summary.zone, clock);
            }
        }
        Ok(ZoneClocks::new(rules, clocks))
    }

    /// All plant ids, sorted.
    pub fn plants(&self) -> anyhow::Result<Vec<String>> {
        let mut stmt = self.conn.prepare("SELECT name FROM plants ORDER BY name")?;
        let rows = stmt.query_map([], |r| r.get(0))?.collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// Plant ids with no count at all, sorted: every image of theirs failed
    /// or was a duplicate, and no count was imported for them. They have no
    /// timeline yet.
    pub fn plants_without_counts(&self) -> anyhow::Result<Vec<String>> {
        let mut stmt = self.conn.prepare(
            "SELECT name FROM plants p
             WHERE NOT EXISTS (SELECT 1 FROM observations o WHERE o.plant_id = p.id) ORDER BY name",
        )?;
        let rows = stmt.query_map([], |r| r.get(0))?.collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// Every plant's timeline as stored, in plant order.
    pub fn plant_timelines(&self) -> anyhow::Result<Vec<PlantTimeline>> {
        let mut out = Vec::new();
        for plant in self.plants()? {
            out.extend(self.plant_timeline(&plant)?);
        }
        Ok(out)
    }

    /// One plant's timeline as stored.
    pub fn plant_timeline(&self, plant: &str) -> anyhow::Result<Option<PlantTimeline>> {
        let Some((id, phyllochron_days, phyllochron_cd, climate_zone, next_leaf)) = self
            .conn
            .query_row(
                "SELECT id, phyllochron_days, phyllochron_cd, COALESCE(climate_zone, ''), next_leaf, next_leaf_at
                 FROM plants WHERE name = ?1",
                [plant],
                |r| {
                    let next = match (r.get(4)?, r.get(5)?) {
                        (Some(leaf), Some(expected)) => Some(NextLeafRow { leaf, expected }),
                        _ => None,
                    };
                    Ok((r.get::<_, i64>(0)?, r.get(1)?, r.get(2)?, r.get(3)?, next))
                },
            )
            .optional()?
        else {
            return Ok(None);
        };
        let mut stmt = self.conn.prepare(
            "SELECT start, views, fused, leaves_emerged, living, leaves_lost FROM sessions WHERE plant_id = ?1 ORDER BY start",
        )?;
        let sessions = stmt
            .query_map([id], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, String>(1)?,
                    r.get(2)?,
                    r.get(3)?,
                    r.get(4)?,
                    r.get(5)?,
                ))
            })?
            .map(|row| {
                let (start, views, fused, leaves_emerged, living, leaves_lost) = row?;
                let views = serde_json::from_str(&views).context("sessions.views")?;
                Ok(SessionRow {
                    start,
                    views,
                    fused,
                    leaves_emerged,
                    living,
                    leaves_lost,
                })
            })
            .collect::<anyhow::Result<_>>()?;
        let mut stmt = self.conn.prepare(
            "SELECT leaf, emerged_at, seen_at, site_view, site_image, site_x, site_y, site_bbox, site_area
             FROM events WHERE plant_id = ?1 ORDER BY leaf",
        )?;
        let rows: Vec<((u32, String, String), Option<LeafSiteRow>)> = stmt
            .query_map([id], |r| {
                let site = match (r.get::<_, Option<String>>(3)?, r.get::<_, Option<String>>(4)?) {
                    (Some(view), Some(image)) => Some(LeafSiteRow {
                        leaf: r.get(0)?,
                        view,
                        image,
                        centre: [r.get(5)?, r.get(6)?],
                        bbox: serde_json::from_str(&r.get::<_, String>(7)?).unwrap_or_default(),
                        area: r.get(8)?,
                    }),
                    _ => None,
                };
                Ok(((r.get(0)?, r.get(1)?, r.get(2)?), site))
            })?
            .collect::<Result<_, _>>()?;
        let (events, sites): (Vec<_>, Vec<_>) = rows.into_iter().unzip();
        Ok(Some(PlantTimeline {
            plant: plant.to_string(),
            phyllochron_days,
            phyllochron_cd,
            climate_zone,
            next_leaf,
            sessions,
            events,
            sites: sites.into_iter().flatten().collect(),
        }))
    }
}
