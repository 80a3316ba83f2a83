//! The service's own health, checked on every status tick: the database it
//! writes is still the file it opened (deleted, the service would count into
//! an unlinked file and a restart would start empty; replaced, it would write
//! to the old one), and every worker thread is alive. A failure stops the
//! service with an error and a non-zero exit, which systemd sees and restarts.

use std::sync::atomic::Ordering;

use super::job::Stats;
use crate::files::identity::DatabaseIdentity;

/// Exit status of a service stopped by a failed health check.
pub const EXIT_UNHEALTHY: i32 = 3;

/// Why the service must stop, if it must: the database changed under it or
/// a worker thread died.
pub fn unhealthy(db: &DatabaseIdentity, stats: &Stats) -> Option<String> {
    if let Some(why) = db.changed() {
        return Some(why);
    }
    let dead = stats.dead_workers.load(Ordering::SeqCst);
    (dead > 0).then(|| format!("{dead} worker thread(s) died"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_deleted_or_replaced_database_and_a_dead_worker_are_noticed() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("phyllo.sqlite");
        std::fs::write(&db, b"x").unwrap();
        let id = DatabaseIdentity::of(&db).unwrap();
        let stats = Stats::default();
        assert_eq!(unhealthy(&id, &stats), None);
        stats.dead_workers.store(1, Ordering::SeqCst);
        assert_eq!(unhealthy(&id, &stats).as_deref(), Some("1 worker thread(s) died"));
        stats.dead_workers.store(0, Ordering::SeqCst);
        // Replaced: a new file under the same name (another inode).
        let other = dir.path().join("restored.sqlite");
        std::fs::write(&other, b"y").unwrap();
        std::fs::rename(&other, &db).unwrap();
        assert!(unhealthy(&id, &stats).unwrap().contains("deleted or replaced"));
        std::fs::remove_file(&db).unwrap();
        assert!(unhealthy(&id, &stats).unwrap().contains("was deleted"));
    }
}
