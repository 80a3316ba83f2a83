//! The review sheet: the days to check ([`crate::domain::review`]) as a CSV a person
//! fills in and hands back to `phyllo import`. Its first four columns are
//! import's (`plant,timestamp,view,leaf_count`, the view `human` and the
//! count left empty); the rest say what phyllo counted and where the images
//! are. Rows left empty are skipped on import.

use std::path::Path;

use serde::Serialize;

use crate::domain::review::Doubt;
use crate::sinks::export::{format_real, write_csv};
use crate::store::Store;

/// The sheet's header.
pub const COLUMNS: [&str; 9] = [
    "plant",
    "timestamp",
    "view",
    "leaf_count",
    "phyllo_count",
    "timeline",
    "views",
    "why",
    "images",
];

/// A session to check, with its images.
#[derive(Debug, Clone, Serialize)]
pub struct Item {
    /// The session and why it is in doubt.
    #[serde(flatten)]
    pub doubt: Doubt,
    /// Its counted images, relative to the drop directory (`;` between them in the sheet).
    pub images: Vec<String>,
}

/// The first `top` sessions of `ranked` with their images.
pub fn items(store: &Store, ranked: &[Doubt], top: usize) -> anyhow::Result<Vec<Item>> {
    ranked
        .iter()
        .take(top)
        .map(|d| {
            let images = store
                .session_images(&d.plant, &d.start, d.until.as_deref())?
                .into_iter()
                .map(|(path, _)| path)
                .collect();
            Ok(Item {
                doubt: d.clone(),
                images,
            })
        })
        .collect()
}

/// One row per item, in [`COLUMNS`] order.
pub fn rows(items: &[Item]) -> Vec<Vec<String>> {
    items
        .iter()
        .map(|it| {
            let d = &it.doubt;
            let views: Vec<String> = d
                .views
                .iter()
                .map(|(v, c)| format!("{v} {}", format_real(*c)))
                .collect();
            vec![
                d.plant.clone(),
                d.start.clone(),
                "human".into(),
                String::new(),
                format_real(d.fused),
                crate::domain::timeline::whole_leaves(d.fit).to_string(),
                views.join(" "),
                d.why(),
                it.images.join(";"),
            ]
        })
        .collect()
}

/// Writes the sheet to `out` (renamed into place whole); returns its rows.
pub fn write(out: &Path, items: &[Item]) -> anyhow::Result<usize> {
    write_csv(out, |w| {
        w.write_record(COLUMNS)?;
        let rows = rows(items);
        for r in &rows {
            w.write_record(r)?;
        }
        Ok(rows.len())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::names::{ParsedName, View};
    use crate::domain::timeline::TimelineParams;
    use crate::store::{CountRecord, FileFacts, Outcome};

    #[test]
    fn a_session_in_doubt_comes_with_its_images_and_a_filled_sheet_imports() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = Store::open(&dir.path().join("db.sqlite"), &TimelineParams::default(), 3).unwrap();
        let start = chrono::NaiveDate::from_ymd_opt(2026, 11, 1)
            .unwrap()
            .and_hms_opt(8, 0, 0)
            .unwrap();
        // Day 1 reads 8 between a 6 and two 7s: the fit overrules it.
        for (day, counts) in [[6, 6, 6], [8, 8, 7], [7, 7, 7], [7, 7, 7]].iter().enumerate() {
            for (v, &n) in counts.iter().enumerate() {
                let rel = format!("P1/day{day}/SV_{}.png", v * 72);
                let facts = FileFacts {
                    rel: rel.clone(),
                    size: 1,
                    mtime: None,
                    sha256: crate::files::sha256_hex(rel.as_bytes()),
                };
                let name = ParsedName {
                    plant: "P1".into(),
                    taken_at: start
                        + chrono::Duration::days(day as i64)
                        + chrono::Duration::seconds(v as i64),
                    view: View::Side(v as u16 * 72),
                    pattern: "test".into(),
                };
                let count = CountRecord {
                    leaf_count: n,
                    instances: serde_json::json!([]),
                    timing: serde_json::json!({}),
                    ms_total: 1.0,
                    model_id: "test".into(),
                    settings: serde_json::json!({}),
                };
                store.record(&facts, Outcome::Counted(&name, &count)).unwrap();
            }
        }
        let ranked = crate::domain::review::rank(&store.plant_timelines().unwrap(), None);
        let got = items(&store, &ranked, 1).unwrap();
        assert_eq!(got[0].doubt.start, "2026-11-02T08:00:00.000");
        assert_eq!(
            got[0].images,
            ["P1/day1/SV_0.png", "P1/day1/SV_72.png", "P1/day1/SV_144.png"]
        );
        let sheet = dir.path().join("review.csv");
        assert_eq!(write(&sheet, &got).unwrap(), 1);
        let read = crate::ops::import_csv::read_rows(&sheet).unwrap();
        assert_eq!((read.rows.len(), read.skipped), (0, 1), "nothing filled in yet");
        let filled = std::fs::read_to_string(&sheet)
            .unwrap()
            .replacen(",human,,", ",human,7,", 1);
        std::fs::write(&sheet, filled).unwrap();
        let read = crate::ops::import_csv::read_rows(&sheet).unwrap();
        assert_eq!(read.skipped, 0);
        assert_eq!(read.rows[0].0, "P1");
        assert_eq!((read.rows[0].2.is_person(), read.rows[0].3), (true, 7));
    }
}
