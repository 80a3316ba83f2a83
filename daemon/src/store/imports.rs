//! Imports: counts made elsewhere (people, other tools), greenhouse
//! temperature logs, and taking either back; each recorded by its journal entry.

use std::collections::{BTreeMap, BTreeSet};

use chrono::NaiveDateTime;
use rusqlite::{params, Transaction, TransactionBehavior};

use super::derive::{refit_plants, refresh_thermal, Announce};
use super::images::upsert_plant;
use super::{iso, now_utc, FeedRow, Store};
use crate::domain::names::View;

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

impl Store {
    /// Ingests counts made elsewhere, in one transaction. Re-importing the
    /// same row (plant, time, view, source) replaces its count rather than
    /// adding a second one. `journal` names the file's entry in the import
    /// journal ([`crate::ops::import_journal`]), recorded with it. Returns (rows, plants).
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
        let plants: Vec<(i64, String)> = plants.into_iter().map(|(name, id)| (id, name)).collect();
        refit_plants(&tx, &self.fit, &plants, &now, Announce::Each, |plant, diff| {
            Some(FeedRow {
                kind: "import".into(),
                plant: Some(plant.to_string()),
                leaves_emerged: diff.sessions.last().map(|s| s.1),
                fused: diff.sessions.last().map(|s| s.0),
                new_leaves: diff.new_leaves.clone(),
                message: Some(format!("imported from {source}")),
                ..FeedRow::default()
            })
        })?;
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
        let with = refresh_thermal(&tx, &self.fit.params)?;
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
        refit_plants(&tx, &self.fit, &plants, &now, Announce::Each, |plant, _| {
            Some(FeedRow {
                kind: "import".into(),
                plant: Some(plant.to_string()),
                message: Some(format!("what {source} imported or moved was taken back")),
                ..FeedRow::default()
            })
        })?;
        if temps > 0 {
            refresh_thermal(&tx, &self.fit.params)?;
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
}

/// Records an import by its journal entry (when it has one), so a restore
/// knows which entries the database already holds.
pub(super) fn record_import(
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
