//! Images moved to another plant: a misread barcode files a plant's images
//! under another id, and the file names cannot be fixed without the daemon
//! counting the files again as copies. `phyllo import` of an `image,plant`
//! sheet moves each image (every version of its path) and its count to the
//! named plant and refits both plants; each move is recorded with the plant
//! it came from, so `phyllo import --undo SHEET` moves it back, and the sheet
//! is journalled like any import so a restore takes it again.

use std::collections::BTreeMap;

use anyhow::{bail, Context};
use rusqlite::{params, TransactionBehavior};

use super::derive::{refit_plants, Announce};
use super::feed::push_feed;
use super::images::upsert_plant;
use super::imports::record_import;
use super::{now_utc, FeedRow, Store};

impl Store {
    /// Moves each image of `moves` (path relative to the drop directory,
    /// plant) to its plant, in one transaction, and refits every plant that
    /// lost or gained one. Returns (images moved, plants refitted). An image
    /// the database does not hold fails the whole sheet, naming it.
    pub fn reassign(
        &mut self,
        source: &str,
        moves: &[(String, String)],
        journal: Option<&str>,
    ) -> anyhow::Result<(usize, usize)> {
        let now = now_utc();
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        // plant id → name, of every plant an image leaves or joins.
        let mut touched: BTreeMap<i64, String> = BTreeMap::new();
        // (from, to) → images moved.
        let mut moved: BTreeMap<(String, String), usize> = BTreeMap::new();
        for (i, (path, plant)) in moves.iter().enumerate() {
            let versions: Vec<(i64, Option<i64>, Option<String>)> = tx
                .prepare_cached(
                    "SELECT i.id, i.plant_id, p.name FROM images i LEFT JOIN plants p ON p.id = i.plant_id
                     WHERE i.path = ?1 ORDER BY i.version",
                )?
                .query_map([path], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?
                .collect::<Result<_, _>>()?;
            if versions.is_empty() {
                // Row i of the sheet is its line i + 2, after the header.
                bail!(
                    "line {}: no image {path:?} in the database (give the path as images.csv has it)",
                    i + 2
                );
            }
            let to = upsert_plant(&tx, plant, &now)?;
            touched.insert(to, plant.clone());
            for (image_id, from, from_name) in versions {
                if from == Some(to) {
                    continue;
                }
                tx.execute(
                    "INSERT INTO reassignments (image_id, from_plant_id, to_plant_id, source, moved_at)
                     VALUES (?1, ?2, ?3, ?4, ?5)",
                    params![image_id, from, to, source, now],
                )?;
                tx.execute(
                    "UPDATE images SET plant_id = ?2 WHERE id = ?1",
                    params![image_id, to],
                )?;
                tx.execute(
                    "UPDATE observations SET plant_id = ?2 WHERE image_id = ?1",
                    params![image_id, to],
                )?;
                if let (Some(from), Some(name)) = (from, &from_name) {
                    touched.insert(from, name.clone());
                }
                *moved
                    .entry((from_name.unwrap_or_default(), plant.clone()))
                    .or_default() += 1;
            }
        }
        let touched: Vec<(i64, String)> = touched.into_iter().collect();
        refit_plants(&tx, &self.fit, &touched, &now, Announce::Each, |_, _| None)?;
        for ((from, to), n) in &moved {
            push_feed(
                &tx,
                &FeedRow {
                    kind: "reassign".into(),
                    plant: Some(to.clone()),
                    message: Some(format!("{n} images moved from {from} to {to} ({source})")),
                    ..FeedRow::default()
                },
                &now,
            )?;
        }
        record_import(&tx, journal, source, moves.len(), touched.len(), &now)?;
        tx.commit()?;
        Ok((moved.values().sum(), touched.len()))
    }

    /// Moves back every image `source` moved (newest move first, so an image
    /// moved twice ends where it started) and refits the plants; returns how
    /// many images went back. Runs inside `unimport`'s transaction.
    pub(super) fn unassign(
        tx: &rusqlite::Transaction,
        source: &str,
    ) -> anyhow::Result<(usize, Vec<(i64, String)>)> {
        let rows: Vec<(i64, i64, Option<i64>, i64)> = tx
            .prepare(
                "SELECT id, image_id, from_plant_id, to_plant_id FROM reassignments WHERE source = ?1
                 ORDER BY id DESC",
            )?
            .query_map([source], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))?
            .collect::<Result<_, _>>()?;
        let mut plants: BTreeMap<i64, String> = BTreeMap::new();
        for (id, image_id, from, to) in &rows {
            tx.execute(
                "UPDATE images SET plant_id = ?2 WHERE id = ?1",
                params![image_id, from],
            )?;
            if let Some(from) = from {
                tx.execute(
                    "UPDATE observations SET plant_id = ?2 WHERE image_id = ?1",
                    params![image_id, from],
                )?;
            }
            tx.execute("DELETE FROM reassignments WHERE id = ?1", [id])?;
            for pid in from.iter().chain(std::iter::once(to)) {
                let name: String = tx
                    .query_row("SELECT name FROM plants WHERE id = ?1", [pid], |r| r.get(0))
                    .with_context(|| format!("plant {pid} of a recorded move"))?;
                plants.insert(*pid, name);
            }
        }
        Ok((rows.len(), plants.into_iter().collect()))
    }
}
