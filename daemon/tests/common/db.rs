//! Reading a test site's database.

use std::path::Path;

use rusqlite::{Connection, OpenFlags};

/// The database at `db`, read-only, as `phyllo status` reads it: tests
/// inspect a database with their own SQL, the store hands out no connection.
pub fn open(db: &Path) -> rusqlite::Result<Connection> {
    let conn = Connection::open_with_flags(
        db,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )?;
    conn.busy_timeout(std::time::Duration::from_secs(10))?;
    Ok(conn)
}

/// One integer from the database at `db` (-1 if it cannot be read).
pub fn q(db: &Path, sql: &str) -> i64 {
    let Ok(s) = open(db) else {
        return -1;
    };
    s.query_row(sql, [], |r| r.get(0)).unwrap_or(-1)
}

/// One text value from the database.
pub fn qs(db: &Path, sql: &str) -> String {
    let s = open(db).unwrap();
    s.query_row(sql, [], |r| r.get::<_, String>(0))
        .unwrap_or_else(|e| panic!("{sql}: {e}"))
}

/// All rows of a query, each row's columns joined with `|` (NULL as `∅`).
pub fn rows(db: &Path, sql: &str) -> Vec<String> {
    let s = open(db).unwrap();
    let mut st = s.prepare(sql).unwrap();
    let n = st.column_count();
    st.query_map([], |r| {
        let mut cols = Vec::with_capacity(n);
        for i in 0..n {
            use rusqlite::types::ValueRef;
            cols.push(match r.get_ref(i)? {
                ValueRef::Null => "∅".to_string(),
                ValueRef::Integer(v) => v.to_string(),
                ValueRef::Real(v) => format!("{v:.6}"),
                ValueRef::Text(t) | ValueRef::Blob(t) => String::from_utf8_lossy(t).into_owned(),
            });
        }
        Ok(cols.join("|"))
    })
    .unwrap()
    .map(Result::unwrap)
    .collect()
}

/// Timelines as comparable rows: sessions, plants and events per plant name.
pub fn timelines(db: &Path) -> Vec<String> {
    let mut out = rows(
        db,
        "SELECT 'session', p.name, s.start, s.views, s.n_counts, s.fused, s.leaves_emerged, s.living
         FROM sessions s JOIN plants p ON p.id = s.plant_id ORDER BY p.name, s.start",
    );
    out.extend(rows(
        db,
        "SELECT 'plant', name, sessions, last_taken_at, leaves_emerged, living, phyllochron_days
         FROM plants ORDER BY name",
    ));
    out.extend(rows(
        db,
        "SELECT 'event', p.name, e.leaf, e.emerged_at, e.seen_at FROM events e
         JOIN plants p ON p.id = e.plant_id ORDER BY p.name, e.leaf",
    ));
    out
}

/// `PRAGMA integrity_check` of the database.
pub fn integrity(db: &Path) -> String {
    qs(db, "PRAGMA integrity_check")
}
