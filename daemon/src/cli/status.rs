//! `phyllo status --config FILE [--json | --check | --verbose]`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::ExitCode;

use super::ConfigArg;
use crate::config::Config;
use crate::ops::backup::Snapshot;
use crate::store::{ClimateSummary, ImageCounts, LastImage, Store, TimelineSummary};

/// Arguments of `phyllo status`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Print JSON.
    #[arg(long, conflicts_with = "check")]
    json: bool,
    /// One line for a monitoring system, with the Nagios plugin exit codes:
    /// 0 OK, 1 WARNING, 2 CRITICAL, 3 UNKNOWN (the database cannot be read).
    #[arg(long)]
    check: bool,
    /// Also print internal detail: the fingerprint of the settings the
    /// timelines were fitted with and the service's counting settings.
    #[arg(long, conflicts_with_all = ["check", "json"])]
    verbose: bool,
}

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
        Some(f) if f < crate::disk::SNAPSHOT_RESERVE_BYTES => out.push((
            Level::Critical,
            format!("{} free beside the database", crate::disk::human(f)),
        )),
        Some(f) if f < crate::disk::LOW_FREE_BYTES => out.push((
            Level::Warning,
            format!("{} free beside the database", crate::disk::human(f)),
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
fn log_behind(zone: &str, hours: f64) -> String {
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
const STALE_NIGHTLY_HOURS: i64 = 48;

/// Runs `phyllo status`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.check {
        // A monitor must tell "cannot tell" from "broken": UNKNOWN is 3.
        return Ok(match check(&args) {
            Ok((line, code)) => {
                println!("{line}");
                ExitCode::from(code)
            }
            Err(e) => {
                println!("phyllo UNKNOWN: {e:#}");
                ExitCode::from(3)
            }
        });
    }
    show(args).map(|()| ExitCode::SUCCESS)
}

fn check(args: &Args) -> anyhow::Result<(String, u8)> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    Ok(check_line(&findings(&health(&config, &store)?)))
}

/// What `--check` weighs, read now from the store, the disk and the snapshots.
pub fn health(config: &crate::config::Config, store: &Store) -> anyhow::Result<Health> {
    let svc = store.service()?;
    let since = crate::store::utc(chrono::Utc::now() - chrono::Duration::hours(24));
    Ok(Health {
        state: service_state(&svc),
        free: crate::disk::free_bytes(&config.state_dir()).ok(),
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
                crate::pipeline::health::DatabaseIdentity::of(&config.database)
                    .map_or(true, |now| &now.text() != opened)
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
fn export_age_hours(config: &crate::config::Config) -> Option<i64> {
    let written = std::fs::metadata(config.export_dir().join("index.html"))
        .and_then(|m| m.modified())
        .ok()?;
    let age = std::time::SystemTime::now()
        .duration_since(written)
        .unwrap_or_default();
    Some((age.as_secs() / 3600) as i64)
}

/// Hours since the newest snapshot, `None` when there is none.
fn newest_snapshot_age(config: &crate::config::Config) -> anyhow::Result<Option<i64>> {
    Ok(crate::ops::backup::list(&config.backup_dir())?
        .pop()
        .map(|s| s.age_hours()))
}

/// The service's state from its self-report: a stale heartbeat means it is not running.
fn service_state(svc: &std::collections::BTreeMap<String, String>) -> String {
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

/// What `phyllo status` shows, read before anything is printed so that a
/// database error prints nothing half-way.
struct Report {
    /// The service's self-report.
    svc: BTreeMap<String, String>,
    counts: ImageCounts,
    timeline: TimelineSummary,
    last: Option<LastImage>,
    /// The newest failures: (path, error).
    failures: Vec<(String, String)>,
    /// Plants with no count at all (their images failed): no timeline yet.
    uncounted: Vec<String>,
    /// Counts made with other settings than the service's (an upgrade since):
    /// `phyllo recount` brings them in line.
    other_settings: Option<i64>,
    backup_dir: PathBuf,
    /// An unreadable backup directory is shown, not fatal.
    snapshots: anyhow::Result<Vec<Snapshot>>,
    newest: Option<Snapshot>,
    backup_age_hours: Option<i64>,
    state_dir: PathBuf,
    free: Option<u64>,
    in_doubt: usize,
    climate: Vec<ClimateSummary>,
    /// Temperature logs ending well before their plants' newest session: (zone, hours).
    behind: Vec<(String, f64)>,
}

impl Report {
    /// Reads it from the store, the snapshots and the disk.
    fn read(config: &Config, store: &Store) -> anyhow::Result<Report> {
        let svc = store.service()?;
        let counts = store.image_counts()?;
        let timeline = store.timeline_summary()?;
        let last = store.last_image()?;
        let failures = store.recent_failures(5)?;
        let uncounted = store.plants_without_counts()?;
        let other_settings = match svc.get("settings") {
            Some(s) => Some(store.counts_with_other_settings(s)?),
            None => None,
        };
        let backup_dir = config.backup_dir();
        let snapshots = crate::ops::backup::list(&backup_dir);
        let newest = snapshots.as_ref().ok().and_then(|s| s.last().cloned());
        let backup_age_hours = newest.as_ref().map(|s| s.age_hours());
        let state_dir = config.state_dir();
        let free = crate::disk::free_bytes(&state_dir).ok();
        let in_doubt = crate::domain::review::rank(&store.plant_timelines()?, None).len();
        let climate = store.climate_summary()?;
        let behind = store.temperature_logs_behind(STALE_NIGHTLY_HOURS as f64)?;
        Ok(Report {
            svc,
            counts,
            timeline,
            last,
            failures,
            uncounted,
            other_settings,
            backup_dir,
            snapshots,
            newest,
            backup_age_hours,
            state_dir,
            free,
            in_doubt,
            climate,
            behind,
        })
    }
}

fn show(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    let r = Report::read(&config, &store)?;
    let state = service_state(&r.svc);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&json(&config, &r, &state))?);
        return Ok(());
    }
    print_service(&config, &r, &state);
    for line in count_lines(&r.counts, &r.timeline, &r.uncounted) {
        println!("{line}");
    }
    if args.verbose {
        let get = |k: &str| r.svc.get(k).map_or("-", String::as_str);
        println!("fit:       {}", r.timeline.settings.as_deref().unwrap_or("-"));
        println!("counting:  {}", get("settings"));
    }
    print_climate(&config, &r);
    print_attention(&r);
    print_backup(&r);
    print_export(&config);
    match &r.last {
        Some(l) => println!("last:      {} ({}, {})", l.path, l.state, l.at),
        None => println!("last:      -"),
    }
    for (path, err) in &r.failures {
        println!("failed:    {path}: {err}");
    }
    Ok(())
}

/// `--json`: everything the text shows, for scripts.
fn json(config: &Config, r: &Report, state: &str) -> serde_json::Value {
    serde_json::json!({
        "state": state,
        "service": r.svc,
        "images": r.counts,
        "timeline": r.timeline,
        "sessions_in_doubt": r.in_doubt,
        "climate": r.climate,
        "climate_behind_hours": r.behind.iter().cloned().collect::<BTreeMap<String, f64>>(),
        "last_image": r.last,
        "recent_failures": r.failures,
        "counts_with_other_settings": r.other_settings,
        "free_bytes": r.free,
        "export_age_hours": export_age_hours(config),
        "backup": {
            "dir": r.backup_dir,
            "snapshots": r.snapshots.as_ref().map(Vec::len).ok(),
            "newest": r.newest,
            "age_hours": r.backup_age_hours,
            "error": r.snapshots.as_ref().err().map(|e| format!("{e:#}")),
        },
    })
}

/// The service, where it reads and writes, and what it has done.
fn print_service(config: &Config, r: &Report, state: &str) {
    let get = |k: &str| r.svc.get(k).cloned().unwrap_or_else(|| "-".into());
    println!(
        "service:   {state} (pid {}, since {})",
        get("pid"),
        get("started_at")
    );
    println!("model:     {}", get("model"));
    println!("drop dir:  {}", config.drop_dir.display());
    println!("database:  {}", config.database.display());
    println!(
        "queue:     {} queued, {} being counted",
        get("queued"),
        get("busy")
    );
}

/// "1 leaf", "2 leaves", "0 leaves".
fn count(n: i64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// At most this many plants without a count are named.
const UNCOUNTED_NAMED: usize = 10;

/// The images, the plants and the timelines in words: plants without any
/// count (`uncounted`) are listed apart, not among the plants with a timeline.
fn count_lines(counts: &ImageCounts, timeline: &TimelineSummary, uncounted: &[String]) -> Vec<String> {
    let with_counts = counts.plants - uncounted.len() as i64;
    let mut out = vec![format!(
        "images:    {} counted, {}, {} failed; {}; {} counted",
        counts.counted,
        count(counts.duplicate, "duplicate", "duplicates"),
        counts.failed,
        count(counts.imported, "imported count", "imported counts"),
        count(with_counts, "plant", "plants"),
    )];
    if !uncounted.is_empty() {
        let mut names = uncounted[..uncounted.len().min(UNCOUNTED_NAMED)].join(", ");
        if uncounted.len() > UNCOUNTED_NAMED {
            names.push_str(", …");
        }
        out.push(format!(
            "plants:    {} no counted image yet: {names}",
            count(uncounted.len() as i64, "plant has", "plants have"),
        ));
    }
    let lost = timeline.leaves_lost;
    out.push(format!(
        "timeline:  {} dated; {lost} {} lost on {}",
        count(timeline.events, "leaf", "leaves"),
        if lost == 1.0 { "leaf" } else { "leaves" },
        count(timeline.plants_with_lost_leaves, "plant", "plants"),
    ));
    out
}

/// The temperature logs, and the zones whose plants they leave without
/// degree-days (gaps, a log behind, none at all).
fn print_climate(config: &Config, r: &Report) {
    for c in &r.climate {
        println!(
            "climate:   {}{} from {} to {}; longest gap {:.1} h{}",
            if c.zone.is_empty() {
                String::new()
            } else {
                format!("zone {}: ", c.zone)
            },
            count(c.readings, "temperature", "temperatures"),
            &c.first[..c.first.len().min(16)],
            &c.last[..c.last.len().min(16)],
            c.longest_gap_hours,
            if c.longest_gap_hours > crate::domain::thermal::MAX_GAP_HOURS {
                " (no degree-days across gaps over 6 h)"
            } else {
                ""
            }
        );
    }
    for (zone, hours) in &r.behind {
        println!("climate:   {}", log_behind(zone, *hours));
    }
    for zone in &config.timeline.zones {
        if !r.climate.iter().any(|c| c.zone == zone.name) {
            println!(
                "climate:   zone {}: no temperatures yet (its plants get no phyllochron in degree-days)",
                zone.name
            );
        }
    }
}

/// What asks for an operator's hand: sessions in doubt, counts made with
/// other settings, and the disk.
fn print_attention(r: &Report) {
    if r.in_doubt > 0 {
        println!(
            "review:    {} in doubt: `phyllo review` lists the most doubtful to count by hand",
            count(r.in_doubt as i64, "plant session", "plant sessions")
        );
    }
    match r.other_settings {
        Some(0) => println!("settings:  every count made with the service's settings"),
        Some(n) => println!(
            "settings:  {} made with other settings than the service's (an upgrade since?): `phyllo recount` counts {} again",
            count(n, "count", "counts"),
            if n == 1 { "it" } else { "them" }
        ),
        None => {}
    }
    if let Some(free) = r.free {
        let warn = if free < crate::disk::LOW_FREE_BYTES {
            " — low: counting fails when it runs out"
        } else {
            ""
        };
        println!(
            "disk:      {} free beside the database ({}){warn}",
            crate::disk::human(free),
            r.state_dir.display()
        );
    }
}

/// The newest snapshot, or why there is none: a stale one means the nightly
/// timer is not running.
fn print_backup(r: &Report) {
    match (&r.snapshots, &r.newest) {
        (Err(e), _) => println!("backup:    {e:#}"),
        (Ok(_), None) => println!(
            "backup:    no snapshot in {} (`phyllo backup`, or enable phyllo-backup.timer)",
            r.backup_dir.display()
        ),
        (Ok(all), Some(s)) => {
            let age = r.backup_age_hours.unwrap_or(0);
            let warn = if age > STALE_NIGHTLY_HOURS {
                " — older than 2 days: is phyllo-backup.timer enabled?"
            } else {
                ""
            };
            println!(
                "backup:    newest {} ({age} h ago, {:.1} MB), {} kept in {}{warn}",
                s.taken_at.format("%Y-%m-%d %H:%M"),
                s.bytes as f64 / 1e6,
                all.len(),
                r.backup_dir.display()
            );
        }
    }
}

/// The nightly export's age: a stale one means its timer is not running.
fn print_export(config: &Config) {
    match export_age_hours(config) {
        Some(a) => println!(
            "export:    index.html written {a} h ago in {}{}",
            config.export_dir().display(),
            if a > STALE_NIGHTLY_HOURS {
                " — older than 2 days: is phyllo-export.timer enabled?"
            } else {
                ""
            }
        ),
        None => println!(
            "export:    none yet in {} (`phyllo export`, or enable phyllo-export.timer)",
            config.export_dir().display()
        ),
    }
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
    fn counts_read_in_words_and_plants_without_a_count_stand_apart() {
        let counts = ImageCounts {
            counted: 1,
            duplicate: 1,
            failed: 1,
            imported: 1,
            plants: 2,
        };
        let timeline = TimelineSummary {
            events: 1,
            plants_with_lost_leaves: 1,
            leaves_lost: 1.0,
            settings: Some("fusion=second-max-side;session_gap_minutes=240".into()),
        };
        let lines = count_lines(&counts, &timeline, &["B-2".into()]);
        assert_eq!(
            lines,
            [
                "images:    1 counted, 1 duplicate, 1 failed; 1 imported count; 1 plant counted",
                "plants:    1 plant has no counted image yet: B-2",
                "timeline:  1 leaf dated; 1 leaf lost on 1 plant",
            ]
        );
        let many: Vec<String> = (1..=12).map(|i| format!("P{i:02}")).collect();
        let counts = ImageCounts {
            counted: 2,
            plants: 14,
            ..counts
        };
        let timeline = TimelineSummary {
            events: 2,
            plants_with_lost_leaves: 2,
            leaves_lost: 2.5,
            ..timeline
        };
        let lines = count_lines(&counts, &timeline, &many);
        assert_eq!(
            lines,
            [
                "images:    2 counted, 1 duplicate, 1 failed; 1 imported count; 2 plants counted",
                "plants:    12 plants have no counted image yet: P01, P02, P03, P04, P05, P06, P07, P08, P09, P10, …",
                "timeline:  2 leaves dated; 2.5 leaves lost on 2 plants",
            ]
        );
        let none = count_lines(&ImageCounts::default(), &TimelineSummary::default(), &[]);
        assert_eq!(
            none,
            [
                "images:    0 counted, 0 duplicates, 0 failed; 0 imported counts; 0 plants counted",
                "timeline:  0 leaves dated; 0 leaves lost on 0 plants",
            ]
        );
        assert!(lines.iter().chain(&none).all(|l| !l.contains("fusion=")));
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
