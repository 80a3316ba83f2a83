//! `phyllo tail`: follows the database's feed from another process.
//!
//! The service appends to the `feed` table in the same transaction as each
//! image, so polling it (a cheap indexed range read in WAL mode, which never
//! blocks the writer) sees exactly what has committed, in order, and nothing
//! twice.

use std::io::Write;
use std::path::Path;
use std::time::Duration;

use crate::store::{FeedRow, Store};

/// How often the feed is polled.
pub const POLL: Duration = Duration::from_millis(250);

/// What `tail` says once, on standard error, before its first line: every
/// time it shows is one clock's, the facility's local time.
pub const TIME_NOTE: &str =
    "phyllo tail: times are local: an image's line shows when it was taken, other lines when phyllo wrote them";

/// Formats one feed row for people, its times in this computer's local time.
pub fn format_row(r: &FeedRow) -> String {
    format_row_in(r, &chrono::Local)
}

/// [`format_row`] with the feed's UTC write times shown in `zone` (tests
/// pin it; capture times are already the facility's local time).
pub fn format_row_in<Z: chrono::TimeZone>(r: &FeedRow, zone: &Z) -> String
where
    Z::Offset: std::fmt::Display,
{
    let at = written_at(&r.at, zone);
    let r = &FeedRow { at, ..r.clone() };
    let plant = r.plant.as_deref().unwrap_or("-");
    let new = if r.new_leaves.is_empty() {
        String::new()
    } else {
        format!(
            "  new leaves {}",
            r.new_leaves
                .iter()
                .map(|l| l.to_string())
                .collect::<Vec<_>>()
                .join(",")
        )
    };
    // People read whole leaves: the fused count rounded, and leaves emerged
    // as the leaves the fit has reached, the rule of every output.
    let fused = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{}", v.round()));
    let emerged = |v: Option<f64>| {
        v.map_or("-".to_string(), |v| {
            crate::domain::timeline::whole_leaves(v).to_string()
        })
    };
    match r.kind.as_str() {
        "count" => format!(
            "{}  {plant}  {}  count {}  fused {}  emerged {}{new}",
            r.taken_at.as_deref().unwrap_or("-"),
            r.view.as_deref().unwrap_or("-"),
            r.leaf_count.map_or("-".into(), |c| c.to_string()),
            fused(r.fused),
            emerged(r.leaves_emerged),
        ),
        "event" => format!(
            "{}  {plant}  EVENT  {}",
            r.taken_at.as_deref().unwrap_or("-"),
            r.message.as_deref().unwrap_or("")
        ),
        "lost" => format!(
            "{}  {plant}  LOST  {}",
            r.taken_at.as_deref().unwrap_or("-"),
            r.message.as_deref().unwrap_or("")
        ),
        "import" => format!(
            "{}  {plant}  IMPORT  fused {}  emerged {}{new}",
            r.at,
            fused(r.fused),
            emerged(r.leaves_emerged)
        ),
        "withdrawn" => format!(
            "{}  {plant}  WITHDRAWN  {}",
            r.at,
            r.message.as_deref().unwrap_or("")
        ),
        "failed" => format!("{}  FAILED  {}", r.at, r.message.as_deref().unwrap_or("")),
        "recount" => format!(
            "{}  {plant}  {}  RECOUNT  {}",
            r.taken_at.as_deref().unwrap_or("-"),
            r.view.as_deref().unwrap_or("-"),
            r.message.as_deref().unwrap_or("")
        ),
        _ => format!(
            "{}  {}  {}",
            r.at,
            r.kind.to_uppercase(),
            r.message.as_deref().unwrap_or("")
        ),
    }
}

/// A feed write time (UTC, `…Z`) in `zone`, as capture times are written
/// (`2026-12-05T09:00:00.000`); left as it is when it does not parse.
fn written_at<Z: chrono::TimeZone>(at: &str, zone: &Z) -> String
where
    Z::Offset: std::fmt::Display,
{
    chrono::DateTime::parse_from_rfc3339(at).map_or_else(
        |_| at.to_string(),
        |t| t.with_timezone(zone).format("%Y-%m-%dT%H:%M:%S%.3f").to_string(),
    )
}

/// Prints feed rows as they land until `stop()` is true. With `from_start`
/// the whole feed is replayed first; otherwise only new rows are shown.
pub fn follow(
    db: &Path,
    plant: Option<&str>,
    json: bool,
    from_start: bool,
    out: &mut dyn Write,
    stop: &dyn Fn() -> bool,
) -> anyhow::Result<()> {
    // Wait for the service to create (and migrate) the database, so tail can start
    // first. Everything in a database that did not exist yet is new to us.
    let existed = db.exists();
    if !json {
        eprintln!("{TIME_NOTE}");
    }
    let mut complained = false;
    let store = loop {
        match Store::open_read_only(db) {
            Ok(s) => break s,
            Err(e) => {
                if stop() {
                    return Err(e);
                }
                if !complained {
                    eprintln!("phyllo tail: waiting for the database: {e:#}");
                    complained = true;
                }
                std::thread::sleep(POLL);
            }
        }
    };
    let mut seq = if from_start || !existed {
        0
    } else {
        store.feed_head()?
    };
    loop {
        // Read once more after a stop request, so nothing committed before it is missed.
        let stopping = stop();
        let rows = store.feed_after(seq, plant, 1000)?;
        for r in &rows {
            if json {
                writeln!(out, "{}", serde_json::to_string(r)?)?;
            } else {
                writeln!(out, "{}", format_row(r))?;
            }
            seq = r.seq;
        }
        out.flush()?;
        if stopping && rows.is_empty() {
            return Ok(());
        }
        if rows.is_empty() {
            std::thread::sleep(POLL);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recount_reads_as_old_and_new_count_of_the_file() {
        let row = FeedRow {
            kind: "recount".into(),
            plant: Some("P1".into()),
            taken_at: Some("2026-05-01T10:00:00".into()),
            view: Some("SV_36".into()),
            leaf_count: Some(9),
            path: Some("P1/a.png".into()),
            message: Some("P1/a.png: count 8 -> 9 (phyllo-s10-cpu)".into()),
            ..FeedRow::default()
        };
        assert_eq!(
            format_row_in(&row, &chrono::Utc),
            "2026-05-01T10:00:00  P1  SV_36  RECOUNT  P1/a.png: count 8 -> 9 (phyllo-s10-cpu)"
        );
    }

    #[test]
    fn a_lost_leaf_reads_with_its_plant_and_session() {
        let row = FeedRow {
            kind: "lost".into(),
            plant: Some("P1".into()),
            taken_at: Some("2026-05-04T10:00:00.000".into()),
            message: Some("a leaf died by 2026-05-04 10:00 (1 lost in all)".into()),
            ..FeedRow::default()
        };
        assert_eq!(
            format_row_in(&row, &chrono::Utc),
            "2026-05-04T10:00:00.000  P1  LOST  a leaf died by 2026-05-04 10:00 (1 lost in all)"
        );
    }

    #[test]
    fn write_times_read_in_the_local_clock_like_capture_times() {
        let row = FeedRow {
            at: "2026-12-05T08:00:00.000Z".into(),
            kind: "failed".into(),
            message: Some("x.png: corrupt".into()),
            ..FeedRow::default()
        };
        let zone = chrono::FixedOffset::east_opt(3600).unwrap();
        assert_eq!(
            format_row_in(&row, &zone),
            "2026-12-05T09:00:00.000  FAILED  x.png: corrupt"
        );
        assert!(!format_row(&row).contains('Z'));
    }

    #[test]
    fn counts_read_as_whole_leaves() {
        let row = FeedRow {
            kind: "count".into(),
            plant: Some("P1".into()),
            taken_at: Some("2026-05-01T10:00:00.000".into()),
            view: Some("SV_36".into()),
            leaf_count: Some(5),
            fused: Some(4.33),
            leaves_emerged: Some(3.8),
            new_leaves: vec![3],
            ..FeedRow::default()
        };
        assert_eq!(
            format_row_in(&row, &chrono::Utc),
            "2026-05-01T10:00:00.000  P1  SV_36  count 5  fused 4  emerged 3  new leaves 3"
        );
    }

    #[test]
    fn a_withdrawn_leaf_reads_with_its_plant() {
        let row = FeedRow {
            at: "2026-12-05T08:00:00.000Z".into(),
            kind: "withdrawn".into(),
            plant: Some("P1".into()),
            message: Some("leaf 6 withdrawn: with the newer images the fit no longer finds it".into()),
            ..FeedRow::default()
        };
        assert_eq!(
            format_row_in(&row, &chrono::Utc),
            "2026-12-05T08:00:00.000  P1  WITHDRAWN  leaf 6 withdrawn: with the newer images the fit no longer finds it"
        );
    }

    #[test]
    fn a_refit_reads_as_one_line_with_its_reason() {
        let row = FeedRow {
            at: "2026-12-05T08:00:00Z".into(),
            kind: "refit".into(),
            message: Some("timeline settings now fusion=max-side: 36 plants refitted".into()),
            ..FeedRow::default()
        };
        assert_eq!(
            format_row_in(&row, &chrono::Utc),
            "2026-12-05T08:00:00.000  REFIT  timeline settings now fusion=max-side: 36 plants refitted"
        );
    }
}
