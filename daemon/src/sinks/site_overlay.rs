//! `phyllo timeline PLANT --sites DIR`: where each new leaf emerged, drawn
//! on the image it was found in: a red box round the leaf instance and a
//! cross on its predicted centre, on a square of the frame around it
//! (a third of the frame's height at least) enlarged to at least
//! [`MIN_SIDE`] pixels, so a seedling's first leaves are not specks; one
//! PNG per located leaf (`<plant>-leaf-<NN>.png`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use image::{imageops, Rgb, RgbImage};
use imageproc::drawing::{draw_hollow_rect_mut, draw_line_segment_mut};
use imageproc::rect::Rect;

use crate::store::PlantTimeline;

const RED: Rgb<u8> = Rgb([230, 20, 20]);
/// Smallest side of a drawn square, pixels.
pub const MIN_SIDE: u32 = 480;

/// Draws every located leaf of `t` from the images under `drop_dir` into
/// `dir`; returns the files written. A missing or unreadable image (the
/// drop directory may have been cleaned since) does not stop the others: the
/// error, after them, names each.
pub fn draw_sites(t: &PlantTimeline, drop_dir: &Path, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    crate::files::owner::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    let mut unreadable = Vec::new();
    for site in &t.sites {
        let src = drop_dir.join(crate::domain::rel_path::decode(&site.image));
        // Decoded as counted (EXIF orientation applied), so the leaf's box lands on it.
        let full = match phyllo_inference::decode::read_rgb(&src) {
            Ok(img) => img,
            Err(e) => {
                unreadable.push(format!("leaf {}: {}: {e}", site.leaf, src.display()));
                continue;
            }
        };
        let img = draw(&full, site.bbox, site.centre);
        let out = dir.join(format!(
            "{}-leaf-{:02}.png",
            super::plot::file_stem(&t.plant),
            site.leaf
        ));
        write_png(&img, &out)?;
        written.push(out);
    }
    if !unreadable.is_empty() {
        anyhow::bail!(
            "{} of {} new leaves of {} drawn into {}; {} images could not be read:\n  {}",
            written.len(),
            t.sites.len(),
            t.plant,
            dir.display(),
            unreadable.len(),
            unreadable.join("\n  ")
        );
    }
    Ok(written)
}

/// What [`draw_newest`] did.
#[derive(Debug, Default)]
pub struct NewestSites {
    /// Plant id → (its newest placed leaf, that leaf's PNG under the folder).
    pub files: std::collections::BTreeMap<String, (u32, String)>,
    /// PNGs drawn this time (the others were there already).
    pub drawn: usize,
    /// Plants whose image has left the drop directory (nothing drawn).
    pub gone: usize,
}

/// Draws each plant's newest placed leaf into `dir` for the nightly export,
/// only what is not there yet: a file's name carries a digest of its image
/// and box, so a site that moves (a refit) is drawn again, and files of sites
/// that no longer exist are removed.
pub fn draw_newest(timelines: &[PlantTimeline], drop_dir: &Path, dir: &Path) -> anyhow::Result<NewestSites> {
    crate::files::owner::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut done = NewestSites::default();
    for t in timelines {
        let Some(site) = t.sites.iter().max_by_key(|s| s.leaf) else {
            continue;
        };
        let digest = crate::files::sha256_hex(format!("{}|{:?}", site.image, site.bbox).as_bytes());
        let name = format!(
            "{}-leaf-{:02}-{}.png",
            super::plot::file_stem(&t.plant),
            site.leaf,
            &digest[..8]
        );
        let out = dir.join(&name);
        if !out.exists() {
            let src = drop_dir.join(crate::domain::rel_path::decode(&site.image));
            let Ok(full) = phyllo_inference::decode::read_rgb(&src) else {
                done.gone += 1;
                continue;
            };
            let img = draw(&full, site.bbox, site.centre);
            write_png(&img, &out)?;
            done.drawn += 1;
        }
        done.files.insert(t.plant.clone(), (site.leaf, name));
    }
    let keep: std::collections::HashSet<&str> = done.files.values().map(|(_, n)| n.as_str()).collect();
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if name.ends_with(".png") && name.contains("-leaf-") && !keep.contains(name) {
            std::fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
        }
    }
    Ok(done)
}

/// Writes `img` to `out` as PNG, renamed into place whole.
fn write_png(img: &RgbImage, out: &Path) -> anyhow::Result<()> {
    crate::files::atomic::replace(out, ".png", |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .with_context(|| format!("writing {}", out.display()))
    })
}

/// The square around a leaf's box `bbox` (centre `centre`) cut from `full`,
/// enlarged to at least [`MIN_SIDE`], with the box and centre drawn.
fn draw(full: &RgbImage, bbox: [u32; 4], centre: [f64; 2]) -> RgbImage {
    let (w, h) = full.dimensions();
    let [x0, y0, x1, y1] = bbox;
    let side = (h / 3)
        .max(6 * x1.saturating_sub(x0).max(y1.saturating_sub(y0)))
        .min(w.min(h))
        .max(1);
    let cx = ((x0 + x1) / 2).saturating_sub(side / 2).min(w - side);
    let cy = ((y0 + y1) / 2).saturating_sub(side / 2).min(h - side);
    let crop = imageops::crop_imm(full, cx, cy, side, side).to_image();
    let scale = (f64::from(MIN_SIDE) / f64::from(side)).max(1.0);
    let out_side = (f64::from(side) * scale).round() as u32;
    let mut img = imageops::resize(&crop, out_side, out_side, imageops::FilterType::Triangle);
    let at = |v: u32, o: u32| (f64::from(v.saturating_sub(o)) * scale) as i32;
    // A few pixels of margin, so the box does not hide the leaf's edge.
    let pad = 3;
    for k in 0..3 {
        let (bx, by) = (at(x0, cx) - pad - k, at(y0, cy) - pad - k);
        let (bw, bh) = (
            at(x1, cx) - at(x0, cx) + 2 * (pad + k),
            at(y1, cy) - at(y0, cy) + 2 * (pad + k),
        );
        draw_hollow_rect_mut(
            &mut img,
            Rect::at(bx, by).of_size(bw.max(1) as u32, bh.max(1) as u32),
            RED,
        );
    }
    let (px, py) = (
        ((centre[0] - f64::from(cx)) * scale) as f32,
        ((centre[1] - f64::from(cy)) * scale) as f32,
    );
    let a = 8.0;
    draw_line_segment_mut(&mut img, (px - a, py), (px + a, py), RED);
    draw_line_segment_mut(&mut img, (px, py - a), (px, py + a), RED);
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timeline(plant: &str, image: &str, leaf: u32) -> PlantTimeline {
        PlantTimeline {
            plant: plant.into(),
            phyllochron_days: None,
            phyllochron_cd: None,
            climate_zone: String::new(),
            next_leaf: None,
            sessions: Vec::new(),
            events: Vec::new(),
            sites: vec![crate::store::LeafSiteRow {
                leaf,
                view: "SV_0".into(),
                image: image.into(),
                centre: [30.0, 30.0],
                bbox: [25, 25, 35, 35],
                area: 60,
            }],
        }
    }

    #[test]
    fn a_missing_image_is_named_and_the_other_leaves_still_drawn() {
        let drop = tempfile::tempdir().unwrap();
        let out = tempfile::tempdir().unwrap();
        RgbImage::from_pixel(64, 64, Rgb([200, 200, 200]))
            .save(drop.path().join("a.png"))
            .unwrap();
        let mut t = timeline("P1", "gone.png", 4);
        t.sites.extend(timeline("P1", "a.png", 5).sites);
        let err = draw_sites(&t, drop.path(), out.path()).unwrap_err().to_string();
        assert!(
            err.contains("1 of 2 new leaves of P1") && err.contains("leaf 4: ") && err.contains("gone.png"),
            "{err}"
        );
        assert!(out.path().join("P1-leaf-05.png").exists());
    }

    #[test]
    fn the_nightly_sites_draw_only_what_is_new_and_drop_what_moved() {
        let drop = tempfile::tempdir().unwrap();
        let out = tempfile::tempdir().unwrap();
        RgbImage::from_pixel(64, 64, Rgb([200, 200, 200]))
            .save(drop.path().join("a.png"))
            .unwrap();
        let first = draw_newest(
            &[timeline("P1", "a.png", 5), timeline("P2", "gone.png", 3)],
            drop.path(),
            out.path(),
        )
        .unwrap();
        assert_eq!((first.drawn, first.gone), (1, 1));
        let (leaf, name) = first.files["P1"].clone();
        assert!(leaf == 5 && name.starts_with("P1-leaf-05-"), "{name}");
        // Nothing new: nothing drawn.
        let again = draw_newest(&[timeline("P1", "a.png", 5)], drop.path(), out.path()).unwrap();
        assert_eq!(again.drawn, 0);
        // A newer leaf replaces the old file.
        let newer = draw_newest(&[timeline("P1", "a.png", 6)], drop.path(), out.path()).unwrap();
        assert_eq!(newer.drawn, 1);
        let names: Vec<String> = std::fs::read_dir(out.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, vec![newer.files["P1"].1.clone()]);
    }

    #[test]
    fn a_small_leaf_is_drawn_enlarged_on_a_square_round_it() {
        let full = RgbImage::from_pixel(614, 514, Rgb([255, 255, 255]));
        let img = draw(&full, [300, 350, 310, 380], [305.0, 365.0]);
        // 514 / 3 = 171 px of frame, enlarged to at least 480.
        assert_eq!(img.width(), img.height());
        assert!(img.width() >= MIN_SIDE, "{}", img.width());
        assert!(img.pixels().any(|p| *p == RED));
        // A box stored upside down draws, rather than taking the service down.
        let odd = draw(&full, [310, 380, 300, 350], [305.0, 365.0]);
        assert!(odd.width() >= MIN_SIDE);
        // A box near the frame's corner keeps its square inside the frame.
        let corner = draw(&full, [600, 500, 612, 512], [606.0, 506.0]);
        assert_eq!(corner.width(), corner.height());
    }
}
