//! The queries behind `phyllo export`: one per table it writes, each row
//! handed out as plain cells for the CSV sink to format.

use anyhow::bail;
use rusqlite::types::ValueRef;
use rusqlite::Connection;

/// The tables `phyllo export` can write.
pub const KINDS: [&str; 5] = ["images", "sessions", "timeline", "events", "plants"];

/// The query for one export kind; `?1` is the `--since` bound (or NULL).
fn query(kind: &str) -> anyhow::Result<&'static str> {
    Ok(match kind {
        // One row per image version: what was counted, skipped or failed, and why.
        "images" => {
            "SELECT i.path, i.version, i.state, p.name AS plant, i.taken_at, i.view, o.leaf_count,
                    o.model_id, o.ms_total, i.size, i.sha256, d.path AS duplicate_of, i.superseded,
                    i.attempts, i.error, i.first_seen, i.updated_at, o.settings
             FROM images i
             LEFT JOIN plants p ON p.id = i.plant_id
             LEFT JOIN observations o ON o.image_id = i.id
             LEFT JOIN images d ON d.id = i.duplicate_of
             WHERE ?1 IS NULL OR COALESCE(i.taken_at, i.first_seen) >= ?1
             ORDER BY COALESCE(i.taken_at, i.first_seen), i.path, i.version"
        }
        // One row per plant and imaging session: every view's count and the fused count.
        "sessions" => {
            "SELECT p.name AS plant, s.start AS session_start, s.n_counts,
                    (SELECT group_concat(key || '=' || value, ';') FROM json_each(s.views)) AS views,
                    s.fused, s.fusion_rule
             FROM sessions s JOIN plants p ON p.id = s.plant_id
             WHERE ?1 IS NULL OR s.start >= ?1
             ORDER BY p.name, s.start"
        }
        // One row per plant and session: fused count, leaves emerged (whole leaves, as
        // domain::timeline::whole_leaves has them; the fit itself in leaves_emerged_fit),
        // living leaves (smoothed), leaves read as dead by then.
        "timeline" => {
            "SELECT p.name AS plant, s.start AS session_start, s.fused,
                    CAST(s.leaves_emerged + 1e-9 AS INTEGER) AS leaves_emerged, s.living,
                    p.phyllochron_days, s.leaves_lost, s.leaves_emerged AS leaves_emerged_fit
             FROM sessions s JOIN plants p ON p.id = s.plant_id
             WHERE ?1 IS NULL OR s.start >= ?1
             ORDER BY p.name, s.start"
        }
        // One row per leaf emergence event, and where the leaf was first seen (crate::domain::leaf_site).
        "events" => {
            "SELECT p.name AS plant, e.leaf, e.emerged_at, e.seen_at, p.phyllochron_days,
                    e.site_view, e.site_image, e.site_x, e.site_y, e.site_bbox, e.site_area
             FROM events e JOIN plants p ON p.id = e.plant_id
             WHERE ?1 IS NULL OR e.emerged_at >= ?1
             ORDER BY p.name, e.leaf"
        }
        // One row per plant: where its timeline stands now (a breeder's summary sheet).
        "plants" => {
            "SELECT p.name AS plant, p.sessions,
                    (SELECT MIN(s.start) FROM sessions s WHERE s.plant_id = p.id) AS first_session,
                    p.last_taken_at AS last_session,
                    CAST(p.leaves_emerged + 1e-9 AS INTEGER) AS leaves_emerged, p.living,
                    (SELECT COALESCE(MAX(s.leaves_lost), 0) FROM sessions s WHERE s.plant_id = p.id) AS leaves_lost,
                    p.phyllochron_days,
                    (SELECT COUNT(*) FROM events e WHERE e.plant_id = p.id) AS events,
                    (SELECT MAX(e.emerged_at) FROM events e WHERE e.plant_id = p.id) AS last_emergence,
                    p.phyllochron_cd, p.climate_zone, p.next_leaf, p.next_leaf_at AS next_leaf_expected,
                    p.leaves_emerged AS leaves_emerged_fit
             FROM plants p
             WHERE ?1 IS NULL OR p.last_taken_at >= ?1
             ORDER BY p.name"
        }
        _ => bail!("unknown export '{kind}' (one of: {})", KINDS.join(", ")),
    })
}

/// Refuses a kind `phyllo export` does not know, naming the ones it does.
pub fn check_kind(kind: &str) -> anyhow::Result<()> {
    query(kind).map(|_| ())
}

/// One value of an exported row.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// SQL NULL.
    Null,
    /// An integer.
    Integer(i64),
    /// A real number.
    Real(f64),
    /// Text (or a blob, read as UTF-8).
    Text(String),
}

/// What [`export_rows`] hands out: the column names once, then each row.
pub enum ExportLine<'a> {
    /// The column names.
    Header(&'a [String]),
    /// One row's cells, in column order.
    Row(&'a [Cell]),
}

impl super::Store {
    /// Streams one export kind (rows since `since` where the kind has a time)
    /// to `each`: the header first, then every row. Returns the number of rows.
    pub fn export_rows(
        &self,
        kind: &str,
        since: Option<&str>,
        each: impl FnMut(ExportLine<'_>) -> anyhow::Result<()>,
    ) -> anyhow::Result<usize> {
        stream(&self.conn, kind, since, each)
    }
}

/// [`super::Store::export_rows`] on a connection.
fn stream(
    conn: &Connection,
    kind: &str,
    since: Option<&str>,
    mut each: impl FnMut(ExportLine<'_>) -> anyhow::Result<()>,
) -> anyhow::Result<usize> {
    let mut stmt = conn.prepare(query(kind)?)?;
    let names: Vec<String> = stmt.column_names().iter().map(|s| s.to_string()).collect();
    each(ExportLine::Header(&names))?;
    let mut rows = stmt.query([since])?;
    let mut n = 0;
    while let Some(row) = rows.next()? {
        let cells = (0..names.len())
            .map(|i| {
                Ok(match row.get_ref(i)? {
                    ValueRef::Null => Cell::Null,
                    ValueRef::Integer(v) => Cell::Integer(v),
                    ValueRef::Real(v) => Cell::Real(v),
                    ValueRef::Text(t) | ValueRef::Blob(t) => {
                        Cell::Text(String::from_utf8_lossy(t).into_owned())
                    }
                })
            })
            .collect::<anyhow::Result<Vec<Cell>>>()?;
        each(ExportLine::Row(&cells))?;
        n += 1;
    }
    Ok(n)
}
