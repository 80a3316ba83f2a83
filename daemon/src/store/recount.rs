//! What `phyllo recount` reads from and writes to the store: the images
//! counted so far, and a count replaced in place.

use rusqlite::params;

use super::{now_utc, CountRecord, Store};

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
}

impl Store {
    /// The latest version of every counted image, of one plant or of all,
    /// in order of plant and time taken.
    pub fn counted_images(&self, plant: Option<&str>) -> anyhow::Result<Vec<CountedImage>> {
        let mut stmt = self.conn.prepare(
            "SELECT i.id, i.path, i.sha256, p.name, o.leaf_count, o.settings
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
                })
            })?
            .collect::<Result<_, _>>()?;
        Ok(rows)
    }

    /// Replaces the count of a counted image with `count`. Timelines are
    /// not refitted here: call [`Store::recompute_all`] once after a batch.
    pub fn replace_count(&mut self, image_id: i64, count: &CountRecord) -> anyhow::Result<()> {
        let n = self.conn.execute(
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
                now_utc()
            ],
        )?;
        anyhow::ensure!(n == 1, "image {image_id} has no observation to replace");
        Ok(())
    }
}
