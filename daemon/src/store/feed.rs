//! The feed `phyllo tail` follows: rows appended inside the transactions
//! that make the news, and pruned by age.

use std::time::Duration;

use anyhow::Context;
use rusqlite::{params, Transaction};

use super::{FeedRow, Store};

impl Store {
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
}

/// Appends one feed row, written at `now`.
pub(super) fn push_feed(tx: &Transaction, row: &FeedRow, now: &str) -> anyhow::Result<()> {
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
