//! `phyllo export`: RFC 4180 CSV with a header row and ISO 8601 times,
//! written to a temporary file beside the target and renamed into place, so a
//! reader never sees half a file.

use std::path::Path;

pub use crate::store::exports::KINDS;
use crate::store::exports::{check_kind, Cell, ExportLine};
use crate::store::Store;

/// Writes one export kind to `out` atomically. Returns the number of rows.
pub fn export(store: &Store, kind: &str, since: Option<&str>, out: &Path) -> anyhow::Result<usize> {
    check_kind(kind)?;
    write_csv(out, |w| {
        store.export_rows(kind, since, |line| {
            match line {
                ExportLine::Header(names) => w.write_record(names)?,
                ExportLine::Row(cells) => w.write_record(cells.iter().map(cell_text))?,
            }
            Ok(())
        })
    })
}

/// One export kind in memory, as its CSV would hold it: (header, rows).
/// For small kinds (`plants`); the others stream through [`export`].
pub fn table(store: &Store, kind: &str) -> anyhow::Result<(Vec<String>, Vec<Vec<String>>)> {
    let (mut header, mut rows) = (Vec::new(), Vec::new());
    store.export_rows(kind, None, |line| {
        match line {
            ExportLine::Header(names) => header = names.to_vec(),
            ExportLine::Row(cells) => rows.push(cells.iter().map(cell_text).collect()),
        }
        Ok(())
    })?;
    Ok((header, rows))
}

/// A cell as CSV text: NULL empty, reals compact.
fn cell_text(cell: &Cell) -> String {
    match cell {
        Cell::Null => String::new(),
        Cell::Integer(v) => v.to_string(),
        Cell::Real(v) => format_real(*v),
        Cell::Text(t) => t.clone(),
    }
}

/// The CSV writer [`write_csv`] hands out: every field goes through
/// [`crate::files::csv_cell::neutralise`], so no CSV a person opens runs a
/// formula from a plant id, a note or a path.
pub struct CsvOut(csv::Writer<std::fs::File>);

impl CsvOut {
    /// Writes one record.
    pub fn write_record<I, T>(&mut self, record: I) -> csv::Result<()>
    where
        I: IntoIterator<Item = T>,
        T: AsRef<str>,
    {
        // Field by field, so that a cell is copied only when it gains its `'`.
        for field in record {
            self.0
                .write_field(crate::files::csv_cell::neutralise(field.as_ref()).as_bytes())?;
        }
        self.0.write_record(None::<&[u8]>)
    }
}

/// Writes a CSV (CRLF, as RFC 4180) and renames it into place
/// ([`crate::files::atomic::replace`]); `fill` writes the records and returns the
/// number of rows. On any error `out` is left as it was.
pub fn write_csv(
    out: &Path,
    fill: impl FnOnce(&mut CsvOut) -> anyhow::Result<usize>,
) -> anyhow::Result<usize> {
    crate::files::atomic::replace(out, ".csv", |tmp| {
        let mut w = CsvOut(
            csv::WriterBuilder::new()
                .terminator(csv::Terminator::CRLF)
                .from_path(tmp)?,
        );
        let n = fill(&mut w)?;
        w.0.flush()?;
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
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("db.sqlite"), &Default::default(), 3).unwrap();
        let err = export(&store, "leaves", None, &dir.path().join("x.csv")).unwrap_err();
        assert!(
            err.to_string()
                .contains("images, sessions, timeline, events, plants"),
            "{err}"
        );
        assert!(!dir.path().join("x.csv").exists());
    }
}
