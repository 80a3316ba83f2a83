//! `phyllo-gen sequence`: the same plants imaged on successive days, written
//! as full camera frames named like the facility's flat files
//! (`<plant>_<YYYY-MM-DD>_<HH-MM-SS>_Vis_SV_<angle>.png`, top `Vis_TV_90`)
//! so they can be dropped into the daemon's watch folder, plus `truth.csv`.

use crate::climate::{Climate, ClimateSpec};
use crate::date::Date;
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
    check(args)?;
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
    let climate = args.climate.map(|spec| simulate_climate(args, spec));
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
        for d in 0..args.days {
            let date = args.start.add_days(i64::from(d * args.interval));
            // Plants go through the imager one after another each morning.
            let secs = 8 * 3600 + (p as u32 * 157 + d * 41) % (10 * 3600);
            let (h, m, s) = (secs / 3600, secs / 60 % 60, secs % 60);
            let (age, emerged, thermal) = development(args, climate.as_ref(), &traits, d, secs);
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
            let session = p * 10_000 + u64::from(d);
            render_session(args, &preset, &traits, age, session, &names, &bar)?;
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

/// Refuses settings that would render nothing or frames the camera model
/// was not made for, before any file is written.
fn check(args: &SequenceArgs) -> anyhow::Result<()> {
    if args.plants == 0 || args.days == 0 {
        bail!("--plants and --days must be at least 1");
    }
    if args.interval == 0 {
        bail!("--interval must be at least 1 day");
    }
    if !(64..=4112).contains(&args.frame_height) {
        bail!("--frame-height {} is outside 64..=4112", args.frame_height);
    }
    Ok(())
}

/// The temperature log of a run, and the whole days from sowing to the
/// first imaging day (the log starts at sowing).
fn simulate_climate(args: &SequenceArgs, spec: ClimateSpec) -> (Climate, u32) {
    // Sown at midnight, `start_age` days before the first imaging day;
    // the log runs to the day after the last session.
    let sown_days = args.start_age.round() as u32;
    let span = sown_days + (args.days - 1) * args.interval + 2;
    let sown = args.start.add_days(-i64::from(sown_days));
    (
        Climate::simulate(spec, rng::derive(args.seed, "climate", 0), sown, span),
        sown_days,
    )
}

/// A plant's development age on imaging day `d` (`secs` into the day), the
/// dates its leaves emerged by then, and the extra `truth.csv` columns a
/// climate adds (empty without one). Without a climate every day is a day
/// of development; with one the age follows the degree-days.
fn development(
    args: &SequenceArgs,
    climate: Option<&(Climate, u32)>,
    traits: &PlantTraits,
    d: u32,
    secs: u32,
) -> (f32, Vec<String>, String) {
    match climate {
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
            let minutes =
                f64::from((sown_days + d * args.interval) * 1440 + secs / 60) + f64::from(secs % 60) / 60.0;
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
    }
}

/// Renders the views `names` of one plant on one imaging day, skipping the
/// frames already written so an interrupted run picks up where it stopped.
/// `session` keys the day's look and render seeds (plant × 10 000 + day).
fn render_session(
    args: &SequenceArgs,
    preset: &Preset,
    traits: &PlantTraits,
    age: f32,
    session: u64,
    names: &[(View, String)],
    bar: &ProgressBar,
) -> anyhow::Result<()> {
    // One look per plant with the facility's calibration, small day-to-day drift.
    let mut look = Look::facility();
    let mut r = rng::stream(args.seed, "sequence-look", session);
    look.exposure *= 1.0 + 0.03 * rand::Rng::random::<f32>(&mut r) - 0.015;
    let plant = Plant::build(traits, age);
    let stage = Stage::for_preset(&plant, preset, &look);
    for (view, name) in names {
        let path = args.out.join(name);
        if path.exists() {
            bar.inc(1);
            continue;
        }
        let scene = Scene::new(&stage, &look, *view);
        let camera = render::camera_for(*view, &look, args.frame_height);
        let seed = rng::derive(rng::derive(args.seed, "sequence", session), &view.name(), 0);
        let out = render::render(&scene, &camera, &look, Window::frame(&camera), args.quality, seed)?;
        if args.labels {
            png_io::write_atomic(
                &args.out.join("labels").join(name),
                &png_io::label_png(&out.label)?,
            )?;
        }
        png_io::write_atomic(&path, &png_io::rgb_png(&out.rgb)?)?;
        bar.inc(1);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_match_facility() {
        let d = Date::parse("2018-04-28").unwrap();
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
