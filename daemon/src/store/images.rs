//! Images: the ledger of every file seen (versions, hashes, duplicates,
//! failures) and the observation each counted image adds, written with the
//! plant's refit in one transaction.

use rusqlite::{params, OptionalExtension, Transaction, TransactionBehavior};

use super::derive::{refit_plants, refresh, Announce};
use super::feed::push_feed;
use super::{iso, now_utc, FeedRow, Store};
use crate::domain::names::ParsedName;

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

/// A count to store, independent of the inference crate's types.
#[derive(Debug, Clone, PartialEq)]
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
    /// Its bytes were counted before under another identity (another
    /// plant, time or view, or a version its path has since left): an
    /// observation of its own, with the count already made.
    Reuse {
        /// The count made of the same bytes.
        count: CountRecord,
        /// Where they were counted (path relative to the drop directory).
        original: String,
    },
}

/// What a failure for a file's permissions says ("P1.png: permission
/// denied: …"): such a failure is tried again once the file can be read.
pub const PERMISSION_DENIED: &str = ": permission denied";

impl Store {
    /// True if the latest version of `rel` has this size and mtime and needs
    /// no more work: lets periodic rescans skip files without reading them.
    /// A file that failed for its permissions until its attempts ran out is
    /// tried again once `readable` says it can be read: `chmod` changes
    /// neither its size nor its mtime.
    pub fn is_known(
        &self,
        rel: &str,
        size: u64,
        mtime: &str,
        readable: impl FnOnce() -> bool,
    ) -> anyhow::Result<bool> {
        /// size, mtime, state, retry, attempts, error
        type Row = (i64, Option<String>, String, i64, u32, Option<String>);
        let row: Option<Row> = self
            .conn
            .prepare_cached(
                "SELECT size, mtime, state, retry, attempts, error FROM images WHERE path = ?1 ORDER BY version DESC LIMIT 1",
            )?
            .query_row([rel], |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?, r.get(5)?))
            })
            .optional()?;
        Ok(match row {
            Some((s, Some(m), state, retry, attempts, error)) if s as u64 == size && m == mtime => {
                let gave_up = state == "failed" && retry != 0 && attempts >= self.max_attempts;
                let unreadable = error.is_some_and(|e| e.contains(PERMISSION_DENIED));
                state != "failed" || retry == 0 || (gave_up && !(unreadable && readable()))
            }
            _ => false,
        })
    }

    /// Decides, from the content hash and the name's identity, whether a file
    /// needs counting (docs/daemon.md, "An image's identity"). Same content
    /// at the same path: skip (and remember the new mtime). Content counted
    /// as the same image (plant, time and view) elsewhere: recorded here as a
    /// duplicate, skip. Content counted under another identity: reuse that
    /// count. Without a name (it does not parse) any counted copy is a duplicate.
    pub fn precheck(&mut self, f: &FileFacts, name: Option<&ParsedName>) -> anyhow::Result<Precheck> {
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
        if let Some((orig_id, orig_path)) = counted_same_image(&tx, &f.sha256, name)? {
            let stale = insert_duplicate(&tx, f, latest.as_ref(), orig_id, &orig_path)?;
            refresh(&tx, &self.fit, &stale, None)?;
            tx.commit()?;
            return Ok(Precheck::Skip(format!(
                "{} has the same content as {orig_path}",
                f.rel
            )));
        }
        if name.is_some() {
            if let Some((count, original)) = counted_count(&tx, &f.sha256)? {
                return Ok(Precheck::Reuse { count, original });
            }
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
                if let Some((orig_id, orig_path)) = counted_same_image(&tx, &f.sha256, Some(name))? {
                    if same.map(|l| l.id) != Some(orig_id) {
                        let stale = insert_duplicate(&tx, f, latest.as_ref(), orig_id, &orig_path)?;
                        refresh(&tx, &self.fit, &stale, None)?;
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
                refresh(&tx, &self.fit, &stale, Some(plant_id))?;
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
                let plant = [(plant_id, name.plant.clone())];
                let diff = refit_plants(&tx, &self.fit, &plant, &now, Announce::Each, |plant, diff| {
                    let (fused, emerged) = diff.at(name.taken_at);
                    Some(FeedRow {
                        kind: "count".into(),
                        plant: Some(plant.to_string()),
                        taken_at: Some(iso(name.taken_at)),
                        view: Some(name.view.to_string()),
                        leaf_count: Some(count.leaf_count as i64),
                        fused: Some(fused),
                        leaves_emerged: Some(emerged),
                        new_leaves: diff.new_leaves.clone(),
                        path: Some(f.rel.clone()),
                        ..FeedRow::default()
                    })
                })?
                .remove(0);
                let (fused, emerged) = diff.at(name.taken_at);
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
                refresh(&tx, &self.fit, &stale, None)?;
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
}

/// The newest version of a path, as the ledger holds it.
struct Latest {
    id: i64,
    version: i64,
    sha256: String,
    state: String,
    retry: i64,
    attempts: u32,
}

/// The newest version of `rel`, if the ledger holds it.
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

/// The first counted image with this content that is the same image as
/// `name` says (plant, time and view; current versions only), as (id, path);
/// without a name, the first counted image with this content.
fn counted_same_image(
    tx: &Transaction,
    sha: &str,
    name: Option<&ParsedName>,
) -> anyhow::Result<Option<(i64, String)>> {
    let Some(n) = name else {
        return Ok(tx
            .prepare_cached(
                "SELECT id, path FROM images WHERE sha256 = ?1 AND state = 'counted' ORDER BY id LIMIT 1",
            )?
            .query_row([sha], |r| Ok((r.get(0)?, r.get(1)?)))
            .optional()?);
    };
    Ok(tx
        .prepare_cached(
            "SELECT i.id, i.path FROM images i JOIN plants p ON p.id = i.plant_id
             WHERE i.sha256 = ?1 AND i.state = 'counted' AND i.superseded = 0
               AND p.name = ?2 AND i.taken_at = ?3 AND i.view = ?4
             ORDER BY i.id LIMIT 1",
        )?
        .query_row(params![sha, n.plant, iso(n.taken_at), n.view.to_string()], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .optional()?)
}

/// The newest count made of this content, and the image it was made of.
fn counted_count(tx: &Transaction, sha: &str) -> anyhow::Result<Option<(CountRecord, String)>> {
    let json = |text: Option<String>| {
        text.and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or_default()
    };
    Ok(tx
        .prepare_cached(
            "SELECT o.leaf_count, o.instances, o.timing, o.ms_total, o.model_id, o.settings, i.path
             FROM images i JOIN observations o ON o.image_id = i.id
             WHERE i.sha256 = ?1 AND i.state = 'counted' ORDER BY i.id DESC LIMIT 1",
        )?
        .query_row([sha], |r| {
            Ok((
                CountRecord {
                    leaf_count: r.get(0)?,
                    instances: json(r.get(1)?),
                    timing: json(r.get(2)?),
                    ms_total: r.get::<_, Option<f64>>(3)?.unwrap_or(0.0),
                    model_id: r.get(4)?,
                    settings: json(r.get(5)?),
                },
                r.get(6)?,
            ))
        })
        .optional()?)
}

/// The plant's id, adding it on first sight.
pub(super) fn upsert_plant(tx: &Transaction, name: &str, now: &str) -> anyhow::Result<i64> {
    tx.execute(
        "INSERT INTO plants (name, first_seen) VALUES (?1, ?2) ON CONFLICT (name) DO NOTHING",
        params![name, now],
    )?;
    Ok(tx.query_row("SELECT id FROM plants WHERE name = ?1", [name], |r| r.get(0))?)
}

/// Records `f` as a duplicate of an image already counted, with its feed
/// row; returns the plants whose timeline lost a superseded count.
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
