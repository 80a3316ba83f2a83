//! Storage: one SQLite file (bundled SQLite, WAL mode) holding images,
//! observations, the per-plant timeline and the feed that `phyllo tail` reads.
//!
//! Invariants:
//! - every image lands in **one** transaction: its row, its observation, the
//!   plant's recomputed timeline and its feed entries commit together or not
//!   at all, so a crash never leaves a half-counted image;
//! - the same content (SHA-256) is never counted twice: a second file with
//!   counted content is recorded as a `duplicate` of the first, checked inside
//!   the write transaction so two workers cannot both count it;
//! - a changed file at a known path is a new `version`; the older version's
//!   observation stays in the database but leaves the timeline (`superseded`).
//!
//! Times: `taken_at` is the facility's local time as written in file names (no
//! offset, ISO 8601 with milliseconds); bookkeeping times (`first_seen`,
//! `updated_at`, feed `at`) are UTC with a `Z`.

mod lock;
pub mod migrations;
mod queries;
mod reassign;
mod recount;
mod site_rows;

pub use lock::{DatabaseLock, RestoreLock, WritersLock};
pub use recount::CountedImage;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context};
use chrono::NaiveDateTime;
use rusqlite::{params, Connection, OpenFlags, OptionalExtension, Transaction, TransactionBehavior};

use crate::domain::names::{ParsedName, View};
use crate::domain::timeline::{self, Obs, TimelineParams};

pub use crate::domain::plant::{LeafSiteRow, NextLeafRow, PlantTimeline, SessionRow};
pub use queries::{ClimateSummary, FeedRow, ImageCounts, LastImage};

/// Formats a facility time the way the database and exports store it.
pub fn iso(t: NaiveDateTime) -> String {
    t.format("%Y-%m-%dT%H:%M:%S%.3f").to_string()
}

/// Parses a time stored by [`iso`] (or any `%Y-%m-%dT%H:%M:%S[.f]`).
pub fn parse_iso(s: &str) -> anyhow::Result<NaiveDateTime> {
    NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M:%S%.f").with_context(|| format!("time '{s}'"))
}

/// Now, UTC, ISO 8601 with `Z`.
pub fn now_utc() -> String {
    utc(chrono::Utc::now())
}

/// Formats a bookkeeping time the way the database stores it (UTC, `Z`).
pub fn utc(t: chrono::DateTime<chrono::Utc>) -> String {
    t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string()
}

/// What a worker knows about a file before counting it.
#[derive(Debug, Clone)]
pub struct FileFacts {
    /// Path relative to the drop directory, `/` separators.
    pub rel: String,
    /// Size in bytes of the content that was hashed.
    pub size: u64,
    /// File mtime (ISO 8601 UTC), if known.
    pub mtime: Option<String>,
    /// SHA-256 of the content, hex.
    pub sha256: String,
}

/// What [`Store::unimport`] took back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unimported {
    /// Counts removed.
    pub counts: usize,
    /// Temperatures removed.
    pub temperatures: usize,
    /// Images moved back to the plant they were moved from.
    pub images: usize,
    /// Plants refitted.
    pub plants: usize,
}

/// One air-temperature reading of a greenhouse log.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// Its zone ([`crate::domain::climate_zone`]); `""` for the facility's log.
    pub zone: String,
    /// When it was taken (facility local time).
    pub taken_at: NaiveDateTime,
    /// Air temperature, °C.
    pub temp_c: f64,
}

/// A count to store, independent of the inference crate's types.
#[derive(Debug, Clone)]
pub struct CountRecord {
    /// Leaves counted.
    pub leaf_count: u32,
    /// Per-instance summary (JSON).
    pub instances: serde_json::Value,
    /// Per-stage timings (JSON).
    pub timing: serde_json::Value,
    /// Total milliseconds.
    pub ms_total: f64,
    /// Identifies the model that counted.
    pub model_id: String,
    /// The counting settings (zoom, post-processing) as JSON; `Null` when
    /// the counter has none to report.
    pub settings: serde_json::Value,
}

impl CountRecord {
    /// The settings as stored: JSON text, or NULL when there are none.
    pub(crate) fn settings_text(&self) -> Option<String> {
        (!self.settings.is_null()).then(|| self.settings.to_string())
    }
}

/// What happened to one image.
#[derive(Debug)]
pub enum Outcome<'a> {
    /// Counted.
    Counted(&'a ParsedName, &'a CountRecord),
    /// Failed; `retry` if the failure may be transient (runtime, not data).
    Failed {
        /// Name, when it could be parsed.
        name: Option<&'a ParsedName>,
        /// Error text naming the file and the problem.
        error: String,
        /// Whether trying again later may succeed.
        retry: bool,
    },
}

/// What the store did with an image.
#[derive(Debug, Clone, PartialEq)]
pub enum Recorded {
    /// Stored as a new observation.
    Counted {
        /// Fused count of the image's session after recomputation.
        fused: f64,
        /// Leaves emerged (fit) at the image's session.
        emerged: f64,
        /// Leaf numbers whose emergence is new after this image.
        new_leaves: Vec<u32>,
    },
    /// Same content as an image already counted (path given).
    Duplicate(String),
    /// Recorded as failed.
    Failed,
}

/// Decision before the (expensive) count.
#[derive(Debug, Clone, PartialEq)]
pub enum Precheck {
    /// Nothing to do (reason).
    Skip(String),
    /// Count it.
    Process,
}

/// The database.
pub struct Store {
    conn: Connection,
    params: TimelineParams,
    fusion_name: String,
    max_attempts: u32,
}

/// The `[timeline]` settings a fit depends on, as stored in `meta`.
fn timeline_settings(
    tl: &crate::config::TimelineConfig,
    zones: &crate::domain::climate_zone::ZoneRules,
) -> String {
    format!(
        // `leaf_sites`: where each new leaf emerged, added in schema 6; bumping
        // it refits every plant once so older events get their sites.
        // `next_leaf`: the forecast of schema 7, filled in by that refit for
        // plants that get no new image.
        "fusion={};session_gap_minutes={};living_window={};death_penalty={};base_temp_c={};leaf_sites=2;next_leaf=1{}",
        tl.fusion,
        tl.session_gap_minutes,
        tl.living_window,
        tl.death_penalty,
        tl.base_temp_c,
        zones.fingerprint()
    )
}

impl Store {
    /// Opens (creating if needed) a database for writing and migrates it.
    pub fn open(path: &Path, tl: &crate::config::TimelineConfig, max_attempts: u32) -> anyhow::Result<Store> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating database directory {}", dir.display()))?;
        }
        let mut conn =
            Connection::open(path).with_context(|| format!("opening database {}", path.display()))?;
        conn.busy_timeout(Duration::from_secs(30))?;
        let mode: String = conn.pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get(0))?;
        if !mode.eq_ignore_ascii_case("wal") {
            bail!(
                "database {}: could not switch to WAL mode (got {mode})",
                path.display()
            );
        }
        // WAL + NORMAL is durable across application crashes; a power cut may lose the last
        // transactions, which the next rescan recounts.
        conn.pragma_update(None, "synchronous", "NORMAL")?;
        conn.pragma_update(None, "foreign_keys", "ON")?;
        migrations::migrate(&mut conn).with_context(|| format!("database {}", path.display()))?;
        let mut store = Store {
            conn,
            params: TimelineParams::from_config(tl)?,
            fusion_name: tl.fusion.clone(),
            max_attempts,
        };
        // Changed timeline settings (in the config, or new defaults after an
        // upgrade) would otherwise leave plants that get no new image fitted the old way.
        let fit = timeline_settings(tl, &store.params.zones);
        let stored = store.stored_timeline_settings()?;
        if stored.as_deref() != Some(fit.as_str()) {
            let has_sessions: bool =
                store
                    .conn
                    .query_row("SELECT EXISTS(SELECT 1 FROM sessions)", [], |r| r.get(0))?;
            if has_sessions {
                let plants = store.refit_all(&format!("timeline settings now {fit}"))?;
                tracing::info!(plants, settings = %fit, was = ?stored, "timeline settings changed: every timeline refitted");
            }
            store.conn.execute(
                "INSERT INTO meta (key, value) VALUES ('timeline', ?1)
                 ON CONFLICT (key) DO UPDATE SET value = excluded.value",
                [&fit],
            )?;
        }
        Ok(store)
    }

    /// Opens an existing database read-only (tail, status, export, timeline).
    pub fn open_read_only(path: &Path) -> anyhow::Result<Store> {
        if !path.exists() {
            bail!(
                "database {} does not exist (has `phyllo serve` run yet?)",
                path.display()
            );
        }
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .with_context(|| format!("opening database {} read-only", path.display()))?;
        conn.busy_timeout(Duration::from_secs(10))?;
        migrations::check_version(&conn).with_context(|| format!("database {}", path.display()))?;
        Ok(Store {
            conn,
            params: TimelineParams::default(),
            fusion_name: String::new(),
            max_attempts: 0,
        })
    }

    /// Which temperature log times each plant (the config's `[[timeline.zones]]`).
    pub fn zone_rules(&self) -> &crate::domain::climate_zone::ZoneRules {
        &self.params.zones
    }

    /// The underlying connection, for read queries of the sinks.
    pub fn conn(&self) -> &Connection {
        &self.conn
    }

    /// True if the latest version of `rel` has this size and mtime and needs
    /// no more work: lets periodic rescans skip files without reading them.
    pub fn is_known(&self, rel: &str, size: u64, mtime: &str) -> anyhow::Result<bool> {
        let row: Option<(i64, Option<String>, String, i64, u32)> = self
            .conn
            .prepare_cached(
                "SELECT size, mtime, state, retry, attempts FROM images WHERE path = ?1 ORDER BY version DESC LIMIT 1",
            )?
            .query_row([rel], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)))
            .optional()?;
        Ok(match row {
            Some((s, Some(m), state, retry, attempts)) if s as u64 == size && m == mtime => {
                state != "failed" || retry == 0 || attempts >= self.max_attempts
            }
            _ => false,
        })
    }

    /// Decides, from the content hash, whether a file needs counting. Same
    /// content at the same path: skip (and remember the new mtime). Content
    /// already counted elsewhere: recorded here as a duplicate, skip.
    pub fn precheck(&mut self, f: &FileFacts) -> anyhow::Result<Precheck> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let latest = latest_version(&tx, &f.rel)?;
        if let Some(l) = &latest {
            if l.sha256 == f.sha256 {
                tx.execute(
                    "UPDATE images SET size = ?2, mtime = ?3 WHERE id = ?1",
                    params![l.id, f.size as i64, f.mtime],
                )?;
                tx.commit()?;
                let done = l.state != "failed" || l.retry == 0 || l.attempts >= self.max_attempts;
                return Ok(if done {
                    Precheck::Skip(format!(
                        "{} unchanged (version {}, {})",
                        f.rel, l.version, l.state
                    ))
                } else {
                    Precheck::Process
                });
            }
        }
        if let Some((orig_id, orig_path)) = counted_with_hash(&tx, &f.sha256)? {
            let stale = insert_duplicate(&tx, f, latest.as_ref(), orig_id, &orig_path)?;
            refresh(&tx, &self.params, &self.fusion_name, &stale, None)?;
            tx.commit()?;
            return Ok(Precheck::Skip(format!(
                "{} has the same content as {orig_path}",
                f.rel
            )));
        }
        Ok(Precheck::Process)
    }

    /// Records one image's outcome in one transaction; recomputes the plant's
    /// timeline when it was counted.
    pub fn record(&mut self, f: &FileFacts, outcome: Outcome<'_>) -> anyhow::Result<Recorded> {
        let now = now_utc();
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let latest = latest_version(&tx, &f.rel)?;
        let same = latest.as_ref().filter(|l| l.sha256 == f.sha256);
        let recorded = match outcome {
            Outcome::Counted(name, count) => {
                // Re-checked inside the write lock: another worker may have counted this content.
                if let Some((orig_id, orig_path)) = counted_with_hash(&tx, &f.sha256)? {
                    if same.map(|l| l.id) != Some(orig_id) {
                        let stale = insert_duplicate(&tx, f, latest.as_ref(), orig_id, &orig_path)?;
                        refresh(&tx, &self.params, &self.fusion_name, &stale, None)?;
                        tx.commit()?;
                        return Ok(Recorded::Duplicate(orig_path));
                    }
                }
                let plant_id = upsert_plant(&tx, &name.plant, &now)?;
                let (image_id, stale) = write_image(
                    &tx,
                    f,
                    latest.as_ref(),
                    Some((plant_id, name)),
                    "counted",
                    None,
                    false,
                    &now,
                )?;
                refresh(&tx, &self.params, &self.fusion_name, &stale, Some(plant_id))?;
                tx.execute(
                    "INSERT INTO observations (image_id, plant_id, taken_at, view, leaf_count, instances, model_id,
                         timing, ms_total, created_at, settings)
                         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                    params![
                        image_id,
                        plant_id,
                        iso(name.taken_at),
                        name.view.to_string(),
                        count.leaf_count,
                        count.instances.to_string(),
                        count.model_id,
                        count.timing.to_string(),
                        count.ms_total,
                        now,
                        count.settings_text()
                    ],
                )?;
                let diff = recompute(
                    &tx,
                    &self.params,
                    &self.fusion_name,
                    plant_id,
                    &name.plant,
                    &now,
                    Announce::Each,
                )?;
                let (fused, emerged) = diff.at(name.taken_at);
                push_feed(
                    &tx,
                    &FeedRow {
                        kind: "count".into(),
                        plant: Some(name.plant.clone()),
                        taken_at: Some(iso(name.taken_at)),
                        view: Some(name.view.to_string()),
                        leaf_count: Some(count.leaf_count as i64),
                        fused: Some(fused),
                        leaves_emerged: Some(emerged),
                        new_leaves: diff.new_leaves.clone(),
                        path: Some(f.rel.clone()),
                        ..FeedRow::default()
                    },
                    &now,
                )?;
                Recorded::Counted {
                    fused,
                    emerged,
                    new_leaves: diff.new_leaves,
                }
            }
            Outcome::Failed { name, error, retry } => {
                let plant = match name {
                    Some(n) => Some((upsert_plant(&tx, &n.plant, &now)?, n)),
                    None => None,
                };
                let (_, stale) = write_image(
                    &tx,
                    f,
                    latest.as_ref(),
                    plant,
                    "failed",
                    Some(&error),
                    retry,
                    &now,
                )?;
                refresh(&tx, &self.params, &self.fusion_name, &stale, None)?;
                push_feed(
                    &tx,
                    &FeedRow {
                        kind: "failed".into(),
                        plant: name.map(|n| n.plant.clone()),
                        path: Some(f.rel.clone()),
                        message: Some(error),
                        ..FeedRow::default()
                    },
                    &now,
                )?;
                Recorded::Failed
            }
        };
        tx.commit()?;
        Ok(recorded)
    }

    /// Ingests counts made elsewhere, in one transaction. Re-importing the
    /// same row (plant, time, view, source) replaces its count rather than
    /// adding a second one. `journal` names the file's entry in the import
    /// journal ([`crate::import_journal`]), recorded with it. Returns (rows, plants).
    pub fn import(
        &mut self,
        source: &str,
        rows: &[(String, NaiveDateTime, View, u32)],
        journal: Option<&str>,
    ) -> anyhow::Result<(usize, usize)> {
        let now = now_utc();
        let model_id = format!("import:{source}");
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let mut plants: BTreeMap<String, i64> = BTreeMap::new();
        for (plant, taken_at, view, count) in rows {
            let pid = match plants.get(plant) {
                Some(&id) => id,
                None => {
                    let id = upsert_plant(&tx, plant, &now)?;
                    plants.insert(plant.clone(), id);
                    id
                }
            };
            tx.execute(
                "INSERT INTO observations (image_id, plant_id, taken_at, view, leaf_count, model_id, created_at)
                 VALUES (NULL, ?1, ?2, ?3, ?4, ?5, ?6)
                 ON CONFLICT (plant_id, taken_at, view, model_id) WHERE image_id IS NULL
                 DO UPDATE SET leaf_count = excluded.leaf_count, created_at = excluded.created_at",
                params![pid, iso(*taken_at), view.to_string(), count, model_id, now],
            )?;
        }
        for (plant, &pid) in &plants {
            let diff = recompute(
                &tx,
                &self.params,
                &self.fusion_name,
                pid,
                plant,
                &now,
                Announce::Each,
            )?;
            push_feed(
                &tx,
                &FeedRow {
                    kind: "import".into(),
                    plant: Some(plant.clone()),
                    leaves_emerged: diff.sessions.last().map(|s| s.1),
                    fused: diff.sessions.last().map(|s| s.0),
                    new_leaves: diff.new_leaves,
                    message: Some(format!("imported from {source}")),
                    ..FeedRow::default()
                },
                &now,
            )?;
        }
        record_import(&tx, journal, source, rows.len(), plants.len(), &now)?;
        tx.commit()?;
        Ok((rows.len(), plants.len()))
    }

    /// Stores air temperatures from `source`, in one transaction; a reading
    /// at a time its zone already logged is replaced. Every plant's thermal
    /// phyllochron is then worked out again. Returns how many plants have one.
    pub fn import_climate(
        &mut self,
        source: &str,
        readings: &[Reading],
        journal: Option<&str>,
    ) -> anyhow::Result<usize> {
        let now = now_utc();
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        for r in readings {
            tx.execute(
                "INSERT INTO climate (zone, taken_at, temp_c, source) VALUES (?1, ?2, ?3, ?4)
                 ON CONFLICT (zone, taken_at) DO UPDATE SET temp_c = excluded.temp_c, source = excluded.source",
                params![r.zone, iso(r.taken_at), r.temp_c, source],
            )?;
        }
        let with = refresh_thermal(&tx, &self.params)?;
        record_import(&tx, journal, source, readings.len(), 0, &now)?;
        tx.commit()?;
        Ok(with)
    }

    /// Takes back everything imported from files named `source` (counts
    /// and temperatures), refitting the plants it touched. The image counts
    /// and other imports stay. Returns (counts removed, temperatures removed,
    /// plants refitted).
    pub fn unimport(&mut self, source: &str) -> anyhow::Result<Unimported> {
        let now = now_utc();
        let model_id = format!("import:{source}");
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let plants: Vec<(i64, String)> = tx
            .prepare(
                "SELECT DISTINCT p.id, p.name FROM observations o JOIN plants p ON p.id = o.plant_id
                 WHERE o.image_id IS NULL AND o.model_id = ?1 ORDER BY p.id",
            )?
            .query_map([&model_id], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_, _>>()?;
        let counts = tx.execute(
            "DELETE FROM observations WHERE image_id IS NULL AND model_id = ?1",
            [&model_id],
        )?;
        let temps = tx.execute("DELETE FROM climate WHERE source = ?1", [source])?;
        let (images, moved_plants) = Store::unassign(&tx, source)?;
        let mut plants = plants;
        for p in moved_plants {
            if !plants.contains(&p) {
                plants.push(p);
            }
        }
        for (id, name) in &plants {
            recompute(
                &tx,
                &self.params,
                &self.fusion_name,
                *id,
                name,
                &now,
                Announce::Each,
            )?;
            push_feed(
                &tx,
                &FeedRow {
                    kind: "import".into(),
                    plant: Some(name.clone()),
                    message: Some(format!("what {source} imported or moved was taken back")),
                    ..FeedRow::default()
                },
                &now,
            )?;
        }
        if temps > 0 {
            refresh_thermal(&tx, &self.params)?;
        }
        tx.execute("DELETE FROM imports WHERE source = ?1", [source])?;
        tx.commit()?;
        Ok(Unimported {
            counts,
            temperatures: temps,
            images,
            plants: plants.len(),
        })
    }

    /// The import-journal entries this database holds.
    pub fn journaled_imports(&self) -> anyhow::Result<BTreeSet<String>> {
        let mut stmt = self.conn.prepare("SELECT journal FROM imports")?;
        let ids = stmt.query_map([], |r| r.get(0))?;
        Ok(ids.collect::<Result<_, _>>()?)
    }

    /// Sets keys of the service's self-report.
    pub fn set_service(&mut self, kv: &[(&str, String)]) -> anyhow::Result<()> {
        let tx = self.conn.transaction()?;
        for (k, v) in kv {
            tx.execute(
                "INSERT INTO service (key, value) VALUES (?1, ?2) ON CONFLICT (key) DO UPDATE SET value = excluded.value",
                params![k, v],
            )?;
        }
        tx.commit()?;
        Ok(())
    }

    /// Deletes feed entries written more than `keep` ago; returns how many.
    /// Only the feed is pruned: it repeats what the other tables keep.
    pub fn prune_feed(&mut self, keep: Duration) -> anyhow::Result<usize> {
        let keep = chrono::Duration::from_std(keep).context("feed retention out of range")?;
        let cutoff = (chrono::Utc::now() - keep)
            .format("%Y-%m-%dT%H:%M:%S%.3fZ")
            .to_string();
        // `at` is written by `now_utc` in this format, so text order is time order.
        Ok(self
            .conn
            .execute("DELETE FROM feed WHERE at < ?1", params![cutoff])?)
    }

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
        for (id, name) in &plants {
            recompute(&tx, &self.params, &self.fusion_name, *id, name, &now, announce)?;
        }
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

/// Which feed rows a refit writes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Announce {
    /// One per newly emerged or newly lost leaf.
    Each,
    /// None (the caller writes a summary).
    Nothing,
}

/// Recomputes the timelines of `plants`, except `skip` (recomputed by the caller).
fn refresh(
    tx: &Transaction,
    params: &TimelineParams,
    rule: &str,
    plants: &[(i64, String)],
    skip: Option<i64>,
) -> anyhow::Result<()> {
    let now = now_utc();
    for (id, name) in plants.iter().filter(|(id, _)| Some(*id) != skip) {
        recompute(tx, params, rule, *id, name, &now, Announce::Each)?;
    }
    Ok(())
}

struct Latest {
    id: i64,
    version: i64,
    sha256: String,
    state: String,
    retry: i64,
    attempts: u32,
}

fn latest_version(tx: &Transaction, rel: &str) -> anyhow::Result<Option<Latest>> {
    Ok(tx
        .prepare_cached(
            "SELECT id, version, sha256, state, retry, attempts FROM images WHERE path = ?1
             ORDER BY version DESC LIMIT 1",
        )?
        .query_row([rel], |r| {
            Ok(Latest {
                id: r.get(0)?,
                version: r.get(1)?,
                sha256: r.get(2)?,
                state: r.get(3)?,
                retry: r.get(4)?,
                attempts: r.get(5)?,
            })
        })
        .optional()?)
}

fn counted_with_hash(tx: &Transaction, sha: &str) -> anyhow::Result<Option<(i64, String)>> {
    Ok(tx
        .prepare_cached(
            "SELECT id, path FROM images WHERE sha256 = ?1 AND state = 'counted' ORDER BY id LIMIT 1",
        )?
        .query_row([sha], |r| Ok((r.get(0)?, r.get(1)?)))
        .optional()?)
}

/// Records an import by its journal entry (when it has one), so a restore
/// knows which entries the database already holds.
fn record_import(
    tx: &Transaction,
    journal: Option<&str>,
    source: &str,
    rows: usize,
    plants: usize,
    now: &str,
) -> anyhow::Result<()> {
    if let Some(journal) = journal {
        tx.execute(
            "INSERT OR REPLACE INTO imports (journal, source, rows, plants, imported_at)
             VALUES (?1, ?2, ?3, ?4, ?5)",
            params![journal, source, rows, plants, now],
        )?;
    }
    Ok(())
}

fn upsert_plant(tx: &Transaction, name: &str, now: &str) -> anyhow::Result<i64> {
    tx.execute(
        "INSERT INTO plants (name, first_seen) VALUES (?1, ?2) ON CONFLICT (name) DO NOTHING",
        params![name, now],
    )?;
    Ok(tx.query_row("SELECT id FROM plants WHERE name = ?1", [name], |r| r.get(0))?)
}

fn insert_duplicate(
    tx: &Transaction,
    f: &FileFacts,
    latest: Option<&Latest>,
    orig_id: i64,
    orig_path: &str,
) -> anyhow::Result<Vec<(i64, String)>> {
    let now = now_utc();
    let (id, stale) = write_image(tx, f, latest, None, "duplicate", None, false, &now)?;
    tx.execute(
        "UPDATE images SET duplicate_of = ?2 WHERE id = ?1",
        params![id, orig_id],
    )?;
    push_feed(
        tx,
        &FeedRow {
            kind: "duplicate".into(),
            path: Some(f.rel.clone()),
            message: Some(format!(
                "{} has the same content as {orig_path}; not counted again",
                f.rel
            )),
            ..FeedRow::default()
        },
        &now,
    )?;
    Ok(stale)
}

/// Inserts a new version of the file, or updates the latest one when it holds
/// the same content (a retry). Returns the image id and the plants whose
/// timeline lost a superseded count.
#[allow(clippy::too_many_arguments)]
fn write_image(
    tx: &Transaction,
    f: &FileFacts,
    latest: Option<&Latest>,
    plant: Option<(i64, &ParsedName)>,
    state: &str,
    error: Option<&str>,
    retry: bool,
    now: &str,
) -> anyhow::Result<(i64, Vec<(i64, String)>)> {
    let (plant_id, taken_at, view) = match plant {
        Some((id, n)) => (Some(id), Some(iso(n.taken_at)), Some(n.view.to_string())),
        None => (None, None, None),
    };
    let attempts = i64::from(state == "counted" || state == "failed");
    if let Some(l) = latest.filter(|l| l.sha256 == f.sha256) {
        tx.execute(
            "UPDATE images SET size = ?2, mtime = ?3, plant_id = ?4, taken_at = ?5, view = ?6, state = ?7,
                 error = ?8, retry = ?9, attempts = attempts + ?10, updated_at = ?11 WHERE id = ?1",
            params![
                l.id,
                f.size as i64,
                f.mtime,
                plant_id,
                taken_at,
                view,
                state,
                error,
                retry,
                attempts,
                now
            ],
        )?;
        return Ok((l.id, Vec::new()));
    }
    let version = latest.map_or(1, |l| l.version + 1);
    let mut stale = Vec::new();
    if let Some(l) = latest {
        // A new version takes the older ones' counts out of the timeline; the caller
        // recomputes the plants they belonged to.
        tx.execute(
            "UPDATE images SET superseded = 1 WHERE path = ?1 AND id <= ?2",
            params![f.rel, l.id],
        )?;
        stale = tx
            .prepare(
                "SELECT DISTINCT p.id, p.name FROM images i JOIN plants p ON p.id = i.plant_id
                 WHERE i.path = ?1 AND i.state = 'counted'",
            )?
            .query_map([&f.rel], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_, _>>()?;
    }
    tx.execute(
        "INSERT INTO images (path, version, size, mtime, sha256, plant_id, taken_at, view, state, error,
             attempts, retry, first_seen, updated_at)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?13)",
        params![
            f.rel,
            version,
            f.size as i64,
            f.mtime,
            f.sha256,
            plant_id,
            taken_at,
            view,
            state,
            error,
            attempts,
            retry,
            now
        ],
    )?;
    Ok((tx.last_insert_rowid(), stale))
}

struct Diff {
    new_leaves: Vec<u32>,
    /// (fused, emerged, start) per session.
    sessions: Vec<(f64, f64, NaiveDateTime)>,
}

impl Diff {
    /// Fused count and leaves emerged of the session holding time `t`.
    fn at(&self, t: NaiveDateTime) -> (f64, f64) {
        self.sessions
            .iter()
            .rev()
            .find(|s| s.2 <= t)
            .or(self.sessions.first())
            .map_or((0.0, 0.0), |s| (s.0, s.1))
    }
}

/// Recomputes one plant's sessions, events and summary from all its current
/// observations, and appends a feed entry for each newly emerged leaf.
fn recompute(
    tx: &Transaction,
    params: &TimelineParams,
    rule: &str,
    plant_id: i64,
    plant: &str,
    now: &str,
    announce: Announce,
) -> anyhow::Result<Diff> {
    let mut obs: Vec<Obs> = Vec::new();
    // The images' leaf instances, kept as stored text until a site needs them.
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
    let tl = timeline::compute(&obs, params);
    let sites = site_rows::event_sites(&tl, &seen);
    let old: BTreeSet<u32> = tx
        .prepare_cached("SELECT leaf FROM events WHERE plant_id = ?1")?
        .query_map([plant_id], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    let old_lost: f64 = tx
        .prepare_cached("SELECT COALESCE(MAX(leaves_lost), 0) FROM sessions WHERE plant_id = ?1")?
        .query_row([plant_id], |r| r.get(0))?;
    tx.execute("DELETE FROM sessions WHERE plant_id = ?1", [plant_id])?;
    tx.execute("DELETE FROM events WHERE plant_id = ?1", [plant_id])?;
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
    let mut new_leaves = Vec::new();
    for (e, site) in tl.events.iter().zip(&sites) {
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
        if !old.contains(&e.leaf) {
            new_leaves.push(e.leaf);
        }
        if !old.contains(&e.leaf) && announce == Announce::Each {
            push_feed(
                tx,
                &FeedRow {
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
                },
                now,
            )?;
        }
    }
    // One feed row per leaf newly read as lost, dated by the session it first shows in.
    let new_lost = tl.sessions.last().map_or(0.0, |s| s.lost);
    let mut k = old_lost + 1.0;
    while k <= new_lost && announce == Announce::Each {
        let at = tl.sessions.iter().find(|s| s.lost >= k).map(|s| s.start);
        push_feed(
            tx,
            &FeedRow {
                kind: "lost".into(),
                plant: Some(plant.to_string()),
                taken_at: at.map(iso),
                message: Some(format!(
                    "a leaf died by {} ({new_lost} lost in all)",
                    at.map_or("-".into(), |t| t.format("%Y-%m-%d %H:%M").to_string()),
                )),
                ..FeedRow::default()
            },
            now,
        )?;
        k += 1.0;
    }
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
    Ok(Diff {
        new_leaves,
        sessions: tl
            .sessions
            .iter()
            .map(|s| (s.fused, s.emerged, s.start))
            .collect(),
    })
}

/// Works out every plant's thermal phyllochron again (after the temperature
/// log changed); returns how many plants have one.
fn refresh_thermal(tx: &Transaction, params: &TimelineParams) -> anyhow::Result<usize> {
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
pub(crate) fn zone_clock(
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

fn push_feed(tx: &Transaction, row: &FeedRow, now: &str) -> anyhow::Result<()> {
    tx.prepare_cached(
        "INSERT INTO feed (at, kind, plant, taken_at, view, leaf_count, fused, leaves_emerged, new_leaves, path, message)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
    )?
    .execute(params![
        now,
        row.kind,
        row.plant,
        row.taken_at,
        row.view,
        row.leaf_count,
        row.fused,
        row.leaves_emerged,
        serde_json::to_string(&row.new_leaves)?,
        row.path,
        row.message
    ])?;
    Ok(())
}

#[cfg(test)]
mod tests;
