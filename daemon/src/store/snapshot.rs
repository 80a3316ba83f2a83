//! The SQL side of `phyllo backup`: the live database's size, its copy by
//! `VACUUM INTO` (one read transaction, so the service keeps writing), and
//! the check of a copy. File names, retention and restoring are the backup
//! sink's ([`crate::ops::backup`]).

use std::path::Path;

use anyhow::{bail, Context};
use rusqlite::{Connection, OpenFlags};

/// What a new snapshot holds, read back from the copy itself.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Contents {
    /// Image versions recorded.
    pub images: i64,
    /// Plants with a timeline.
    pub plants: i64,
    /// Schema version (`PRAGMA user_version`).
    pub schema: i64,
}

/// Bytes the live pages take: about what a copy will.
pub fn live_bytes(conn: &Connection) -> anyhow::Result<u64> {
    Ok(conn.query_row(
        "SELECT page_count * page_size FROM pragma_page_count(), pragma_page_size()",
        [],
        |r| r.get::<_, i64>(0),
    )? as u64)
}

/// Copies the database, compacted and self-contained, into the new file `path`.
pub fn copy_into(conn: &Connection, path: &str) -> anyhow::Result<()> {
    conn.execute("VACUUM INTO ?1", [path])?;
    Ok(())
}

/// The database's schema version (`PRAGMA user_version`).
pub fn schema_version(conn: &Connection) -> anyhow::Result<i64> {
    Ok(conn.pragma_query_value(None, "user_version", |r| r.get(0))?)
}

/// Opens a snapshot read-only, runs SQLite's full integrity check and reads
/// what it holds. Also what an operator runs on a snapshot before restoring it.
pub fn check_file(path: &Path) -> anyhow::Result<Contents> {
    let conn = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY)
        .with_context(|| format!("opening snapshot {}", path.display()))?;
    let problems: Vec<String> = conn
        .prepare("PRAGMA integrity_check")?
        .query_map([], |r| r.get::<_, String>(0))?
        .collect::<Result<_, _>>()
        .with_context(|| format!("checking snapshot {}", path.display()))?;
    if problems != ["ok"] {
        bail!(
            "snapshot {} fails SQLite's integrity check: {}",
            path.display(),
            problems.join("; ")
        );
    }
    let one = |sql: &str| -> anyhow::Result<i64> {
        conn.query_row(sql, [], |r| r.get(0))
            .with_context(|| format!("reading snapshot {} ({sql})", path.display()))
    };
    Ok(Contents {
        images: one("SELECT COUNT(*) FROM images")?,
        plants: one("SELECT COUNT(*) FROM plants")?,
        schema: one("PRAGMA user_version")?,
    })
}
