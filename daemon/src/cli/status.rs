//! `phyllo status --config FILE [--json | --check | --verbose]`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::ExitCode;

use super::ConfigArg;
use crate::config::Config;
use crate::ops::backup::Snapshot;
use crate::ops::health::{
    check_line, count, export_age_hours, findings, health, log_behind, service_state, STALE_NIGHTLY_HOURS,
};
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
    /// Acknowledge every failure recorded so far: it leaves the counts, the
    /// list of failures and `--check` (a file that changes is still counted).
    #[arg(long, conflicts_with_all = ["check", "json", "verbose"])]
    ack: bool,
}

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
    if args.ack {
        let config = args.config.load()?;
        let mut store = Store::open(
            &config.database,
            &config.rules().timeline,
            config.inference.max_attempts,
        )?;
        let n = store.acknowledge_failures()?;
        println!(
            "acknowledged {}: status and --check no longer count them",
            count(n as i64, "failure", "failures")
        );
        return Ok(ExitCode::SUCCESS);
    }
    show(args).map(|()| ExitCode::SUCCESS)
}

fn check(args: &Args) -> anyhow::Result<(String, u8)> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    Ok(check_line(&findings(&health(&config, &store)?)))
}

/// What `phyllo status` shows, read before anything is printed so that a
/// database error prints nothing half-way.
struct Report {
    /// The service's self-report.
    svc: BTreeMap<String, String>,
    /// The `--check` line: every problem `--check` finds, shown by plain
    /// `status` too (a missing drop directory must not look healthy).
    check: String,
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
        // As --check would say it; plain status still shows the rest when it
        // cannot (an unreadable backup directory is shown, not fatal).
        let check = match health(config, store) {
            Ok(h) => check_line(&findings(&h)).0,
            Err(e) => format!("phyllo UNKNOWN: {e:#}"),
        };
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
        let free = crate::files::disk::free_bytes(&state_dir).ok();
        let in_doubt = crate::domain::review::rank(&store.plant_timelines()?, None).len();
        let climate = store.climate_summary()?;
        let behind = store.temperature_logs_behind(STALE_NIGHTLY_HOURS as f64)?;
        Ok(Report {
            svc,
            check,
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
    println!("check:     {}", r.check);
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
        "check": r.check,
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
        let warn = if free < crate::files::disk::LOW_FREE_BYTES {
            " — low: counting fails when it runs out"
        } else {
            ""
        };
        println!(
            "disk:      {} free beside the database ({}){warn}",
            crate::files::disk::human(free),
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
}
