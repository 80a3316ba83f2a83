//! `phyllo-gen dataset`: image + label pairs with a JSON-lines manifest.
//!
//! Layout under the output folder: `images/`, `labels/` (16-bit panoptic
//! PNG), optional `masks/`, `meta/` (one finished-item record each) and
//! `manifest.jsonl`. An item is finished when its meta record exists; the
//! record is written last and atomically, so a re-run skips finished items
//! and redoes interrupted ones. With `--shard I/N` only plants with
//! `index % N == I` are rendered and the manifest is
//! `manifest.shard-I-of-N.jsonl`; the union of all shards equals an
//! unsharded run byte for byte (re-running unsharded then only writes
//! `manifest.jsonl`).

use crate::plant::{growth::PlantTraits, preset::Preset, Plant};
use crate::render::{self, look::Look, Quality, Scene, Stage, View};
use crate::{png_io, rng, sampling, tips};
use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Settings of a dataset run.
#[derive(Debug, Clone)]
pub struct DatasetArgs {
    /// Output folder.
    pub out: PathBuf,
    /// Number of plants.
    pub plants: u64,
    /// Master seed.
    pub seed: u64,
    /// Views rendered per plant.
    pub views: Vec<View>,
    /// Side of the square training crop.
    pub size: u32,
    /// Whole side frames instead of `size` crops (top views stay crops).
    pub full_frame: bool,
    /// Fraction of plants held out for validation.
    pub val_fraction: f32,
    /// Presets to draw from (weighted).
    pub presets: Vec<Preset>,
    /// Ages and living-leaf counts the plants are drawn from.
    pub ages: sampling::AgeRange,
    /// Side-camera zooms the plants are drawn with.
    pub zoom: sampling::ZoomRange,
    /// This shard `(i, n)`.
    pub shard: (u64, u64),
    /// Sampling quality.
    pub quality: Quality,
    /// Write human-viewable masks too.
    pub masks: bool,
    /// No progress bar.
    pub quiet: bool,
}

/// One manifest row.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Row {
    /// RGB image, relative to the dataset folder.
    pub image: String,
    /// Panoptic label, relative to the dataset folder.
    pub label: String,
    /// Plant index.
    pub plant: u64,
    /// View name (`0`, `36`, ..., `top`).
    pub view: String,
    /// Genotype preset.
    pub preset: String,
    /// Plant age in days after sowing.
    pub age_days: f32,
    /// Living leaves on the plant.
    pub leaf_count: usize,
    /// Distinct leaf instances in this label.
    pub visible_leaf_count: usize,
    /// Leaves emerged so far (dead ones included).
    pub leaves_emerged: usize,
    /// `train` or `val`.
    pub split: String,
    /// The dataset's master seed.
    pub seed: u64,
    /// Pixels of each leaf instance in the label.
    pub leaf_pixels: std::collections::BTreeMap<u16, u32>,
    /// Crop origin in camera-frame pixels (frame is `frame` wide/high).
    pub crop: [i32; 2],
    /// Camera frame size the crop was taken from.
    pub frame: [u32; 2],
    /// The generator that rendered it: `phyllo-gen <version> (<git commit>)`.
    /// Empty in datasets written before this field existed.
    #[serde(default)]
    pub generator: String,
    /// Apparent tip of each visible leaf instance (keys as in `leaf_pixels`), as (x, y) in
    /// the written image's pixels (pixel (i, j) spans [i, i+1) x [j, j+1)): the projected
    /// end of the blade's midrib where the label shows that leaf at it, otherwise the centre
    /// of the leaf's label pixel nearest to it (see [`crate::tips`]). Empty in datasets
    /// written before this field existed.
    #[serde(default)]
    pub leaf_tips: std::collections::BTreeMap<u16, [f32; 2]>,
    /// Distance in image pixels from each leaf's projected tip (clamped into
    /// the image) to its apparent tip in `leaf_tips`: near 0 when the tip can
    /// be seen, large when it is hidden (see [`crate::tips::tip_gaps`]).
    /// Empty in datasets written before this field existed.
    #[serde(default)]
    pub leaf_tip_gaps: std::collections::BTreeMap<u16, f32>,
    /// How rolled each visible leaf still is (keys as in `leaf_pixels`): 1 =
    /// furled in the whorl, 0 = open (the growth model's `furl`, to 0.01).
    /// Lets a truth rule tell the whorl's leaves from expanded ones (the real
    /// crops' counts look like expanded leaves only). Empty in older datasets.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub leaf_furl: std::collections::BTreeMap<u16, f32>,
    /// Dead leaves whose remnants (dried sheath, blade stub, labelled stem)
    /// are on the plant; see the preset's `dead_remnant_chance`. Omitted when
    /// 0, so manifests without remnants read as before.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub dead_remnants: usize,
    /// The side camera's zoom (1 for top views). Omitted at 1, so manifests
    /// of unzoomed sets read and write as before.
    #[serde(default = "unit_zoom", skip_serializing_if = "is_unit_zoom")]
    pub zoom: f32,
}

/// The growth model's furl of each visible leaf instance, rounded to 0.01.
fn leaf_furl(
    plant: &crate::plant::Plant,
    visible: &std::collections::BTreeMap<u16, u32>,
) -> std::collections::BTreeMap<u16, f32> {
    visible
        .keys()
        .filter_map(|&k| {
            let leaf = plant.state.leaves.get(usize::from(k).checked_sub(1)?)?;
            Some((k, (leaf.furl * 100.0).round() / 100.0))
        })
        .collect()
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

fn unit_zoom() -> f32 {
    1.0
}

fn is_unit_zoom(z: &f32) -> bool {
    *z == 1.0
}

/// This build's `Row::generator` value.
pub fn generator_id() -> String {
    format!(
        "phyllo-gen {} ({})",
        env!("CARGO_PKG_VERSION"),
        env!("PHYLLO_GEN_COMMIT")
    )
}

fn item_name(plant: u64, view: &View) -> String {
    format!("p{plant:06}_{}", view.name())
}

/// Runs the dataset command.
pub fn run(args: &DatasetArgs) -> anyhow::Result<()> {
    if args.plants == 0 {
        bail!("--plants must be at least 1");
    }
    if args.views.is_empty() {
        bail!("--views is empty");
    }
    let (si, sn) = args.shard;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output folder {}", args.out.display()))?;
    let mine: Vec<u64> = (0..args.plants).filter(|p| p % sn == si).collect();
    let total = mine.len() as u64 * args.views.len() as u64;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} pairs  {per_sec}  eta {eta}  {msg}")
            .expect("valid template"),
    );
    let todo: Vec<(u64, Vec<&View>)> = mine
        .iter()
        .map(|&p| {
            let pending: Vec<&View> = args
                .views
                .iter()
                .filter(|v| !meta_path(&args.out, p, v).exists())
                .collect();
            (p, pending)
        })
        .collect();
    bar.inc(
        todo.iter()
            .map(|(_, v)| (args.views.len() - v.len()) as u64)
            .sum(),
    );
    // Plants render side by side: each one's serial work (growing the mesh,
    // building its BVH, encoding PNGs) then overlaps other plants' pixels
    // instead of idling the other cores. Every item is seeded by its plant
    // and view, so the files do not depend on the order.
    todo.par_iter()
        .filter(|(_, pending)| !pending.is_empty())
        .try_for_each(|(p, pending)| render_plant(args, *p, pending, &bar))?;
    let mut rows = Vec::new();
    for &p in &mine {
        for v in &args.views {
            let path = meta_path(&args.out, p, v);
            let text =
                std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
            rows.push(
                serde_json::from_str::<Row>(&text).with_context(|| format!("parsing {}", path.display()))?,
            );
        }
    }
    bar.finish_and_clear();
    let name = if sn == 1 {
        "manifest.jsonl".to_string()
    } else {
        format!("manifest.shard-{si}-of-{sn}.jsonl")
    };
    let mut text = String::new();
    for r in &rows {
        text.push_str(&serde_json::to_string(r)?);
        text.push('\n');
    }
    png_io::write_atomic(&args.out.join(&name), text.as_bytes())?;
    if !args.quiet {
        eprintln!("wrote {} rows to {}", rows.len(), args.out.join(name).display());
    }
    Ok(())
}

fn meta_path(out: &Path, plant: u64, view: &View) -> PathBuf {
    out.join("meta").join(format!("{}.json", item_name(plant, view)))
}

/// Everything decided about one dataset plant.
pub struct PlantPlan {
    /// The preset it was drawn from.
    pub preset: Preset,
    /// Its traits.
    pub traits: PlantTraits,
    /// Age in days.
    pub age: f32,
    /// Its look.
    pub look: Look,
}

/// Plans dataset plant `index` from the master seed: the same inputs always
/// give the same plant, whatever else the run renders.
pub fn plan_plant(
    presets: &[Preset],
    ages: &sampling::AgeRange,
    zoom: &sampling::ZoomRange,
    seed: u64,
    index: u64,
) -> PlantPlan {
    let preset = sampling::pick_preset(presets, seed, index).clone();
    let traits = PlantTraits::sample(&preset, rng::derive(seed, "plant", index));
    let age = sampling::pick_age(&traits, seed, index, ages);
    let mut look = Look::randomised(rng::derive(seed, "look", index));
    look.zoom = zoom.pick(seed, index);
    PlantPlan {
        preset,
        traits,
        age,
        look,
    }
}

fn render_plant(args: &DatasetArgs, p: u64, views: &[&View], bar: &ProgressBar) -> anyhow::Result<()> {
    let plan = plan_plant(&args.presets, &args.ages, &args.zoom, args.seed, p);
    let plant = Plant::build(&plan.traits, plan.age);
    let stage = Stage::for_preset(&plant, &plan.preset, &plan.look);
    let split = if sampling::is_val(args.seed, p, args.val_fraction) {
        "val"
    } else {
        "train"
    };
    let render_seed = rng::derive(args.seed, "render", p);
    for view in views {
        let scene = Scene::new(&stage, &plan.look, **view);
        let camera = render::camera_for(
            **view,
            &plan.look,
            phyllo_contract::Contract::embedded().input.frame_height,
        );
        let window = match **view {
            View::Side(_) if args.full_frame => render::Window::frame(&camera),
            _ => sampling::crop_window(&scene, &camera, **view, args.size),
        };
        let seed = rng::derive(render_seed, &view.name(), 0);
        let out = render::render(&scene, &camera, &plan.look, window, args.quality, seed)?;
        let name = item_name(p, view);
        let (img_png, lab_png) = rayon::join(|| png_io::rgb_png(&out.rgb), || png_io::label_png(&out.label));
        let image = format!("images/{name}.png");
        let label = format!("labels/{name}.png");
        png_io::write_atomic(&args.out.join(&image), &img_png?)?;
        png_io::write_atomic(&args.out.join(&label), &lab_png?)?;
        if args.masks {
            png_io::write_atomic(
                &args.out.join(format!("masks/{name}.png")),
                &png_io::rgb_png(&out.label.mask())?,
            )?;
        }
        let leaf_pixels = out.label.leaf_pixels();
        let leaf_furl = leaf_furl(&plant, &leaf_pixels);
        let (leaf_tips, leaf_tip_gaps) = tips::leaf_tips(&plant, &scene, &camera, window, &out.label);
        let row = Row {
            image,
            label,
            plant: p,
            view: view.name(),
            preset: plan.preset.name.clone(),
            age_days: plan.age,
            leaf_count: plant.leaf_count(),
            visible_leaf_count: leaf_pixels.len(),
            leaves_emerged: plant.state.emerged,
            split: split.into(),
            seed: args.seed,
            leaf_pixels,
            crop: [window.x0, window.y0],
            frame: [camera.width, camera.height],
            generator: generator_id(),
            leaf_furl,
            leaf_tips,
            leaf_tip_gaps,
            dead_remnants: plant.state.remnants.len(),
            zoom: match view {
                View::Side(_) => plan.look.zoom,
                View::Top => 1.0,
            },
        };
        png_io::write_atomic(
            &meta_path(&args.out, p, view),
            serde_json::to_string(&row)?.as_bytes(),
        )?;
        bar.set_message(format!("plant {p} {}", plan.preset.name));
        bar.inc(1);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_and_older_rows_without_tips_still_parse() {
        let old = r#"{"image":"images/p000000_108.png","label":"labels/p000000_108.png","plant":0,
            "view":"108","preset":"tx3197","age_days":35.0,"leaf_count":8,"visible_leaf_count":3,
            "leaves_emerged":8,"split":"train","seed":4,"leaf_pixels":{"1":10,"2":14,"3":29},
            "crop":[81,2],"frame":[614,514]}"#;
        let mut row: Row = serde_json::from_str(old).unwrap();
        assert!(row.leaf_tips.is_empty() && row.generator.is_empty());
        assert_eq!(row.leaf_pixels.len(), 3);
        row.leaf_tips = [(1, [10.25, 3.5]), (2, [0.5, 511.5]), (3, [200.125, 17.0])].into();
        let text = serde_json::to_string(&row).unwrap();
        assert!(
            text.contains(r#""leaf_tips":{"1":[10.25,3.5],"2":[0.5,511.5],"3":[200.125,17.0]}"#),
            "{text}"
        );
        assert_eq!(serde_json::from_str::<Row>(&text).unwrap(), row);
    }

    #[test]
    fn leaf_furl_covers_the_visible_leaves_and_young_leaves_are_rolled() {
        let preset = crate::plant::preset::Preset::load("btx623").unwrap();
        let traits = crate::plant::growth::PlantTraits::sample(&preset, 11);
        let plant = crate::plant::Plant::build(&traits, 30.0);
        let n = plant.state.leaves.len() as u16;
        // Leaf 2 and the youngest leaf are visible; an instance past the plant's leaves is ignored.
        let visible = [(2, 50), (n, 9), (n + 1, 4)].into();
        let furl = leaf_furl(&plant, &visible);
        assert_eq!(furl.keys().copied().collect::<Vec<_>>(), vec![2, n]);
        assert_eq!(furl[&2], 0.0, "a low leaf is open");
        assert!(
            furl[&n] > 0.5,
            "the youngest leaf is still in the whorl: {}",
            furl[&n]
        );
        assert!(furl.values().all(|f| (0.0..=1.0).contains(f)));
    }
}
