//! What `phyllo recount` reads from and writes to the store: the images
//! counted so far, and a count replaced in place (with a feed entry, so
//! that `phyllo tail` shows what a recount changed).

use anyhow::Context;
use rusqlite::{params, OptionalExtension, TransactionBehavior};

use super::feed::push_feed;
use super::{now_utc, CountRecord, FeedRow, Store};

/// One counted image, as the store holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct CountedImage {
    /// Row id in `images`.
    pub image_id: i64,
    /// Path relative to the drop directory.
    pub path: String,
    /// Content hash recorded when it was counted.
    pub sha256: String,
    /// Plant name.
    pub plant: String,
    /// Leaves counted then.
    pub leaf_count: u32,
    /// Settings it was counted with (JSON text), `None` before schema 2.
    pub settings: Option<String>,
    /// The view its name was read as when it was counted (`SV_108`, `TV_90`).
    pub view: String,
}

impl Store {
    /// The latest version of every counted image, of one plant or of all,
    /// in order of plant and time taken.
    pub fn counted_images(&self, plant: Option<&str>) -> anyhow::Result<Vec<CountedImage>> {
        let mut stmt = self.conn.prepare(
            "SELECT i.id, i.path, i.sha256, p.name, o.leaf_count, o.settings, o.view
             FROM images i
             JOIN observations o ON o.image_id = i.id
             JOIN plants p ON p.id = o.plant_id
             WHERE i.state = 'counted' AND i.superseded = 0 AND (?1 IS NULL OR p.name = ?1)
             ORDER BY p.name, i.taken_at, i.path",
        )?;
        let rows = stmt
            .query_map(params![plant], |r| {
                Ok(CountedImage {
                    image_id: r.get(0)?,
                    path: r.get(1)?,
                    sha256: r.get(2)?,
                    plant: r.get(3)?,
                    leaf_count: r.get(4)?,
                    settings: r.get(5)?,
                    view: r.get(6)?,
                })
            })?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// Replaces the count of a counted image with `count`; a changed count
    /// also lands in the feed as a `recount` entry. Timelines are not
    /// refitted here: call [`Store::recompute_all`] once after a batch.
    pub fn replace_count(&mut self, image_id: i64, count: &CountRecord) -> anyhow::Result<()> {
        let now = now_utc();
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let (old, plant, taken_at, view, path): (i64, String, Option<String>, Option<String>, String) = tx
            .query_row(
                "SELECT o.leaf_count, p.name, i.taken_at, i.view, i.path
                 FROM observations o
                 JOIN images i ON i.id = o.image_id
                 JOIN plants p ON p.id = o.plant_id
                 WHERE o.image_id = ?1",
                [image_id],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)),
            )
            .optional()?
            .with_context(|| format!("image {image_id} has no observation to replace"))?;
        tx.execute(
            "UPDATE observations SET leaf_count = ?2, instances = ?3, model_id = ?4, timing = ?5,
                 ms_total = ?6, settings = ?7, created_at = ?8
             WHERE image_id = ?1",
            params![
                image_id,
                count.leaf_count,
                count.instances.to_string(),
                count.model_id,
                count.timing.to_string(),
                count.ms_total,
                count.settings_text(),
                now
            ],
        )?;
        let new = i64::from(count.leaf_count);
        if new != old {
            let message = format!("{path}: count {old} -> {new} ({})", count.model_id);
            let row = FeedRow {
                kind: "recount".into(),
                plant: Some(plant),
                taken_at,
                view,
                leaf_count: Some(new),
                path: Some(path),
                message: Some(message),
                ..FeedRow::default()
            };
            push_feed(&tx, &row, &now)?;
        }
        tx.commit()?;
        Ok(())
    }
}
