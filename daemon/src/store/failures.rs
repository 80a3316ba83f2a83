//! Failures that no longer need an operator: one made moot by a count of the
//! same image under another name, and those an operator has acknowledged.
//! Both are marked `superseded`, as an image version with a newer one is:
//! `phyllo status` and `--check` count and list only failures that are not.

use rusqlite::params;

use super::{iso, Store};
use crate::domain::names::ParsedName;

impl Store {
    /// After `rel` was counted: failures at other paths of the same bytes
    /// (`sha256`), or of the same plant, time and view, whose file `gone`
    /// says has left the drop directory (a misnamed file renamed, a broken
    /// one replaced under a new name) are superseded. Returns how many.
    pub fn supersede_failures(
        &mut self,
        rel: &str,
        sha256: &str,
        name: &ParsedName,
        gone: impl Fn(&str) -> bool,
    ) -> anyhow::Result<usize> {
        let moot: Vec<(i64, String)> = self
            .conn
            .prepare_cached(
                "SELECT i.id, i.path FROM images i LEFT JOIN plants p ON p.id = i.plant_id
                 WHERE i.state = 'failed' AND i.superseded = 0 AND i.path != ?1
                   AND (i.sha256 = ?2 OR (p.name = ?3 AND i.taken_at = ?4 AND i.view = ?5))",
            )?
            .query_map(
                params![rel, sha256, name.plant, iso(name.taken_at), name.view.to_string()],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )?
            .collect::<Result<_, _>>()?;
        let mut n = 0;
        for (id, path) in moot.into_iter().filter(|(_, path)| gone(path)) {
            self.conn
                .execute("UPDATE images SET superseded = 1 WHERE id = ?1", [id])?;
            tracing::info!("{path}: its failure is superseded by the count of {rel}");
            n += 1;
        }
        Ok(n)
    }

    /// `phyllo status --ack`: every failure recorded so far is acknowledged
    /// (superseded) and leaves the counts, the lists and `--check`. A file
    /// that changes afterwards is still counted, as a new version.
    pub fn acknowledge_failures(&mut self) -> anyhow::Result<usize> {
        Ok(self.conn.execute(
            "UPDATE images SET superseded = 1 WHERE state = 'failed' AND superseded = 0",
            [],
        )?)
    }
}
