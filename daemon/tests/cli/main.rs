//! The operator commands as separate processes on a real database, one
//! module a command: import, tail (in another process), export, timeline
//! (with plot), status, groups, review, temperature logs.

#[path = "../common/mod.rs"]
mod common;

mod climate;
mod groups;
mod import;
mod operator;
mod review;
mod timeline;

use std::path::Path;

use common::{ok, write_config};

/// A config in `d` (drop directory and database under it) with `extra`
/// appended; returns its path and its text.
fn site_config(d: &Path, extra: &str) -> (String, String) {
    let cfg = d.join("phyllo.toml");
    let text = write_config(&cfg, &d.join("drop"), &d.join("state/phyllo.sqlite"), extra);
    (cfg.to_str().unwrap().to_string(), text)
}

/// A config in `d` grouping plants by genotype, and 21 days of counts
/// imported for six plants: a leaf every 2, 2 and 3 days in genotype F,
/// every 4, 4 and 5 in S. Returns the config's path.
fn two_genotypes(d: &Path) -> String {
    two_genotypes_with(d, "")
}

/// [`two_genotypes`] with `extra` at the end of the config.
fn two_genotypes_with(d: &Path, extra: &str) -> String {
    let (cfg, _) = site_config(
        d,
        &format!("[groups]\npattern = '^(?P<genotype>[A-Z]+)-\\d+$'\n{extra}"),
    );
    let plants = [
        ("F-1", 2),
        ("F-2", 2),
        ("F-3", 3),
        ("S-1", 4),
        ("S-2", 4),
        ("S-3", 5),
    ];
    std::fs::write(d.join("obs.csv"), steady_counts(&plants, 21, &[0, 72, 144])).unwrap();
    ok(&["import", "-c", &cfg, d.join("obs.csv").to_str().unwrap()]);
    cfg
}

/// `plant,timestamp,view,leaf_count` rows: each `(plant, every)` seen at
/// `angles` (the n-th angle n seconds past 10:00) on `days` days from 1
/// November, with 4 leaves on the first and one more every `every` days.
fn steady_counts(plants: &[(&str, u32)], days: u32, angles: &[u32]) -> String {
    let mut obs = String::from("plant,timestamp,view,leaf_count\n");
    for &(p, every) in plants {
        for day in 0..days {
            for (i, a) in angles.iter().enumerate() {
                obs += &format!(
                    "{p},2026-11-{:02}T10:00:{i:02},SV_{a},{}\n",
                    1 + day,
                    4 + day / every
                );
            }
        }
    }
    obs
}

/// `timestamp,temp_c[,zone]` rows every 30 minutes from 30 October for 24
/// days at `temp(hour)` °C.
fn temperature_log(zone: Option<&str>, temp: impl Fn(u32) -> f64) -> String {
    let start = chrono::NaiveDate::from_ymd_opt(2026, 10, 30)
        .unwrap()
        .and_hms_opt(0, 0, 0)
        .unwrap();
    let mut log = String::from(if zone.is_some() {
        "timestamp,temp_c,zone\n"
    } else {
        "timestamp,temp_c\n"
    });
    for k in 0..(24 * 48) {
        let t = start + chrono::Duration::minutes(30 * k);
        let temp = temp(chrono::Timelike::hour(&t));
        match zone {
            Some(z) => log += &format!("{},{temp},{z}\n", t.format("%Y-%m-%dT%H:%M:%S")),
            None => log += &format!("{},{temp}\n", t.format("%Y-%m-%dT%H:%M:%S")),
        }
    }
    log
}
