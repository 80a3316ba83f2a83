//! Command-line interface: argument parsing and validation, then hand-off to
//! the command modules. Every bad argument is reported by name.

use crate::climate::ClimateSpec;
use crate::dataset::{self, DatasetArgs};
use crate::date::Date;
use crate::plant::{growth::PlantTraits, preset::Preset, Plant};
use crate::render::{self, look::Look, Quality, Scene, Stage, View, Window};
use crate::sequence::{self, SequenceArgs};
use crate::{bench, png_io, rng, sampling};
use anyhow::{bail, Context};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Synthetic sorghum images with exact panoptic labels for phyllo.
#[derive(Parser, Debug)]
#[command(name = "phyllo-gen", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a training dataset: images, labels, manifest.jsonl.
    Dataset(DatasetCmd),
    /// Convert a rendered dataset to COCO panoptic format (DIR/coco/), for
    /// detectron2 or mmdetection.
    Coco {
        /// Dataset folder (with manifest.jsonl).
        dir: PathBuf,
    },
    /// Render plants growing over days, as facility-named camera frames + truth.csv.
    Sequence(SequenceCmd),
    /// Measure rays/s and image+label pairs/s at training quality.
    Bench {
        /// Pairs to render.
        #[arg(long, default_value_t = 24)]
        pairs: u32,
        /// Crop size.
        #[arg(long, default_value_t = 512)]
        size: u32,
        /// Camera samples per pixel.
        #[arg(long, default_value_t = Quality::default().spp)]
        spp: u32,
        /// Seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Render one full camera frame (image, label, mask) of one plant.
    Render(RenderCmd),
    /// Export a plant mesh as OBJ (one group per leaf).
    Mesh {
        #[command(flatten)]
        plant: PlantArgs,
        /// Output .obj file.
        #[arg(long)]
        out: PathBuf,
    },
    /// List built-in presets, or validate preset files.
    Presets {
        /// Preset files to validate.
        files: Vec<PathBuf>,
    },
}

/// Options of `dataset`, checked and turned into [`DatasetArgs`] by [`DatasetCmd::run`].
#[derive(Args, Debug)]
struct DatasetCmd {
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Number of plants.
    #[arg(long)]
    plants: u64,
    /// Master seed.
    #[arg(long)]
    seed: u64,
    /// Views: side angles in degrees and/or `top`.
    #[arg(long, default_value = "0,36,72,108,144,top")]
    views: String,
    /// Side of the square training crop in pixels (frame scale, never rescaled).
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Write whole side-camera frames (614x514 at the contract scale,
    /// chamber fittings at the edges included) instead of square crops.
    #[arg(long)]
    full_frame: bool,
    /// Fraction of plants held out for validation.
    #[arg(long, default_value_t = 0.1)]
    val_fraction: f32,
    /// Preset names or .toml paths, comma-separated, each optionally `:WEIGHT` (e.g. `btx623,maize:0.5`; default: all weighted built-ins).
    #[arg(long)]
    preset: Option<String>,
    /// Render shard I of N (plants with index % N == I), e.g. 3/16.
    #[arg(long, default_value = "0/1")]
    shard: String,
    /// Camera samples per pixel.
    #[arg(long, default_value_t = Quality::default().spp)]
    spp: u32,
    /// Also write human-viewable colour masks to masks/.
    #[arg(long)]
    masks: bool,
    /// Share of plants whose dead leaves leave a dried sheath and a blade
    /// stub (labelled stem); overrides every preset's `dead_remnant_chance`.
    #[arg(long)]
    dead_remnants: Option<f32>,
    /// Oldest plant age in days. Past the default 8 weeks maize reaches the
    /// 14–15 leaves of the facility's late plants (with --max-leaves).
    #[arg(long, default_value_t = sampling::MAX_AGE)]
    max_age: f32,
    /// Most living leaves of a plant (the paper's 13 by default).
    #[arg(long, default_value_t = sampling::MAX_LEAVES)]
    max_leaves: usize,
    /// Side-camera zoom: `Z` for every plant, `MIN-MAX` drawn per plant, or
    /// `MIN-MAX:SHARE` for a share of the plants (the rest at 1). The
    /// facility zooms some chambers about 2×; `1` is the paper's protocol.
    #[arg(long, default_value = sampling::ZoomRange::DEFAULT_SPEC)]
    zoom: String,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Options of `sequence`, checked and turned into [`SequenceArgs`] by [`SequenceCmd::run`].
#[derive(Args, Debug)]
struct SequenceCmd {
    /// Output folder (e.g. the daemon's watch folder).
    #[arg(long)]
    out: PathBuf,
    /// Number of plants.
    #[arg(long)]
    plants: u64,
    /// Number of imaging days.
    #[arg(long)]
    days: u32,
    /// Master seed.
    #[arg(long)]
    seed: u64,
    /// First imaging date (YYYY-MM-DD).
    #[arg(long, default_value = "2018-04-10")]
    start_date: String,
    /// Plant age in days on the first imaging date.
    #[arg(long, default_value_t = 14.0)]
    start_age: f32,
    /// Days between imaging sessions.
    #[arg(long, default_value_t = 1)]
    interval: u32,
    /// Views per session.
    #[arg(long, default_value = "0,36,72,108,144,top")]
    views: String,
    /// Camera frame height; width follows the 2454x2056 aspect.
    #[arg(long, default_value_t = 514)]
    frame_height: u32,
    /// Preset names or .toml paths, comma-separated, each optionally `:WEIGHT`.
    #[arg(long)]
    preset: Option<String>,
    /// Camera samples per pixel.
    #[arg(long, default_value_t = Quality::default().spp)]
    spp: u32,
    /// Also write panoptic labels to labels/.
    #[arg(long)]
    labels: bool,
    /// Share of plants whose dead leaves leave a dried sheath and a blade
    /// stub (labelled stem); overrides every preset's `dead_remnant_chance`.
    #[arg(long)]
    dead_remnants: Option<f32>,
    /// Greenhouse air temperature `MEAN[,SWING[,DRIFT]]` in °C (daily mean,
    /// half the day–night swing [4], day-to-day spread [1.5]): plants then
    /// develop by degree-days above 10 °C (the presets' days hold at 25 °C),
    /// and the log is written as climate.csv for `phyllo import`.
    #[arg(long)]
    climate: Option<String>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Options of `render`.
#[derive(Args, Debug)]
struct RenderCmd {
    #[command(flatten)]
    plant: PlantArgs,
    /// View: side angle in degrees or `top`.
    #[arg(long, default_value = "108")]
    view: String,
    /// Camera frame height.
    #[arg(long, default_value_t = 514)]
    frame_height: u32,
    /// Camera samples per pixel.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Output RGB PNG; the label goes beside it as `.label.png`, the mask as `.mask.png`.
    #[arg(long)]
    out: PathBuf,
    /// Leave dead leaves' remnants (dried sheath, blade stub) on the plant.
    #[arg(long)]
    dead_remnants: bool,
    /// Side-camera zoom (1: the calibrated field of view; the facility zooms
    /// some chambers about 2×).
    #[arg(long, default_value_t = 1.0)]
    zoom: f32,
}

/// The plant that `render` and `mesh` build: one set of options, so the
/// two commands take them alike.
#[derive(Args, Debug)]
struct PlantArgs {
    /// Preset name or .toml path.
    #[arg(long, default_value = "btx623")]
    preset: String,
    /// Plant seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Age in days after sowing.
    #[arg(long, default_value_t = 35.0)]
    age: f32,
}

/// Parses `I/N` with `I < N`.
pub fn parse_shard(s: &str) -> anyhow::Result<(u64, u64)> {
    let bad = || anyhow::anyhow!("--shard {s:?} must look like I/N with 0 <= I < N, e.g. 0/4");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (u64, u64) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// Parses a comma-separated view list.
pub fn parse_views(s: &str) -> anyhow::Result<Vec<View>> {
    let views = s
        .split(',')
        .filter(|v| !v.trim().is_empty())
        .map(View::parse)
        .collect::<anyhow::Result<Vec<_>>>()
        .context("--views")?;
    if views.is_empty() {
        bail!("--views is empty");
    }
    let mut names: Vec<String> = views.iter().map(View::name).collect();
    names.sort();
    names.dedup();
    if names.len() != views.len() {
        bail!("--views {s:?} lists a view twice");
    }
    Ok(views)
}

/// Loads presets from a comma-separated list, or all weighted built-ins.
pub fn parse_presets(s: Option<&str>) -> anyhow::Result<Vec<Preset>> {
    match s {
        Some(list) => {
            let v = list
                .split(',')
                .filter(|p| !p.trim().is_empty())
                .map(|p| load_weighted(p.trim()))
                .collect::<anyhow::Result<Vec<_>>>()
                .context("--preset")?;
            if v.is_empty() {
                bail!("--preset is empty");
            }
            if v.len() > 1 && v.iter().all(|p| p.weight == 0.0) {
                bail!("--preset: all listed presets have weight 0");
            }
            Ok(v)
        }
        None => Ok(Preset::builtins()?
            .into_iter()
            .filter(|p| p.weight > 0.0)
            .collect()),
    }
}

/// Sets every preset's `dead_remnant_chance` to `chance` when it is given.
fn with_dead_remnants(mut presets: Vec<Preset>, chance: Option<f32>) -> anyhow::Result<Vec<Preset>> {
    if let Some(p) = chance {
        if !(0.0..=1.0).contains(&p) {
            bail!("--dead-remnants {p} must lie in [0, 1]");
        }
        for preset in &mut presets {
            preset.growth.dead_remnant_chance = p;
        }
    }
    Ok(presets)
}

/// Loads one `--preset` entry: a name or path, optionally `:WEIGHT` to
/// override the preset's mixing weight (so `maize:0.5` mixes in maize, whose
/// built-in weight is 0).
fn load_weighted(entry: &str) -> anyhow::Result<Preset> {
    let (name, weight) = match entry.rsplit_once(':') {
        Some((n, w)) if !n.is_empty() && w.trim().parse::<f32>().is_ok() => {
            (n.trim(), Some(w.trim().parse::<f32>().expect("checked")))
        }
        _ => (entry, None),
    };
    let mut preset = Preset::load(name)?;
    if let Some(w) = weight {
        if !(w >= 0.0 && w.is_finite()) {
            bail!("preset `{name}`: weight must be a finite number >= 0, got {w}");
        }
        preset.weight = w;
    }
    Ok(preset)
}

fn quality(spp: u32) -> anyhow::Result<Quality> {
    if spp == 0 || spp > 4096 {
        bail!("--spp {spp} must lie in 1..=4096");
    }
    Ok(Quality {
        spp,
        ..Quality::default()
    })
}

fn check_age(age: f32) -> anyhow::Result<()> {
    if !(age.is_finite() && (0.0..=400.0).contains(&age)) {
        bail!("--age {age} must lie in 0..=400 days");
    }
    Ok(())
}

/// Runs a parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Dataset(cmd) => cmd.run(),
        Command::Sequence(cmd) => cmd.run(),
        Command::Bench {
            pairs,
            size,
            spp,
            seed,
        } => {
            if pairs == 0 {
                bail!("--pairs must be at least 1");
            }
            bench::run(pairs, size, quality(spp)?, seed)
        }
        Command::Render(cmd) => cmd.run(),
        Command::Mesh { plant, out } => mesh(&plant, &out),
        Command::Coco { dir } => coco(&dir),
        Command::Presets { files } => presets(files),
    }
}

impl DatasetCmd {
    /// Checks what clap cannot (ranges, preset, zoom and shard syntax), then runs.
    fn run(self) -> anyhow::Result<()> {
        let DatasetCmd {
            out,
            plants,
            seed,
            views,
            size,
            full_frame,
            val_fraction,
            preset,
            shard,
            spp,
            masks,
            dead_remnants,
            max_age,
            max_leaves,
            zoom,
            quiet,
        } = self;
        if !(16..=4096).contains(&size) {
            bail!("--size {size} must lie in 16..=4096");
        }
        let ages = sampling::AgeRange {
            max_age,
            max_leaves,
            ..Default::default()
        };
        if !(ages.max_age > ages.min_age && ages.max_age <= 365.0) {
            bail!("--max-age {max_age} must lie in ({}, 365] days", ages.min_age);
        }
        if ages.max_leaves < ages.min_leaves {
            bail!("--max-leaves {max_leaves} must be at least {}", ages.min_leaves);
        }
        if !(0.0..=1.0).contains(&val_fraction) {
            bail!("--val-fraction {val_fraction} must lie in [0, 1]");
        }
        dataset::run(&DatasetArgs {
            out,
            plants,
            seed,
            views: parse_views(&views)?,
            size,
            full_frame,
            val_fraction,
            presets: with_dead_remnants(parse_presets(preset.as_deref())?, dead_remnants)?,
            ages,
            zoom: sampling::ZoomRange::parse(&zoom).map_err(anyhow::Error::msg)?,
            shard: parse_shard(&shard)?,
            quality: quality(spp)?,
            masks,
            quiet,
        })
    }
}

impl SequenceCmd {
    /// Checks what clap cannot (age, date, presets, climate), then runs.
    fn run(self) -> anyhow::Result<()> {
        let SequenceCmd {
            out,
            plants,
            days,
            seed,
            start_date,
            start_age,
            interval,
            views,
            frame_height,
            preset,
            spp,
            labels,
            dead_remnants,
            climate,
            quiet,
        } = self;
        check_age(start_age).context("--start-age")?;
        sequence::run(&SequenceArgs {
            out,
            plants,
            days,
            seed,
            start: Date::parse(&start_date).context("--start-date")?,
            start_age,
            interval,
            views: parse_views(&views)?,
            frame_height,
            presets: with_dead_remnants(parse_presets(preset.as_deref())?, dead_remnants)?,
            quality: quality(spp)?,
            labels,
            climate: climate
                .as_deref()
                .map(ClimateSpec::parse)
                .transpose()
                .context("--climate")?,
            quiet,
        })
    }
}

impl RenderCmd {
    /// Renders the frame with its label and mask, and prints what it holds.
    fn run(self) -> anyhow::Result<()> {
        let RenderCmd {
            plant: PlantArgs { preset, seed, age },
            view,
            frame_height,
            spp,
            out,
            dead_remnants,
            zoom,
        } = self;
        check_age(age)?;
        sampling::ZoomRange::parse(&zoom.to_string()).map_err(anyhow::Error::msg)?;
        let mut preset = Preset::load(&preset)?;
        if dead_remnants {
            preset.growth.dead_remnant_chance = 1.0;
        }
        let view = View::parse(&view).context("--view")?;
        let traits = PlantTraits::sample(&preset, seed);
        let plant = Plant::build(&traits, age);
        let look = Look {
            zoom,
            ..Look::facility()
        };
        let stage = Stage::for_preset(&plant, &preset, &look);
        let scene = Scene::new(&stage, &look, view);
        let camera = render::camera_for(view, &look, frame_height);
        let img = render::render(
            &scene,
            &camera,
            &look,
            Window::frame(&camera),
            quality(spp)?,
            rng::derive(seed, "render", 0),
        )?;
        png_io::write_atomic(&out, &png_io::rgb_png(&img.rgb)?)?;
        png_io::write_atomic(&out.with_extension("label.png"), &png_io::label_png(&img.label)?)?;
        png_io::write_atomic(
            &out.with_extension("mask.png"),
            &png_io::rgb_png(&img.label.mask())?,
        )?;
        println!(
            "{}: preset {} age {age} d, {} living leaves ({} emerged), {} visible, {} triangles",
            out.display(),
            preset.name,
            plant.leaf_count(),
            plant.state.emerged,
            img.label.visible_leaf_count(),
            stage.triangles()
        );
        Ok(())
    }
}

/// The `mesh` command: one plant's mesh as OBJ.
fn mesh(plant: &PlantArgs, out: &Path) -> anyhow::Result<()> {
    let PlantArgs { preset, seed, age } = plant;
    check_age(*age)?;
    let preset = Preset::load(preset)?;
    let plant = Plant::build(&PlantTraits::sample(&preset, *seed), *age);
    let mesh = render::scene_mesh(&plant);
    let mut buf = Vec::new();
    mesh.write_obj(&mut buf)?;
    png_io::write_atomic(out, &buf)?;
    println!(
        "{}: {} leaves, {} triangles, {} groups",
        out.display(),
        plant.leaf_count(),
        mesh.tris.len(),
        mesh.groups.len()
    );
    Ok(())
}

/// The `coco` command.
fn coco(dir: &Path) -> anyhow::Result<()> {
    let summary = crate::coco::export(dir)?;
    for (split, n) in &summary.images {
        println!(
            "{split}: {n} images -> {}",
            dir.join("coco").join(format!("panoptic_{split}.json")).display()
        );
    }
    println!("{} segments", summary.segments);
    Ok(())
}

/// The `presets` command.
fn presets(files: Vec<PathBuf>) -> anyhow::Result<()> {
    if files.is_empty() {
        for p in Preset::builtins()? {
            println!(
                "{:10} {:8} weight {:.1}  {}",
                p.name, p.species, p.weight, p.description
            );
        }
    }
    for f in files {
        let p = Preset::load(&f.display().to_string())?;
        println!("{}: ok ({} {})", f.display(), p.name, p.species);
    }
    Ok(())
}

/// Entry point: parse, run, print errors with their causes.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("phyllo-gen: error: {e:#}");
            ExitCode::from(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_weights_can_be_overridden() {
        let v = parse_presets(Some("btx623, maize:0.5")).unwrap();
        assert_eq!(v.len(), 2);
        assert_eq!((v[0].name.as_str(), v[0].weight), ("btx623", 1.0));
        assert_eq!((v[1].name.as_str(), v[1].weight), ("maize", 0.5));
        let err = format!("{:#}", parse_presets(Some("maize:-1")).unwrap_err());
        assert!(err.contains("weight"), "{err}");
        assert!(parse_presets(Some("nosuch:1")).is_err());
        let kept = with_dead_remnants(parse_presets(Some("btx623,maize:1")).unwrap(), Some(0.25)).unwrap();
        assert!(kept.iter().all(|p| p.growth.dead_remnant_chance == 0.25));
        let default = with_dead_remnants(parse_presets(Some("maize")).unwrap(), None).unwrap();
        assert_eq!(default[0].growth.dead_remnant_chance, 0.0);
        let err = format!("{:#}", with_dead_remnants(default, Some(1.5)).unwrap_err());
        assert!(err.contains("--dead-remnants 1.5"), "{err}");
    }
}
