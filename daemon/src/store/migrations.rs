//! Versioned schema migrations, tracked in `PRAGMA user_version`.
//!
//! Migrations are append-only: a released step is never edited, a change is a
//! new step. Each step runs in its own transaction together with the version
//! bump, so a crash leaves the database at a well-defined version.

use anyhow::{bail, Context};
use rusqlite::Connection;

/// The schema steps; step *i* brings the database from version *i* to *i + 1*.
pub const MIGRATIONS: &[&str] = &[
    // 1: the initial schema.
    r#"
CREATE TABLE plants (
    id            INTEGER PRIMARY KEY,
    name          TEXT NOT NULL UNIQUE,
    first_seen    TEXT NOT NULL,              -- ISO 8601, when phyllo first saw it
    sessions      INTEGER NOT NULL DEFAULT 0,
    last_taken_at TEXT,
    leaves_emerged REAL,                      -- latest value of the non-decreasing fit
    living        REAL,                       -- latest smoothed living-leaf count
    phyllochron_days REAL,                    -- days per leaf; NULL with < 2 events
    updated_at    TEXT
);

-- One row per version of a file in the drop directory.
CREATE TABLE images (
    id           INTEGER PRIMARY KEY,
    path         TEXT NOT NULL,               -- relative to drop_dir, '/' separators
    version      INTEGER NOT NULL,            -- 1, 2, ... when the content at path changes
    size         INTEGER NOT NULL,
    mtime        TEXT,                        -- file mtime, to skip rehashing on rescans
    sha256       TEXT NOT NULL,               -- content hash (hex)
    plant_id     INTEGER REFERENCES plants(id),
    taken_at     TEXT,                        -- from the file name, facility local time
    view         TEXT,                        -- SV_<angle> | TV_<angle>
    state        TEXT NOT NULL CHECK (state IN ('counted', 'duplicate', 'failed')),
    error        TEXT,                        -- why it failed, naming the file
    attempts     INTEGER NOT NULL DEFAULT 0,
    retry        INTEGER NOT NULL DEFAULT 0,  -- 1 if the failure may be transient
    duplicate_of INTEGER REFERENCES images(id),
    superseded   INTEGER NOT NULL DEFAULT 0,  -- 1 once a newer version of path exists
    first_seen   TEXT NOT NULL,
    updated_at   TEXT NOT NULL,
    UNIQUE (path, version)
);
CREATE INDEX images_sha256 ON images(sha256);
CREATE INDEX images_state ON images(state);

-- One count per image (or per imported row).
CREATE TABLE observations (
    id          INTEGER PRIMARY KEY,
    image_id    INTEGER UNIQUE REFERENCES images(id),   -- NULL for imported counts
    plant_id    INTEGER NOT NULL REFERENCES plants(id),
    taken_at    TEXT NOT NULL,
    view        TEXT NOT NULL,
    leaf_count  INTEGER NOT NULL,
    instances   TEXT,                         -- JSON: per-instance summary
    model_id    TEXT NOT NULL,                -- model that counted, or 'import:<file>'
    timing      TEXT,                         -- JSON: per-stage milliseconds
    ms_total    REAL,
    created_at  TEXT NOT NULL
);
CREATE INDEX observations_plant ON observations(plant_id, taken_at);
CREATE UNIQUE INDEX observations_import ON observations(plant_id, taken_at, view, model_id)
    WHERE image_id IS NULL;

-- Per plant and imaging session: fused count and fits. Rewritten per plant.
CREATE TABLE sessions (
    plant_id    INTEGER NOT NULL REFERENCES plants(id),
    start       TEXT NOT NULL,                -- first image of the session
    views       TEXT NOT NULL,                -- JSON {"SV_0": 9, ...}
    n_counts    INTEGER NOT NULL,
    fused       REAL NOT NULL,
    fusion_rule TEXT NOT NULL,
    leaves_emerged REAL NOT NULL,
    living      REAL NOT NULL,
    PRIMARY KEY (plant_id, start)
) WITHOUT ROWID;

-- Leaf emergence events. Rewritten per plant.
CREATE TABLE events (
    plant_id   INTEGER NOT NULL REFERENCES plants(id),
    leaf       INTEGER NOT NULL,
    emerged_at TEXT NOT NULL,
    seen_at    TEXT NOT NULL,                 -- first session the leaf was counted at
    PRIMARY KEY (plant_id, leaf)
) WITHOUT ROWID;

-- Append-only feed for `phyllo tail` (another process polls it).
CREATE TABLE feed (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    at         TEXT NOT NULL,
    kind       TEXT NOT NULL,                 -- count | import | event | duplicate | failed
    plant      TEXT,
    taken_at   TEXT,
    view       TEXT,
    leaf_count INTEGER,
    fused      REAL,
    leaves_emerged REAL,
    new_leaves TEXT,                          -- JSON list of leaf numbers
    path       TEXT,
    message    TEXT
);

-- What the running service reports about itself (for `phyllo status`).
CREATE TABLE service (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
) WITHOUT ROWID;
"#,
    // 2: the settings each count was made with. A pipeline change (a new
    // post-processing stage, say) moves counts under the same model, and a
    // timeline must be able to tell. NULL for imports and older rows.
    r#"
ALTER TABLE observations ADD COLUMN settings TEXT;  -- JSON: zoom and post-processing
"#,
    // 3: leaves read as dead, and the timeline settings the fits were made
    // with, so a store opened with other settings refits every plant.
    r#"
ALTER TABLE sessions ADD COLUMN leaves_lost REAL NOT NULL DEFAULT 0;
CREATE TABLE meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
) WITHOUT ROWID;
"#,
    // 4: the imports this database holds, by their entry in the import
    // journal, so a restored snapshot knows which later imports to take again.
    r#"
CREATE TABLE imports (
    journal     TEXT PRIMARY KEY,             -- the entry under <state>/imports/
    source      TEXT NOT NULL,                -- the CSV's file name
    rows        INTEGER NOT NULL,
    plants      INTEGER NOT NULL,
    imported_at TEXT NOT NULL                 -- ISO 8601, UTC
) WITHOUT ROWID;
"#,
    // 5: the greenhouse's air temperature, and each plant's phyllochron in
    // degree-days per leaf above `[timeline] base_temp_c`.
    r#"
CREATE TABLE climate (
    taken_at TEXT PRIMARY KEY,                -- facility local time, ISO 8601
    temp_c   REAL NOT NULL,
    source   TEXT NOT NULL                    -- the CSV it came from
) WITHOUT ROWID;
ALTER TABLE plants ADD COLUMN phyllochron_cd REAL;  -- °Cd per leaf; NULL without a log covering its leaves
"#,
    // 6: where each new leaf emerged (crate::domain::leaf_site): the leaf instance, in
    // the session that first counted it, taken for the new leaf.
    r#"
ALTER TABLE events ADD COLUMN site_view TEXT;    -- the view it was found in; NULL without images' instances
ALTER TABLE events ADD COLUMN site_image TEXT;   -- that image, relative to drop_dir
ALTER TABLE events ADD COLUMN site_x REAL;       -- the leaf instance's predicted centre, image pixels
ALTER TABLE events ADD COLUMN site_y REAL;
ALTER TABLE events ADD COLUMN site_bbox TEXT;    -- JSON [x0, y0, x1, y1]
ALTER TABLE events ADD COLUMN site_area INTEGER; -- its area, image pixels
"#,
    // 7: greenhouse compartments (crate::domain::climate_zone), each with its own
    // temperature log; '' is the facility's log, which every earlier reading was.
    r#"
CREATE TABLE climate_zoned (
    zone     TEXT NOT NULL DEFAULT '',        -- [[timeline.zones]] name; '' = the facility's log
    taken_at TEXT NOT NULL,                   -- facility local time, ISO 8601
    temp_c   REAL NOT NULL,
    source   TEXT NOT NULL,                   -- the CSV it came from
    PRIMARY KEY (zone, taken_at)
) WITHOUT ROWID;
INSERT INTO climate_zoned (zone, taken_at, temp_c, source) SELECT '', taken_at, temp_c, source FROM climate;
DROP TABLE climate;
ALTER TABLE climate_zoned RENAME TO climate;
ALTER TABLE plants ADD COLUMN climate_zone TEXT;  -- the zone whose log timed phyllochron_cd; '' = the facility's
-- Images moved to another plant by an `image,plant` sheet (crate::store::reassign),
-- kept so `phyllo import --undo SHEET` moves them back.
CREATE TABLE reassignments (
    id            INTEGER PRIMARY KEY,
    image_id      INTEGER NOT NULL REFERENCES images(id),
    from_plant_id INTEGER REFERENCES plants(id),
    to_plant_id   INTEGER NOT NULL REFERENCES plants(id),
    source        TEXT NOT NULL,                -- the sheet's file name
    moved_at      TEXT NOT NULL                 -- ISO 8601, UTC
);
CREATE INDEX reassignments_source ON reassignments(source);
ALTER TABLE plants ADD COLUMN next_leaf INTEGER;     -- crate::domain::forecast: the leaf that comes next
ALTER TABLE plants ADD COLUMN next_leaf_at TEXT;     -- and when it should appear (facility local time)
"#,
];

/// The schema version this build writes (`PRAGMA user_version` after [`migrate`]).
pub const SCHEMA_VERSION: usize = MIGRATIONS.len();

/// Brings the database to the newest schema version.
pub fn migrate(conn: &mut Connection) -> anyhow::Result<()> {
    let current: usize = conn.pragma_query_value(None, "user_version", |r| r.get::<_, i64>(0))? as usize;
    if current > MIGRATIONS.len() {
        bail!(
            "database schema version {current} is newer than this phyllo knows ({}); upgrade phyllo",
            MIGRATIONS.len()
        );
    }
    for (i, sql) in MIGRATIONS.iter().enumerate().skip(current) {
        let tx = conn.transaction()?;
        tx.execute_batch(sql)
            .with_context(|| format!("schema migration {}", i + 1))?;
        tx.pragma_update(None, "user_version", (i + 1) as i64)?;
        tx.commit()?;
    }
    Ok(())
}

/// Fails unless the database is at exactly the version this phyllo writes.
pub fn check_version(conn: &Connection) -> anyhow::Result<()> {
    let v: i64 = conn.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if v as usize != MIGRATIONS.len() {
        bail!(
            "database schema version {v}, this phyllo expects {} (has `phyllo serve` run on it?)",
            MIGRATIONS.len()
        );
    }
    Ok(())
}
