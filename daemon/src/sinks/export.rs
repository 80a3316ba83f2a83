//! `phyllo export`: RFC 4180 CSV with a header row and ISO 8601 times,
//! written to a temporary file beside the target and renamed into place, so a
//! reader never sees half a file.

use std::path::Path;

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
        // One row per plant and session: fused count, leaves emerged (fit), living leaves
        // (smoothed), leaves read as dead by then.
        "timeline" => {
            "SELECT p.name AS plant, s.start AS session_start, s.fused, s.leaves_emerged, s.living,
                    p.phyllochron_days, s.leaves_lost
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
                    p.last_taken_at AS last_session, p.leaves_emerged, p.living,
                    (SELECT COALESCE(MAX(s.leaves_lost), 0) FROM sessions s WHERE s.plant_id = p.id) AS leaves_lost,
                    p.phyllochron_days,
                    (SELECT COUNT(*) FROM events e WHERE e.plant_id = p.id) AS events,
                    (SELECT MAX(e.emerged_at) FROM events e WHERE e.plant_id = p.id) AS last_emergence,
                    p.phyllochron_cd, p.climate_zone, p.next_leaf, p.next_leaf_at AS next_leaf_expected
             FROM plants p
             WHERE ?1 IS NULL OR p.last_taken_at >= ?1
             ORDER BY p.name"
        }
        _ => bail!("unknown export '{kind}' (one of: {})", KINDS.join(", ")),
    })
}

/// Writes one export kind to `out` atomically. Returns the number of rows.
pub fn export(conn: &Connection, kind: &str, since: Option<&str>, out: &Path) -> anyhow::Result<usize> {
    let mut stmt = conn.prepare(query(kind)?)?;
    let names = column_names(&stmt);
    write_csv(out, |w| {
        w.write_record(&names)?;
        let mut rows = stmt.query([since])?;
        let mut n = 0;
        while let Some(row) = rows.next()? {
            w.write_record(cells(row, names.len())?)?;
            n += 1;
        }
        Ok(n)
    })
}

/// One export kind in memory, as its CSV would hold it: (header, rows).
/// For small kinds (`plants`); the others stream through [`export`].
pub fn table(conn: &Connection, kind: &str) -> anyhow::Result<(Vec<String>, Vec<Vec<String>>)> {
    let mut stmt = conn.prepare(query(kind)?)?;
    let names = column_names(&stmt);
    let mut rows = stmt.query([None::<&str>])?;
    let mut out = Vec::new();
    while let Some(row) = rows.next()? {
        out.push(cells(row, names.len())?);
    }
    Ok((names, out))
}

fn column_names(stmt: &rusqlite::Statement<'_>) -> Vec<String> {
    stmt.column_names().iter().map(|s| s.to_string()).collect()
}

/// A row's values as CSV cells: NULL empty, reals compact.
fn cells(row: &rusqlite::Row<'_>, n: usize) -> anyhow::Result<Vec<String>> {
    (0..n)
        .map(|i| {
            Ok(match row.get_ref(i)? {
                ValueRef::Null => String::new(),
                ValueRef::Integer(v) => v.to_string(),
                ValueRef::Real(v) => format_real(v),
                ValueRef::Text(t) | ValueRef::Blob(t) => String::from_utf8_lossy(t).into_owned(),
            })
        })
        .collect()
}

/// The CSV writer [`write_csv`] hands out.
pub type CsvOut = csv::Writer<std::fs::File>;

/// Writes a CSV (CRLF, as RFC 4180) and renames it into place
/// ([`super::atomic::replace`]); `fill` writes the records and returns the
/// number of rows. On any error `out` is left as it was.
pub fn write_csv(
    out: &Path,
    fill: impl FnOnce(&mut CsvOut) -> anyhow::Result<usize>,
) -> anyhow::Result<usize> {
    super::atomic::replace(out, ".csv", |tmp| {
        let mut w = csv::WriterBuilder::new()
            .terminator(csv::Terminator::CRLF)
            .from_path(tmp)?;
        let n = fill(&mut w)?;
        w.flush()?;
        Ok(n)
    })
}

/// Reals with at most 4 decimals, no trailing zeros (13.3333, 8, 1.425).
pub fn format_real(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_are_compact() {
        assert_eq!(format_real(8.0), "8");
        assert_eq!(format_real(40.0 / 3.0), "13.3333");
        assert_eq!(format_real(1.425), "1.425");
        assert_eq!(format_real(-0.00001), "0");
    }

    #[test]
    fn unknown_kind_is_refused() {
        let conn = Connection::open_in_memory().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let err = export(&conn, "leaves", None, &dir.path().join("x.csv")).unwrap_err();
        assert!(
            err.to_string()
                .contains("images, sessions, timeline, events, plants"),
            "{err}"
        );
        assert!(!dir.path().join("x.csv").exists());
    }
}
