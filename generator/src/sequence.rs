//! `phyllo-gen sequence`: the same plants imaged on successive days, written
//! as full camera frames named like the facility's flat files
//! (`<plant>_<YYYY-MM-DD>_<HH-MM-SS>_Vis_SV_<angle>.png`, top `Vis_TV_90`)
//! so they can be dropped into the daemon's watch folder, plus `truth.csv`.

use crate::climate::{Climate, ClimateSpec};
use crate::plant::{growth::PlantTraits, preset::Preset, Plant};
use crate::render::{self, look::Look, Quality, Scene, Stage, View, Window};
use crate::{png_io, rng, sampling};
use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Settings of a sequence run.
#[derive(Debug, Clone)]
pub struct SequenceArgs {
    /// Output folder.
    pub out: PathBuf,
    /// Number of plants.
    pub plants: u64,
    /// Number of imaging days.
    pub days: u32,
    /// Master seed.
    pub seed: u64,
    /// First imaging date.
    pub start: Date,
    /// Plant age on the first imaging day.
    pub start_age: f32,
    /// Days between imaging sessions.
    pub interval: u32,
    /// Views per session.
    pub views: Vec<View>,
    /// Camera frame height (width follows the facility aspect).
    pub frame_height: u32,
    /// Presets to draw from.
    pub presets: Vec<Preset>,
    /// Sampling quality.
    pub quality: Quality,
    /// Also write panoptic labels into `labels/`.
    pub labels: bool,
    /// Greenhouse air temperature driving development; `None`: every day
    /// counts as one day of development (the presets' reference temperature).
    pub climate: Option<ClimateSpec>,
    /// No progress bar.
    pub quiet: bool,
}

/// A civil (proleptic Gregorian) date.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Date {
    /// Year.
    pub year: i32,
    /// Month 1..=12.
    pub month: u32,
    /// Day 1..=31.
    pub day: u32,
}

impl Date {
    /// Parses `YYYY-MM-DD`.
    pub fn parse(s: &str) -> anyhow::Result<Date> {
        let parts: Vec<&str> = s.split('-').collect();
        let bad = || anyhow::anyhow!("date {s:?} is not YYYY-MM-DD");
        if parts.len() != 3 {
            return Err(bad());
        }
        let d = Date {
            year: parts[0].parse().map_err(|_| bad())?,
            month: parts[1].parse().map_err(|_| bad())?,
            day: parts[2].parse().map_err(|_| bad())?,
        };
        if Date::from_days(d.to_days()) != d {
            bail!("date {s:?} does not exist");
        }
        Ok(d)
    }

    /// Days since 1970-01-01 (Howard Hinnant's algorithm).
    pub fn to_days(self) -> i64 {
        let y = i64::from(self.year) - i64::from(self.month <= 2);
        let era = y.div_euclid(400);
        let yoe = y - era * 400;
        let m = i64::from(self.month);
        let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(self.day) - 1;
        let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
        era * 146_097 + doe - 719_468
    }

    /// The date `days` after 1970-01-01.
    pub fn from_days(days: i64) -> Date {
        let z = days + 719_468;
        let era = z.div_euclid(146_097);
        let doe = z - era * 146_097;
        let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
        let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
        let mp = (5 * doy + 2) / 153;
        let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
        let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
        let year = (yoe + era * 400 + i64::from(month <= 2)) as i32;
        Date { year, month, day }
    }

    /// This date plus `n` days.
    pub fn add_days(self, n: i64) -> Date {
        Date::from_days(self.to_days() + n)
    }
}

impl std::fmt::Display for Date {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:04}-{:02}-{:02}", self.year, self.month, self.day)
    }
}

/// The facility-style file name of one view.
pub fn file_name(plant: &str, date: Date, seconds_of_day: u32, view: View) -> String {
    let (h, m, s) = (
        seconds_of_day / 3600,
        seconds_of_day / 60 % 60,
        seconds_of_day % 60,
    );
    let tail = match view {
        View::Top => "Vis_TV_90".to_string(),
        v => format!("Vis_SV_{}", v.name()),
    };
    format!("{plant}_{date}_{h:02}-{m:02}-{s:02}_{tail}.png")
}

/// Plant id used in file names (no underscores: they separate fields).
pub fn plant_id(index: u64, preset: &str) -> String {
    format!("SYN-{preset}-{index:03}")
}

/// Runs the sequence command.
pub fn run(args: &SequenceArgs) -> anyhow::Result<()> {
    if args.plants == 0 || args.days == 0 {
        bail!("--plants and --days must be at least 1");
    }
    if args.interval == 0 {
        bail!("--interval must be at least 1 day");
    }
    if !(64..=4112).contains(&args.frame_height) {
        bail!("--frame-height {} is outside 64..=4112", args.frame_height);
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output folder {}", args.out.display()))?;
    let total = args.plants * u64::from(args.days) * args.views.len() as u64;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {per_sec}  eta {eta}")
            .expect("valid template"),
    );
    let climate = args.climate.map(|spec| {
        // Sown at midnight, `start_age` days before the first imaging day;
        // the log runs to the day after the last session.
        let sown_days = args.start_age.round() as u32;
        let span = sown_days + (args.days - 1) * args.interval + 2;
        let sown = args.start.add_days(-i64::from(sown_days));
        (
            Climate::simulate(spec, rng::derive(args.seed, "climate", 0), sown, span),
            sown_days,
        )
    });
    let mut truth = String::from("plant,date,time,age_days,living_leaves,leaves_emerged,emergence_dates");
    truth.push_str(if climate.is_some() {
        ",degree_days,emergence_at,emergence_cd\n"
    } else {
        "\n"
    });
    for p in 0..args.plants {
        let preset = sampling::pick_preset(&args.presets, args.seed, p).clone();
        let traits = PlantTraits::sample(&preset, rng::derive(args.seed, "plant", p));
        let id = plant_id(p, &preset.name);
        // One look per plant with the facility's calibration, small day-to-day drift.
        for d in 0..args.days {
            let date = args.start.add_days(i64::from(d * args.interval));
            // Plants go through the imager one after another each morning.
            let secs = 8 * 3600 + (p as u32 * 157 + d * 41) % (10 * 3600);
            let (h, m, s) = (secs / 3600, secs / 60 % 60, secs % 60);
            let (age, emerged, thermal) = match &climate {
                None => {
                    let age = args.start_age + (d * args.interval) as f32;
                    let emerged: Vec<String> = traits
                        .leaves
                        .iter()
                        .filter(|l| l.emergence_day <= age)
                        .map(|l| {
                            let offset = (l.emergence_day - args.start_age).floor() as i64;
                            args.start.add_days(offset).to_string()
                        })
                        .collect();
                    (age, emerged, String::new())
                }
                Some((c, sown_days)) => {
                    let minutes = f64::from((sown_days + d * args.interval) * 1440 + secs / 60)
                        + f64::from(secs % 60) / 60.0;
                    let age = c.development_days_at(minutes) as f32;
                    let (mut dates, mut at, mut cd) = (Vec::new(), Vec::new(), Vec::new());
                    for l in traits.leaves.iter().filter(|l| l.emergence_day <= age) {
                        let when = c
                            .minutes_of_development(f64::from(l.emergence_day))
                            .expect("a leaf out by an imaging day emerged within the log");
                        let (day, time) = c.clock(when);
                        dates.push(day.to_string());
                        at.push(format!("{day}T{time}"));
                        cd.push(format!("{:.2}", c.degree_days_at(when)));
                    }
                    let extra = format!(
                        ",{:.2},{},{}",
                        c.degree_days_at(minutes),
                        at.join(";"),
                        cd.join(";")
                    );
                    (age, dates, extra)
                }
            };
            writeln!(
                truth,
                "{id},{date},{h:02}:{m:02}:{s:02},{age},{},{},{}{thermal}",
                traits.living_on(age),
                traits.emerged_by(age),
                emerged.join(";")
            )?;
            let names: Vec<(View, String)> = args
                .views
                .iter()
                .map(|v| (*v, file_name(&id, date, secs, *v)))
                .collect();
            if names.iter().all(|(_, n)| args.out.join(n).exists()) {
                bar.inc(names.len() as u64);
                continue;
            }
            let mut look = Look::facility();
            let mut r = rng::stream(args.seed, "sequence-look", p * 10_000 + u64::from(d));
            look.exposure *= 1.0 + 0.03 * rand::Rng::random::<f32>(&mut r) - 0.015;
            let plant = Plant::build(&traits, age);
            let panicle = preset
                .panicle
                .as_ref()
                .map(|x| x.reflectance)
                .unwrap_or([0.3, 0.3, 0.1]);
            let stage = Stage::new(&plant, &preset.colour, panicle, &look);
            for (view, name) in &names {
                let path = args.out.join(name);
                if path.exists() {
                    bar.inc(1);
                    continue;
                }
                let scene = Scene::new(&stage, &look, *view);
                let camera = render::camera_for(*view, &look, args.frame_height);
                let window = Window {
                    x0: 0,
                    y0: 0,
                    width: camera.width,
                    height: camera.height,
                };
                let seed = rng::derive(
                    rng::derive(args.seed, "sequence", p * 10_000 + u64::from(d)),
                    &view.name(),
                    0,
                );
                let out = render::render(&scene, &camera, &look, window, args.quality, seed)?;
                if args.labels {
                    png_io::write_atomic(
                        &args.out.join("labels").join(name),
                        &png_io::label_png(&out.label)?,
                    )?;
                }
                png_io::write_atomic(&path, &png_io::rgb_png(&out.rgb)?)?;
                bar.inc(1);
            }
        }
    }
    bar.finish_and_clear();
    png_io::write_atomic(&args.out.join("truth.csv"), truth.as_bytes())?;
    if let Some((c, _)) = &climate {
        png_io::write_atomic(&args.out.join("climate.csv"), c.csv().as_bytes())?;
    }
    if !args.quiet {
        eprintln!("wrote {} frames and truth.csv to {}", total, args.out.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_round_trip_and_names_match_facility() {
        let d = Date::parse("2018-04-28").unwrap();
        assert_eq!(d.add_days(3).to_string(), "2018-05-01");
        assert_eq!(
            Date::parse("2020-02-29").unwrap().add_days(1).to_string(),
            "2020-03-01"
        );
        assert!(Date::parse("2019-02-29").is_err());
        assert_eq!(
            file_name("SYN-btx623-001", d, 8 * 3600 + 62, View::Side(108.0)),
            "SYN-btx623-001_2018-04-28_08-01-02_Vis_SV_108.png"
        );
        assert_eq!(
            file_name("P", d, 0, View::Top),
            "P_2018-04-28_00-00-00_Vis_TV_90.png"
        );
    }
}
