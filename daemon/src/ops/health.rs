//! The service's health as an operator sees it: what `phyllo status --check`
//! weighs (the service's heartbeat, the drop directory, the disk, the nightly
//! snapshot and export, failures, temperature logs) and the rules that turn
//! it into findings and one monitoring line. `phyllo status` prints it and
//! the nightly export writes its line into the page.

use crate::config::Config;
use crate::files::identity::DatabaseIdentity;
use crate::store::Store;

/// How bad a finding of `--check` is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Worth a look.
    Warning,
    /// The service is not doing its job, or soon will not.
    Critical,
}

/// What `--check` weighs.
#[derive(Debug, Clone, Default)]
pub struct Health {
    /// The service's state as `phyllo status` prints it.
    pub state: String,
    /// Bytes free beside the database.
    pub free: Option<u64>,
    /// Hours since the newest snapshot (`None`: there is none).
    pub backup_age_hours: Option<i64>,
    /// Hours since the nightly export last wrote its page (`None`: never).
    pub export_age_hours: Option<i64>,
    /// Images that failed in the last 24 hours.
    pub failed_last_day: i64,
    /// Internal errors since the service started.
    pub internal_errors: i64,
    /// Temperature logs that end more than two days before their plants'
    /// newest session: (zone, hours behind).
    pub logs_behind: Vec<(String, f64)>,
    /// Hours since the newest image arrived (`None`: none yet).
    pub quiet_hours: Option<f64>,
    /// `[watch] quiet_hours`: longer without an image warns; 0 never.
    pub quiet_limit_hours: f64,
    /// What is wrong with the drop directory (missing, not a directory,
    /// unreadable), if anything.
    pub drop_dir_problem: Option<String>,
    /// The running service writes another file than the one at the
    /// database's path now (it was deleted or replaced under it).
    pub database_replaced: bool,
    /// Counted images whose bytes equal an earlier counted image's under
    /// another name (docs/daemon.md, "An image's identity").
    pub shared_bytes: i64,
}

/// The findings, worst first; none means OK.
pub fn findings(h: &Health) -> Vec<(Level, String)> {
    let mut out = Vec::new();
    if h.state != "running" {
        out.push((Level::Critical, format!("service {}", h.state)));
    }
    if let Some(p) = &h.drop_dir_problem {
        out.push((Level::Critical, p.clone()));
    }
    if h.database_replaced {
        out.push((
            Level::Critical,
            "the database is not the file the service opened (deleted or replaced under it)".into(),
        ));
    }
    if h.shared_bytes > 0 {
        out.push((
            Level::Warning,
            format!(
                "{} {} the bytes of another counted image under another name (copied or renamed?)",
                h.shared_bytes,
                if h.shared_bytes == 1 {
                    "image has"
                } else {
                    "images have"
                }
            ),
        ));
    }
    match h.free {
        Some(f) if f < crate::files::disk::SNAPSHOT_RESERVE_BYTES => out.push((
            Level::Critical,
            format!("{} free beside the database", crate::files::disk::human(f)),
        )),
        Some(f) if f < crate::files::disk::LOW_FREE_BYTES => out.push((
            Level::Warning,
            format!("{} free beside the database", crate::files::disk::human(f)),
        )),
        _ => {}
    }
    match h.backup_age_hours {
        None => out.push((Level::Warning, "no database snapshot".into())),
        Some(a) if a > STALE_NIGHTLY_HOURS => {
            out.push((Level::Warning, format!("newest snapshot {a} h old")))
        }
        _ => {}
    }
    match h.export_age_hours {
        None => out.push((Level::Warning, "no nightly export yet".into())),
        Some(a) if a > STALE_NIGHTLY_HOURS => out.push((Level::Warning, format!("nightly export {a} h old"))),
        _ => {}
    }
    if h.failed_last_day > 0 {
        out.push((
            Level::Warning,
            format!(
                "{} failed in the last 24 h",
                count(h.failed_last_day, "image", "images")
            ),
        ));
    }
    if h.internal_errors > 0 {
        out.push((
            Level::Warning,
            format!(
                "{} since start (see the journal)",
                count(h.internal_errors, "internal error", "internal errors")
            ),
        ));
    }
    if let Some(q) = h
        .quiet_hours
        .filter(|q| h.quiet_limit_hours > 0.0 && *q > h.quiet_limit_hours)
    {
        out.push((
            Level::Warning,
            format!("no new image for {q:.0} h (the imaging station, its share or the drop directory?)"),
        ));
    }
    for (zone, hours) in &h.logs_behind {
        out.push((Level::Warning, log_behind(zone, *hours)));
    }
    out.sort_by_key(|f| std::cmp::Reverse(f.0));
    out
}

/// "zone X's temperature log ends N days before its plants' newest session".
pub fn log_behind(zone: &str, hours: f64) -> String {
    format!(
        "{} ends {:.1} days before its plants' newest session (import the latest log)",
        crate::domain::climate_zone::describe(zone),
        hours / 24.0
    )
}

/// The `--check` line and its exit code.
pub fn check_line(found: &[(Level, String)]) -> (String, u8) {
    let (word, code) = match found.first().map(|f| f.0) {
        None => return ("phyllo OK".into(), 0),
        Some(Level::Warning) => ("WARNING", 1),
        Some(Level::Critical) => ("CRITICAL", 2),
    };
    let what: Vec<&str> = found.iter().map(|f| f.1.as_str()).collect();
    (format!("phyllo {word}: {}", what.join("; ")), code)
}

/// A heartbeat older than this means the service is not running.
const STALE_SECS: i64 = 15;
/// A snapshot or export older than this means its nightly timer is not running.
pub const STALE_NIGHTLY_HOURS: i64 = 48;

/// What `--check` weighs, read now from the store, the disk and the snapshots.
pub fn health(config: &Config, store: &Store) -> anyhow::Result<Health> {
    let svc = store.service()?;
    let since = crate::store::utc(chrono::Utc::now() - chrono::Duration::hours(24));
    Ok(Health {
        state: service_state(&svc),
        free: crate::files::disk::free_bytes(&config.state_dir()).ok(),
        backup_age_hours: newest_snapshot_age(config)?,
        export_age_hours: export_age_hours(config),
        failed_last_day: store.failures_since(&since)?,
        internal_errors: svc
            .get("internal_errors")
            .and_then(|v| v.parse().ok())
            .unwrap_or(0),
        logs_behind: store.temperature_logs_behind(STALE_NIGHTLY_HOURS as f64)?,
        quiet_hours: store.hours_since_newest_image()?,
        quiet_limit_hours: config.watch.quiet_hours,
        drop_dir_problem: drop_dir_problem(&config.drop_dir),
        database_replaced: svc.get("state").is_some_and(|s| s == "running")
            && svc.get("database_identity").is_some_and(|opened| {
                DatabaseIdentity::of(&config.database).map_or(true, |now| &now.text() != opened)
            }),
        shared_bytes: store.images_sharing_bytes()?,
    })
}

/// What keeps the service from seeing new images in `dir`, if anything.
fn drop_dir_problem(dir: &std::path::Path) -> Option<String> {
    let shown = dir.display();
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Some(format!("drop directory {shown} is missing (not mounted?)"))
        }
        Err(e) => Some(format!("drop directory {shown}: {e}")),
        Ok(m) if !m.is_dir() => Some(format!("drop directory {shown} is not a directory")),
        Ok(_) => std::fs::read_dir(dir)
            .err()
            .map(|e| format!("drop directory {shown} cannot be read: {e}")),
    }
}

/// Hours since the nightly export wrote its page, `None` when it never has.
pub fn export_age_hours(config: &Config) -> Option<i64> {
    let written = std::fs::metadata(config.export_dir().join("index.html"))
        .and_then(|m| m.modified())
        .ok()?;
    let age = std::time::SystemTime::now()
        .duration_since(written)
        .unwrap_or_default();
    Some((age.as_secs() / 3600) as i64)
}

/// Hours since the newest snapshot, `None` when there is none.
fn newest_snapshot_age(config: &Config) -> anyhow::Result<Option<i64>> {
    Ok(crate::ops::backup::list(&config.backup_dir())?
        .pop()
        .map(|s| s.age_hours()))
}

/// The service's state from its self-report: a stale heartbeat means it is not running.
pub fn service_state(svc: &std::collections::BTreeMap<String, String>) -> String {
    let heartbeat_age = svc
        .get("heartbeat")
        .and_then(|h| chrono::DateTime::parse_from_rfc3339(h).ok())
        .map(|h| (chrono::Utc::now() - h.with_timezone(&chrono::Utc)).num_seconds());
    match (svc.get("state").map(String::as_str), heartbeat_age) {
        (Some("running"), Some(age)) if age > STALE_SECS => {
            format!("not running (last heartbeat {age} s ago)")
        }
        (Some(s), _) => s.to_string(),
        (None, _) => "never started".into(),
    }
}

/// "1 leaf", "2 leaves", "0 leaves".
pub fn count(n: i64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn healthy() -> Health {
        Health {
            state: "running".into(),
            free: Some(50 << 30),
            backup_age_hours: Some(5),
            export_age_hours: Some(6),
            ..Health::default()
        }
    }

    #[test]
    fn one_failure_and_one_error_read_in_the_singular() {
        let h = Health {
            failed_last_day: 1,
            internal_errors: 1,
            ..healthy()
        };
        assert_eq!(
            check_line(&findings(&h)).0,
            "phyllo WARNING: 1 image failed in the last 24 h; 1 internal error since start (see the journal)"
        );
    }

    #[test]
    fn a_healthy_site_is_ok() {
        assert_eq!(check_line(&findings(&healthy())), ("phyllo OK".into(), 0));
    }

    #[test]
    fn a_missing_or_wrong_drop_directory_and_a_replaced_database_are_critical() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("drop");
        assert!(drop_dir_problem(&missing).unwrap().contains("is missing"));
        std::fs::write(&missing, b"").unwrap();
        assert!(drop_dir_problem(&missing).unwrap().contains("is not a directory"));
        std::fs::remove_file(&missing).unwrap();
        std::fs::create_dir(&missing).unwrap();
        assert_eq!(drop_dir_problem(&missing), None);
        let h = Health {
            drop_dir_problem: Some("drop directory /srv/drop is missing (not mounted?)".into()),
            database_replaced: true,
            shared_bytes: 2,
            ..healthy()
        };
        let (line, code) = check_line(&findings(&h));
        assert_eq!(code, 2, "{line}");
        assert!(
            line.starts_with("phyllo CRITICAL: drop directory /srv/drop is missing")
                && line.contains("not the file the service opened")
                && line.contains("2 images have the bytes of another counted image"),
            "{line}"
        );
    }

    #[test]
    fn the_worst_finding_sets_the_code_and_leads_the_line() {
        let h = Health {
            backup_age_hours: Some(72),
            failed_last_day: 3,
            ..healthy()
        };
        assert_eq!(
            check_line(&findings(&h)),
            (
                "phyllo WARNING: newest snapshot 72 h old; 3 images failed in the last 24 h".into(),
                1
            )
        );
        let h = Health {
            state: "not running (last heartbeat 40 s ago)".into(),
            free: Some(100 << 20),
            backup_age_hours: None,
            ..healthy()
        };
        let (line, code) = check_line(&findings(&h));
        assert_eq!(code, 2);
        assert!(
            line.starts_with("phyllo CRITICAL: service not running (last heartbeat 40 s ago); 105 MB free"),
            "{line}"
        );
        assert!(line.ends_with("no database snapshot"), "{line}");
        let h = Health {
            quiet_hours: Some(50.0),
            quiet_limit_hours: 48.0,
            ..healthy()
        };
        assert_eq!(
            check_line(&findings(&h)).0,
            "phyllo WARNING: no new image for 50 h (the imaging station, its share or the drop directory?)"
        );
        let off = Health {
            quiet_limit_hours: 0.0,
            ..h
        };
        assert_eq!(check_line(&findings(&off)).1, 0, "0 turns it off");
        let h = Health {
            logs_behind: vec![("house-2".into(), 60.0)],
            ..healthy()
        };
        assert_eq!(
            check_line(&findings(&h)).0,
            "phyllo WARNING: zone house-2's temperature log ends 2.5 days before its plants' newest session \
             (import the latest log)"
        );
    }
}
