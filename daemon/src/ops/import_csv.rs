//! Import files: what a CSV holds (counts, a temperature log, a sheet of
//! images to move), read and checked with errors naming the file, line and
//! problem, and one journal entry taken into the store.

use anyhow::{bail, Context};
use chrono::{NaiveDate, NaiveDateTime};

use crate::domain::names::View;
use crate::ops::import_journal;
use crate::store::{Reading, Store};

/// What an import CSV holds, told by its columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// Leaf counts: `plant,timestamp,view,leaf_count`.
    Counts,
    /// Air temperatures: `timestamp,temp_c`.
    Climate,
    /// Images moved to another plant: `image,plant` ([`crate::store`]'s reassign).
    Reassign,
}

/// Reads the header of `path`: a `temp_c` column without a `leaf_count`
/// makes a temperature log, `image` and `plant` without one a sheet of
/// images to move, anything else is read as counts.
pub fn kind(path: &std::path::Path) -> anyhow::Result<Kind> {
    let (_, headers) = open_csv(path)?;
    let has = |name: &str| headers.iter().any(|h| h.eq_ignore_ascii_case(name));
    Ok(if has("temp_c") && !has("leaf_count") {
        Kind::Climate
    } else if has("image") && has("plant") && !has("leaf_count") {
        Kind::Reassign
    } else {
        Kind::Counts
    })
}

/// Imports one journal entry into `store`; says what it brought in.
pub fn take(store: &mut Store, entry: &import_journal::Entry) -> anyhow::Result<String> {
    match kind(&entry.file)? {
        Kind::Counts => {
            let sheet = read_rows(&entry.file)?;
            let (n, plants) = store.import(&entry.source(), &sheet.rows, Some(&entry.id))?;
            Ok(format!("{n} counts for {plants} plants"))
        }
        Kind::Reassign => {
            let moves = read_moves(&entry.file)?;
            let (images, plants) = store
                .reassign(&entry.source(), &moves, Some(&entry.id))
                .with_context(|| format!("{}", entry.file.display()))?;
            Ok(format!("{images} image moves ({plants} plants refitted)"))
        }
        Kind::Climate => {
            let readings = read_climate(&entry.file, store.zone_rules())?;
            let with = store.import_climate(&entry.source(), &readings, Some(&entry.id))?;
            let zones: std::collections::BTreeSet<&str> = readings.iter().map(|r| r.zone.as_str()).collect();
            let named: Vec<&str> = zones.into_iter().filter(|z| !z.is_empty()).collect();
            Ok(format!(
                "{} temperatures{} ({with} plants with a phyllochron in degree-days)",
                readings.len(),
                if named.is_empty() {
                    String::new()
                } else {
                    format!(" for zones {}", named.join(", "))
                }
            ))
        }
    }
}

/// Reads and validates a temperature log (`timestamp,temp_c`, an optional
/// `zone`, other columns ignored); errors name the file, line and problem.
/// A zone must be one of `zones`: a misspelt one would time no plant.
pub fn read_climate(
    path: &std::path::Path,
    zones: &crate::domain::climate_zone::ZoneRules,
) -> anyhow::Result<Vec<Reading>> {
    let (mut rdr, headers) = open_csv(path)?;
    let col = |name: &str| headers.iter().position(|h| h.eq_ignore_ascii_case(name));
    let (Some(ct), Some(cc)) = (col("timestamp"), col("temp_c")) else {
        bail!(
            "{}: a temperature log needs timestamp,temp_c columns (have {:?})",
            path.display(),
            headers
        );
    };
    let cz = col("zone");
    let mut out = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        let rec = restored(rec.with_context(|| format!("{}:{line}", path.display()))?);
        let ts = rec.get(ct).unwrap_or("");
        let taken_at =
            parse_timestamp(ts).with_context(|| format!("{}:{line}: timestamp '{ts}'", path.display()))?;
        let c = rec.get(cc).unwrap_or("");
        let temp: f64 = c
            .parse()
            .with_context(|| format!("{}:{line}: temp_c '{c}' is not a number", path.display()))?;
        if !(-40.0..=60.0).contains(&temp) {
            bail!(
                "{}:{line}: temp_c {temp} is not a greenhouse air temperature (°C, -40 to 60)",
                path.display()
            );
        }
        let zone = cz.and_then(|z| rec.get(z)).unwrap_or("").to_string();
        if !zones.knows(&zone) {
            let declared = zones.names();
            bail!(
                "{}:{line}: zone '{zone}' is not declared in the config's [[timeline.zones]] ({})",
                path.display(),
                if declared.is_empty() {
                    "it declares none".to_string()
                } else {
                    format!("it declares {}", declared.join(", "))
                }
            );
        }
        out.push(Reading {
            zone,
            taken_at,
            temp_c: temp,
        });
    }
    Ok(out)
}

/// Reads a sheet of images to move (`image,plant`: the image's path as
/// `images.csv` gives it, the plant it belongs to); errors name the file,
/// line and problem.
pub fn read_moves(path: &std::path::Path) -> anyhow::Result<Vec<(String, String)>> {
    let (mut rdr, headers) = open_csv(path)?;
    let col = |name: &str| headers.iter().position(|h| h.eq_ignore_ascii_case(name));
    let (Some(ci), Some(cp)) = (col("image"), col("plant")) else {
        bail!(
            "{}: a sheet of images to move needs image,plant columns",
            path.display()
        );
    };
    let mut out = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        let rec = restored(rec.with_context(|| format!("{}:{line}", path.display()))?);
        let (image, plant) = (rec.get(ci).unwrap_or(""), rec.get(cp).unwrap_or(""));
        if image.is_empty() || plant.is_empty() {
            bail!(
                "{}:{line}: an image and the plant it belongs to are both needed",
                path.display()
            );
        }
        check_text(path, line, "plant id", plant)?;
        out.push((image.to_string(), plant.to_string()));
    }
    Ok(out)
}

/// Refuses a cell with control characters (a quoted newline or ESC would
/// forge a line in `tail`, the logs and the exports) or the `\x` that marks
/// an escaped byte, as file names are refused ([`crate::domain::names`]).
fn check_text(path: &std::path::Path, line: usize, what: &str, text: &str) -> anyhow::Result<()> {
    if text.chars().any(char::is_control) || text.contains("\\x") {
        bail!(
            "{}:{line}: {what} {} has control characters",
            path.display(),
            crate::domain::names::printable(text)
        );
    }
    Ok(())
}

/// Opens an import CSV (fields trimmed) and reads its header row.
fn open_csv(path: &std::path::Path) -> anyhow::Result<(csv::Reader<std::fs::File>, csv::StringRecord)> {
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("reading {}", path.display()))?;
    let headers = rdr
        .headers()
        .with_context(|| format!("{}: header row", path.display()))?
        .clone();
    Ok((rdr, headers))
}

/// A record with the `'` that phyllo's exports put before formula-like text
/// taken off ([`crate::files::csv_cell`]): a sheet reads back as written.
fn restored(rec: csv::StringRecord) -> csv::StringRecord {
    rec.iter().map(crate::files::csv_cell::restore).collect()
}

/// Reads and validates the CSV; errors name the file, line and problem.
pub fn read_rows(path: &std::path::Path) -> anyhow::Result<Sheet> {
    let (mut rdr, headers) = open_csv(path)?;
    let col = |name: &str| -> anyhow::Result<usize> {
        headers
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
            .with_context(|| {
                format!(
                    "{}: no '{name}' column (need plant,timestamp,view,leaf_count; have {:?})",
                    path.display(),
                    headers
                )
            })
    };
    let (cp, ct, cv, cc) = (col("plant")?, col("timestamp")?, col("view")?, col("leaf_count")?);
    let mut rows = Vec::new();
    let mut skipped = 0;
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        let rec = restored(rec.with_context(|| format!("{}:{line}", path.display()))?);
        let field = |c: usize| rec.get(c).unwrap_or("").to_string();
        let plant = field(cp);
        if plant.is_empty() {
            bail!("{}:{line}: empty plant", path.display());
        }
        check_text(path, line, "plant id", &plant)?;
        let ts = field(ct);
        let taken_at =
            parse_timestamp(&ts).with_context(|| format!("{}:{line}: timestamp '{ts}'", path.display()))?;
        let view = field(cv);
        if view.is_empty() {
            bail!("{}:{line}: empty view", path.display());
        }
        check_text(path, line, "view", &view)?;
        let count = field(cc);
        if count.is_empty() {
            // A review sheet's session nobody counted.
            skipped += 1;
            continue;
        }
        let count: u32 = count
            .parse()
            .with_context(|| format!("{}:{line}: leaf_count '{count}' is not a count", path.display()))?;
        if count > crate::domain::timeline::MAX_COUNT {
            bail!(
                "{}:{line}: leaf_count {count} is not a plausible leaf count (at most {})",
                path.display(),
                crate::domain::timeline::MAX_COUNT
            );
        }
        rows.push((plant, taken_at, View::parse(&view), count));
    }
    Ok(Sheet { rows, skipped })
}

/// The rows of an import CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct Sheet {
    /// (plant, taken at, view, leaf count), one per row with a count.
    pub rows: Vec<(String, NaiveDateTime, View, u32)>,
    /// Rows with an empty `leaf_count` (a review sheet's sessions nobody counted).
    pub skipped: usize,
}

/// A `--since` bound as stored (ISO 8601): any form [`parse_timestamp`]
/// accepts, a bare date meaning from the start of that day.
pub fn parse_since(s: &str) -> anyhow::Result<String> {
    let t = parse_timestamp(s)?;
    let t = if s.trim().len() == 10 {
        t.date().and_hms_opt(0, 0, 0).expect("midnight exists")
    } else {
        t
    };
    Ok(crate::store::iso(t))
}

/// Parses the timestamp forms `phyllo import` accepts.
pub fn parse_timestamp(s: &str) -> anyhow::Result<NaiveDateTime> {
    if let Ok(t) = chrono::DateTime::parse_from_rfc3339(s) {
        // An explicit offset: keep the wall-clock time, as file names carry no offset.
        return Ok(t.naive_local());
    }
    for f in [
        "%Y-%m-%dT%H:%M:%S%.f",
        "%Y-%m-%d %H:%M:%S%.f",
        "%Y-%m-%dT%H:%M",
        "%Y-%m-%d %H:%M",
        "%Y-%m-%d_%H-%M-%S%.f",
    ] {
        if let Ok(t) = NaiveDateTime::parse_from_str(s, f) {
            return Ok(t);
        }
    }
    let d = NaiveDate::parse_from_str(s, "%Y-%m-%d").context("expected ISO 8601 date or date-time")?;
    Ok(d.and_hms_opt(12, 0, 0).expect("noon exists"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps() {
        let want = NaiveDate::from_ymd_opt(2018, 4, 20)
            .unwrap()
            .and_hms_opt(10, 32, 16)
            .unwrap();
        for s in [
            "2018-04-20T10:32:16",
            "2018-04-20 10:32:16",
            "2018-04-20T10:32:16+02:00",
            "2018-04-20_10-32-16",
        ] {
            assert_eq!(parse_timestamp(s).unwrap(), want, "{s}");
        }
        assert_eq!(
            parse_timestamp("2018-04-20").unwrap().format("%H").to_string(),
            "12"
        );
        assert!(parse_timestamp("20/04/2018").is_err());
    }

    #[test]
    fn bad_rows_name_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("obs.csv");
        std::fs::write(
            &p,
            "plant,timestamp,view,leaf_count\nP1,2018-04-20,SV_108,9\nP1,2018-04-21,SV_108,nine\n",
        )
        .unwrap();
        let err = format!("{:#}", read_rows(&p).unwrap_err());
        assert!(err.contains("obs.csv:3") && err.contains("nine"), "{err}");
        std::fs::write(&p, "plant,time,view,leaf_count\n").unwrap();
        let err = format!("{:#}", read_rows(&p).unwrap_err());
        assert!(err.contains("no 'timestamp' column"), "{err}");
        std::fs::write(
            &p,
            "plant,timestamp,view,leaf_count\nP1,2018-04-20,SV_108,4000000000\n",
        )
        .unwrap();
        let err = format!("{:#}", read_rows(&p).unwrap_err());
        assert!(
            err.contains("obs.csv:2") && err.contains("not a plausible leaf count"),
            "{err}"
        );
    }

    /// Issue 57, item 8: a quoted cell with a newline or ESC must not reach
    /// the live feed as a forged line or a raw escape.
    #[test]
    fn control_characters_in_imported_ids_are_refused_and_shown_escaped() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("obs.csv");
        let sheets = [
            "plant,timestamp,view,leaf_count\nP1,2018-04-20,SV_108,9\n\"EVIL\nforged\",2018-04-20,SV_108,9\n",
            "plant,timestamp,view,leaf_count\n\"P\u{1b}[31mRED\",2018-04-20,SV_108,9\n",
            "plant,timestamp,view,leaf_count\nP1,2018-04-20,\"SV\n108\",9\n",
        ];
        for sheet in sheets {
            std::fs::write(&p, sheet).unwrap();
            let err = format!("{:#}", read_rows(&p).unwrap_err());
            assert!(err.contains("control characters"), "{err}");
            assert!(
                !err.chars().any(char::is_control),
                "the message itself is escaped: {err:?}"
            );
        }
        std::fs::write(&p, "image,plant\nimg.png,\"EVIL\nforged\"\n").unwrap();
        let err = format!("{:#}", read_moves(&p).unwrap_err());
        assert!(
            err.contains("obs.csv:2") && err.contains("control characters"),
            "{err}"
        );
    }

    /// Issue 57, item 9: a sheet phyllo wrote (formula-like text prefixed
    /// with `'`) reads back as it was before it was written.
    #[test]
    fn a_neutralised_cell_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("review.csv");
        crate::sinks::export::write_csv(&p, |w| {
            w.write_record(["plant", "timestamp", "view", "leaf_count"])?;
            w.write_record(["=HYPERLINK(\"http://x\")", "2018-04-20", "SV_108", "9"])?;
            w.write_record(["-P2", "2018-04-20", "SV_108", "8"])?;
            Ok(2)
        })
        .unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(
            text.contains("\"'=HYPERLINK(\"\"http://x\"\")\",") && text.contains("'-P2,"),
            "{text}"
        );
        let plants: Vec<String> = read_rows(&p).unwrap().rows.into_iter().map(|r| r.0).collect();
        assert_eq!(plants, ["=HYPERLINK(\"http://x\")", "-P2"]);
    }
}
