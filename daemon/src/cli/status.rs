//! `phyllo status --config FILE [--json]`.

use super::ConfigArg;
use crate::store::Store;

/// Arguments of `phyllo status`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// A heartbeat older than this means the service is not running.
const STALE_SECS: i64 = 15;
/// The newest snapshot older than this means the nightly backup is not running.
const STALE_BACKUP_HOURS: i64 = 48;

/// Runs `phyllo status`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let store = Store::open_read_only(&config.database)?;
    let svc = store.service()?;
    let counts = store.image_counts()?;
    let timeline = store.timeline_summary()?;
    let last = store.last_image()?;
    let failures = store.recent_failures(5)?;
    // Counts made with other settings than the service's (an upgrade since):
    // `phyllo recount` brings them in line.
    let other_settings = match svc.get("settings") {
        Some(s) => Some(store.counts_with_other_settings(s)?),
        None => None,
    };
    let backup_dir = config.backup_dir();
    let snapshots = crate::sinks::backup::list(&backup_dir);
    let newest = snapshots.as_ref().ok().and_then(|s| s.last().cloned());
    let backup_age_hours = newest
        .as_ref()
        .map(|s| (chrono::Local::now().naive_local() - s.taken_at).num_hours());
    let state_dir = config.state_dir();
    let free = crate::disk::free_bytes(&state_dir).ok();
    let get = |k: &str| svc.get(k).cloned().unwrap_or_else(|| "-".into());
    let heartbeat_age = svc
        .get("heartbeat")
        .and_then(|h| chrono::DateTime::parse_from_rfc3339(h).ok())
        .map(|h| (chrono::Utc::now() - h.with_timezone(&chrono::Utc)).num_seconds());
    let state = match (svc.get("state").map(String::as_str), heartbeat_age) {
        (Some("running"), Some(age)) if age > STALE_SECS => {
            format!("not running (last heartbeat {age} s ago)")
        }
        (Some(s), _) => s.to_string(),
        (None, _) => "never started".into(),
    };
    if args.json {
        let v = serde_json::json!({
            "state": state,
            "service": svc,
            "images": counts,
            "timeline": timeline,
            "last_image": last,
            "recent_failures": failures,
            "counts_with_other_settings": other_settings,
            "free_bytes": free,
            "backup": {
                "dir": backup_dir,
                "snapshots": snapshots.as_ref().map(Vec::len).ok(),
                "newest": newest,
                "age_hours": backup_age_hours,
                "error": snapshots.as_ref().err().map(|e| format!("{e:#}")),
            },
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
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
    println!(
        "images:    {} counted, {} duplicates, {} failed; {} imported counts; {} plants",
        counts.counted, counts.duplicate, counts.failed, counts.imported, counts.plants
    );
    println!(
        "timeline:  {} leaves dated; {} leaves lost on {} plants; fit {}",
        timeline.events,
        timeline.leaves_lost,
        timeline.plants_with_lost_leaves,
        timeline.settings.as_deref().unwrap_or("-")
    );
    match other_settings {
        Some(0) => println!("settings:  every count made with the service's settings"),
        Some(n) => println!(
            "settings:  {n} counts made with other settings than the service's (an upgrade since?): `phyllo recount` counts them again"
        ),
        None => {}
    }
    if let Some(free) = free {
        let warn = if free < crate::disk::LOW_FREE_BYTES {
            " — low: counting fails when it runs out"
        } else {
            ""
        };
        println!(
            "disk:      {} free beside the database ({}){warn}",
            crate::disk::human(free),
            state_dir.display()
        );
    }
    match (&snapshots, &newest) {
        (Err(e), _) => println!("backup:    {e:#}"),
        (Ok(_), None) => println!(
            "backup:    no snapshot in {} (`phyllo backup`, or enable phyllo-backup.timer)",
            backup_dir.display()
        ),
        (Ok(all), Some(s)) => {
            let age = backup_age_hours.unwrap_or(0);
            let warn = if age > STALE_BACKUP_HOURS {
                " — older than 2 days: is phyllo-backup.timer enabled?"
            } else {
                ""
            };
            println!(
                "backup:    newest {} ({age} h ago, {:.1} MB), {} kept in {}{warn}",
                s.taken_at.format("%Y-%m-%d %H:%M"),
                s.bytes as f64 / 1e6,
                all.len(),
                backup_dir.display()
            );
        }
    }
    match last {
        Some(l) => println!("last:      {} ({}, {})", l.path, l.state, l.at),
        None => println!("last:      -"),
    }
    for (path, err) in failures {
        println!("failed:    {path}: {err}");
    }
    Ok(())
}
