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

/// The live database as a backup sees it: the three queries a snapshot
/// needs, so the backup never holds the store's connection.
pub struct Source<'a>(&'a Connection);

impl super::Store {
    /// The live database, for a snapshot ([`crate::ops::backup::snapshot`]).
    pub fn snapshot_source(&self) -> Source<'_> {
        Source(&self.conn)
    }
}

/// A database opened by a test with its own SQL (any schema version).
#[cfg(test)]
impl<'a> From<&'a Connection> for Source<'a> {
    fn from(conn: &'a Connection) -> Self {
        Source(conn)
    }
}

impl Source<'_> {
    /// Bytes the live pages take: about what a copy will.
    pub fn live_bytes(&self) -> anyhow::Result<u64> {
        Ok(self.0.query_row(
            "SELECT page_count * page_size FROM pragma_page_count(), pragma_page_size()",
            [],
            |r| r.get::<_, i64>(0),
        )? as u64)
    }

    /// Copies the database, compacted and self-contained, into the new file `path`.
    pub fn copy_into(&self, path: &str) -> anyhow::Result<()> {
        self.0.execute("VACUUM INTO ?1", [path])?;
        Ok(())
    }

    /// The database's schema version (`PRAGMA user_version`).
    pub fn schema_version(&self) -> anyhow::Result<i64> {
        Ok(self.0.pragma_query_value(None, "user_version", |r| r.get(0))?)
    }
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
