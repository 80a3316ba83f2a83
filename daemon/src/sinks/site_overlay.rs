//! `phyllo timeline PLANT --sites DIR`: where each new leaf emerged, drawn
//! on the image it was found in: a red box round the leaf instance and a
//! cross on its predicted centre, one PNG per located leaf
//! (`<plant>-leaf-<NN>.png`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use image::Rgb;
use imageproc::drawing::{draw_hollow_rect_mut, draw_line_segment_mut};
use imageproc::rect::Rect;

use crate::store::PlantTimeline;

const RED: Rgb<u8> = Rgb([230, 20, 20]);

/// Draws every located leaf of `t` from the images under `drop_dir` into
/// `dir`; returns the files written. A missing or unreadable image is an
/// error naming it (the drop directory may have been cleaned since).
pub fn draw_sites(t: &PlantTimeline, drop_dir: &Path, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    for site in &t.sites {
        let src = drop_dir.join(&site.image);
        let mut img = image::open(&src)
            .with_context(|| format!("leaf {} of {}: reading {}", site.leaf, t.plant, src.display()))?
            .to_rgb8();
        let [x0, y0, x1, y1] = site.bbox;
        // A few pixels of margin, so the box does not hide the leaf's edge.
        let pad = (img.width().max(img.height()) / 400).max(2);
        for k in 0..3 {
            let (x, y) = (x0.saturating_sub(pad + k), y0.saturating_sub(pad + k));
            let (w, h) = (x1 - x0 + 2 * (pad + k), y1 - y0 + 2 * (pad + k));
            draw_hollow_rect_mut(
                &mut img,
                Rect::at(x as i32, y as i32).of_size(w.max(1), h.max(1)),
                RED,
            );
        }
        let (cx, cy) = (site.centre[0] as f32, site.centre[1] as f32);
        let a = (pad * 3) as f32;
        draw_line_segment_mut(&mut img, (cx - a, cy), (cx + a, cy), RED);
        draw_line_segment_mut(&mut img, (cx, cy - a), (cx, cy + a), RED);
        let out = dir.join(format!(
            "{}-leaf-{:02}.png",
            super::plot::file_stem(&t.plant),
            site.leaf
        ));
        super::atomic::replace(&out, ".png", |tmp| {
            img.save_with_format(tmp, image::ImageFormat::Png)
                .with_context(|| format!("writing {}", out.display()))
        })?;
        written.push(out);
    }
    Ok(written)
}
