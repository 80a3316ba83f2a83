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

//!
//! Every SQL statement of the daemon lives in this module; [`derive`] is the
//! one door from stored rows to [`crate::domain`] and back
//! (`docs/ARCHITECTURE.md`).

mod derive;
pub mod exports;
mod failures;
mod feed;
mod images;
mod imports;
mod lock;
pub mod migrations;
mod queries;
mod reassign;
mod recount;
mod site_rows;
pub mod snapshot;

pub use images::{CountRecord, FileFacts, Outcome, Precheck, Recorded, PERMISSION_DENIED};
pub use imports::{Reading, Unimported};
pub use lock::{DatabaseLock, RestoreLock, WritersLock};
pub use recount::CountedImage;

use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context};
use chrono::NaiveDateTime;
use rusqlite::{params, Connection, OpenFlags};

use crate::domain::timeline::TimelineParams;
use derive::Fit;

pub use crate::domain::plant::{LeafSiteRow, NextLeafRow, PlantTimeline, SessionRow};
pub use queries::{ClimateSummary, FeedRow, ImageCounts, LastImage, TimelineSummary};

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

/// The database.
pub struct Store {
    conn: Connection,
    fit: Fit,
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
    /// Opens (creating if needed) a database for writing and migrates it;
    /// timelines are fitted by `timeline` (the config's compiled rules).
    pub fn open(path: &Path, timeline: &TimelineParams, max_attempts: u32) -> anyhow::Result<Store> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            crate::files::owner::create_dir_all(dir)
                .with_context(|| format!("creating database directory {}", dir.display()))?;
        }
        let mut conn =
            Connection::open(path).with_context(|| format!("opening database {}", path.display()))?;
        // A database root creates must stay the service user's (SQLite gives
        // its -wal and -shm files the database file's owner itself).
        crate::files::owner::match_parent(path);
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
            fit: Fit {
                params: timeline.clone(),
                rule: timeline.source.fusion.clone(),
            },
            max_attempts,
        };
        // Changed timeline settings (in the config, or new defaults after an
        // upgrade) would otherwise leave plants that get no new image fitted the old way.
        let fit = timeline_settings(&timeline.source, &timeline.zones);
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
            fit: Fit {
                params: TimelineParams::default(),
                rule: String::new(),
            },
            max_attempts: 0,
        })
    }

    /// Which temperature log times each plant (the config's `[[timeline.zones]]`).
    pub fn zone_rules(&self) -> &crate::domain::climate_zone::ZoneRules {
        &self.fit.params.zones
    }

    /// The underlying connection, for the store's own tests: every other
    /// reader asks for the rows it needs.
    #[cfg(test)]
    pub(crate) fn conn(&self) -> &Connection {
        &self.conn
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
}

#[cfg(test)]
mod tests;
