//! Export of a phyllo-gen dataset in COCO panoptic format, so the same data
//! also trains with detectron2 or mmdetection.
//!
//! For every split this writes `DIR/coco/panoptic_<split>.json` and one RGB
//! PNG per image in `DIR/coco/panoptic_<split>/`. A segment's id is the
//! contract label value (`class * 1000 + instance`), which is unique within
//! an image and never 0 (COCO's "void"); it is stored in the PNG as
//! `R + 256 G + 256² B`. Images are referenced by their path relative to the
//! dataset folder, so `DIR` is the image root.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use phyllo_contract::{Contract, BACKGROUND};
use serde_json::{json, Value};

use crate::png_io::{rgb_png, write_atomic};

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CocoSummary {
    /// Images per split.
    pub images: BTreeMap<String, usize>,
    /// Segments over all images.
    pub segments: usize,
}

/// COCO categories: every contract class but the background.
fn categories(c: &Contract) -> Vec<Value> {
    c.classes
        .ids
        .iter()
        .filter(|&&id| id != BACKGROUND)
        .map(|&id| {
            json!({
                "id": id,
                "name": c.classes.names[id as usize],
                "supercategory": "plant",
                "isthing": u8::from(c.is_thing(id)),
                "color": c.mask_colour(id, 1),
            })
        })
        .collect()
}

/// Converts the dataset in `dir` (its `manifest.jsonl` and labels).
pub fn export(dir: &Path) -> anyhow::Result<CocoSummary> {
    let c = Contract::embedded();
    let manifest = dir.join("manifest.jsonl");
    let text =
        std::fs::read_to_string(&manifest).with_context(|| format!("reading {}", manifest.display()))?;
    let mut splits: BTreeMap<String, (Vec<Value>, Vec<Value>)> = BTreeMap::new();
    let mut segments = 0;
    for (n, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let row: Value = serde_json::from_str(line)
            .with_context(|| format!("{} line {}: not JSON", manifest.display(), n + 1))?;
        let field = |k: &str| {
            row[k]
                .as_str()
                .map(str::to_string)
                .with_context(|| format!("{} line {}: no {k:?}", manifest.display(), n + 1))
        };
        let (image, label, split) = (field("image")?, field("label")?, field("split")?);
        let label_path = dir.join(&label);
        let lab = image::open(&label_path)
            .with_context(|| format!("reading label {}", label_path.display()))?
            .into_luma16();
        let (w, h) = lab.dimensions();
        let mut rgb = image::RgbImage::new(w, h);
        // id -> (area, x0, y0, x1, y1)
        let mut stats: BTreeMap<u16, (u64, u32, u32, u32, u32)> = BTreeMap::new();
        for (x, y, p) in lab.enumerate_pixels() {
            let v = p.0[0];
            let (class, _) = c.decode_label(v);
            if class == BACKGROUND {
                continue;
            }
            if usize::from(class) >= c.classes.names.len() {
                bail!(
                    "{}: pixel ({x}, {y}) has label {v}, not a contract class",
                    label_path.display()
                );
            }
            rgb.put_pixel(x, y, image::Rgb([(v % 256) as u8, (v / 256) as u8, 0]));
            let s = stats.entry(v).or_insert((0, x, y, x, y));
            *s = (s.0 + 1, s.1.min(x), s.2.min(y), s.3.max(x), s.4.max(y));
        }
        let stem = Path::new(&image)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let png_name = format!("{stem}.png");
        let png_path: PathBuf = dir.join("coco").join(format!("panoptic_{split}")).join(&png_name);
        write_atomic(&png_path, &rgb_png(&rgb)?)?;
        let infos: Vec<Value> = stats
            .iter()
            .map(|(&id, &(area, x0, y0, x1, y1))| {
                json!({
                    "id": id,
                    "category_id": c.decode_label(id).0,
                    "iscrowd": 0,
                    "area": area,
                    "bbox": [x0, y0, x1 - x0 + 1, y1 - y0 + 1],
                })
            })
            .collect();
        segments += infos.len();
        let entry = splits.entry(split).or_default();
        let image_id = entry.0.len() as u64 + 1;
        entry
            .0
            .push(json!({"id": image_id, "file_name": image, "width": w, "height": h}));
        entry
            .1
            .push(json!({"image_id": image_id, "file_name": png_name, "segments_info": infos}));
    }
    if splits.is_empty() {
        bail!("{} has no rows", manifest.display());
    }
    let mut images = BTreeMap::new();
    for (split, (imgs, anns)) in splits {
        images.insert(split.clone(), imgs.len());
        let doc = json!({
            "info": {"description": "phyllo-gen synthetic sorghum, panoptic labels", "contract_version": c.version},
            "images": imgs,
            "annotations": anns,
            "categories": categories(c),
        });
        let path = dir.join("coco").join(format!("panoptic_{split}.json"));
        write_atomic(&path, serde_json::to_string(&doc)?.as_bytes())?;
    }
    Ok(CocoSummary { images, segments })
}
