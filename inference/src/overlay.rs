//! Overlays for a person to check a count: instances in distinct colours over
//! the original image (neighbouring leaf numbers far apart in hue), each
//! leaf's centre marked with a black-edged white cross and its number (from
//! the base upward), leaf tips marked (white-ringed dots, models with a tip
//! output), the count written in the corner, and the back panel's measured
//! edges dashed in yellow, with a line saying so.

use std::path::Path;

use font8x8::UnicodeFonts;
use image::{Rgb, RgbImage};
use phyllo_contract::Contract;

use crate::counter::Analysis;
use crate::{Counter, InferenceError};

/// Draws `analysis` over `img` (the original image it was computed from).
pub fn render(contract: &Contract, img: &RgbImage, analysis: &Analysis, untrained: bool) -> RgbImage {
    let mut out = img.clone();
    let pan = &analysis.panoptic;
    let canvas = &analysis.canvas;
    let s = contract.outputs.stride as f32;
    for (x, y, p) in out.enumerate_pixels_mut() {
        let cx = (x as f32 + 0.5) * canvas.scale - canvas.origin[0] as f32;
        let cy = (y as f32 + 0.5) * canvas.scale - canvas.origin[1] as f32;
        if cx < 0.0 || cy < 0.0 {
            continue;
        }
        let (ox, oy) = ((cx / s) as usize, (cy / s) as usize);
        if ox >= pan.width || oy >= pan.height {
            continue;
        }
        let id = pan.instance[oy * pan.width + ox];
        if id == 0 {
            continue;
        }
        let class = pan.segments[id as usize - 1].class;
        let colour = if class == phyllo_contract::LEAF {
            leaf_colour(id)
        } else {
            contract.mask_colour(class, id as u16)
        };
        for (v, col) in p.0.iter_mut().zip(colour) {
            *v = ((u16::from(*v) + 2 * u16::from(col)) / 3) as u8;
        }
    }
    let mark = (img.width().max(img.height()) / 300).max(2) as i64;
    let number_scale = (mark as u32 / 2).max(1);
    for (k, inst) in from_the_base(&analysis.result.instances).into_iter().enumerate() {
        let (x, y) = (inst.centre[0] as i64, inst.centre[1] as i64);
        mark_centre(&mut out, x, y, mark);
        // The leaf's number just right of its cross, as a person reads the count.
        let (nx, ny) = (
            (x + 2 * mark + 2).max(0) as u32,
            (y - 6 * number_scale as i64).max(0) as u32,
        );
        text(&mut out, &(k + 1).to_string(), nx, ny, number_scale);
    }
    // Leaf tips (models with a tip output): a dark dot in a white ring, small
    // enough not to hide the leaf's end, distinct from the centres' crosses.
    let ring = mark + 1;
    for tip in &analysis.result.tips {
        let (x, y) = (tip[0] as i64, tip[1] as i64);
        for dy in -ring..=ring {
            for dx in -ring..=ring {
                let d2 = dx * dx + dy * dy;
                if d2 <= (mark - 1).max(1).pow(2) {
                    put(&mut out, x + dx, y + dy, Rgb([200, 0, 160]));
                } else if d2 <= ring * ring {
                    put(&mut out, x + dx, y + dy, Rgb([255, 255, 255]));
                }
            }
        }
    }
    let mut label = format!("{} leaves", analysis.result.leaf_count);
    if !analysis.result.tips.is_empty() {
        label.push_str(&format!(", {} tips", analysis.result.tips.len()));
    }
    if let Some(camera) = &analysis.result.camera {
        if let Some(panel) = &camera.panel {
            mark_panel(&mut out, panel.left, panel.right, mark);
        }
        if camera.camera_zoom != 1.0 {
            label.push_str(&format!(", zoom {:.2}", camera.camera_zoom));
        }
    }
    if untrained {
        label.push_str(" (UNTRAINED MODEL)");
    }
    let scale = (img.height() / 160).clamp(2, 8);
    text(&mut out, &label, 8, 8, scale);
    if analysis.result.camera.as_ref().is_some_and(|c| c.panel.is_some()) {
        // Small enough to fit a half-size crop's width.
        let legend = "yellow dashes: back panel edges (zoom measured on them)";
        text(&mut out, legend, 8, 8 + 13 * scale, (scale / 3).max(1));
    }
    out
}

/// The instances in the order a person counts a plant: from the base
/// upward, by where each reaches lowest (the leaf's base, or its drooping
/// tip), so leaf 1 is the lowest and the numbers climb the plant.
fn from_the_base(instances: &[crate::result::Instance]) -> Vec<&crate::result::Instance> {
    let mut order: Vec<&crate::result::Instance> = instances.iter().collect();
    order.sort_by(|a, b| {
        b.bbox[3]
            .cmp(&a.bbox[3])
            .then(a.centre[0].total_cmp(&b.centre[0]))
    });
    order
}

/// Marks the back panel's measured edges (what the camera zoom was measured
/// on) with dashed yellow lines over the frame's upper part, where it was
/// measured.
fn mark_panel(out: &mut RgbImage, left: f32, right: f32, mark: i64) {
    let h = i64::from(out.height());
    for x in [left as i64, right as i64 - 1] {
        for y in (h / 20..h * 3 / 5).filter(|y| (y / (4 * mark)) % 2 == 0) {
            for dx in -(mark / 2)..=(mark / 2) {
                put(out, x + dx, y, Rgb([255, 210, 0]));
            }
        }
    }
}

/// Draws `analysis` over the image it was made from (`bytes`, read from
/// `path`), decoded within `counter`'s limits; an untrained model's overlay
/// says so.
pub fn render_encoded(
    counter: &Counter,
    path: &Path,
    bytes: &[u8],
    analysis: &Analysis,
) -> Result<RgbImage, InferenceError> {
    let img = crate::decode::decode_rgb(path, bytes, &counter.config().limits)?;
    Ok(render(
        Contract::embedded(),
        &img,
        analysis,
        !counter.model_info().trained,
    ))
}

/// The colour of leaf instance `id`: hues a golden ratio apart, so that
/// neighbouring numbers (often neighbouring leaves in the whorl) are far apart.
pub fn leaf_colour(id: u32) -> [u8; 3] {
    let h = (f64::from(id) * 0.618_033_988_75).fract() * 6.0;
    let (s, v) = (0.85, 0.95);
    let f = h.fract();
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let (r, g, b) = match h as u32 {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    [r, g, b].map(|c| (c * 255.0).round() as u8)
}

/// A white cross with a black edge at (x, y), arms `2 * mark` long: visible on
/// the white chamber wall as on a dark leaf.
fn mark_centre(img: &mut RgbImage, x: i64, y: i64, mark: i64) {
    for (colour, grow) in [(Rgb([0, 0, 0]), 1), (Rgb([255, 255, 255]), 0)] {
        for d in -mark * 2 - grow..=mark * 2 + grow {
            for t in -mark / 2 - grow..=mark / 2 + grow {
                put(img, x + d, y + t, colour);
                put(img, x + t, y + d, colour);
            }
        }
    }
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// Writes `s` in white on a black box at (x, y), each font pixel `scale` wide.
fn text(img: &mut RgbImage, s: &str, x: u32, y: u32, scale: u32) {
    let w = (s.chars().count() as u32 * 8 + 4) * scale;
    let h = 12 * scale;
    for yy in y..y + h {
        for xx in x..x + w {
            put(img, xx.into(), yy.into(), Rgb([0, 0, 0]));
        }
    }
    for (i, ch) in s.chars().enumerate() {
        let Some(glyph) = font8x8::BASIC_FONTS.get(ch) else {
            continue;
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let px = x + (2 + i as u32 * 8 + col) * scale + dx;
                        let py = y + (2 + row as u32) * scale + dy;
                        put(img, px.into(), py.into(), Rgb([255, 255, 255]));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbouring_leaves_get_hues_far_apart() {
        let hue = |c: [u8; 3]| {
            let [r, g, b] = c.map(f64::from);
            let (max, min) = (r.max(g).max(b), r.min(g).min(b));
            let d = max - min;
            let h = if max == r {
                ((g - b) / d).rem_euclid(6.0)
            } else if max == g {
                (b - r) / d + 2.0
            } else {
                (r - g) / d + 4.0
            };
            h / 6.0
        };
        for id in 1..20 {
            let (a, b) = (hue(leaf_colour(id)), hue(leaf_colour(id + 1)));
            let apart = (a - b).abs().min(1.0 - (a - b).abs());
            assert!(apart > 0.3, "leaves {id} and {}: hues {a:.2} and {b:.2}", id + 1);
        }
    }

    #[test]
    fn a_centre_mark_shows_on_white_and_on_black() {
        for bg in [255u8, 0] {
            let mut img = RgbImage::from_pixel(40, 40, Rgb([bg; 3]));
            mark_centre(&mut img, 20, 20, 4);
            let other = 255 - bg;
            // The cross's arm and its edge: one of them contrasts with the background.
            assert_eq!(img.get_pixel(20, 14).0, [255; 3]);
            assert!(img.pixels().any(|p| p.0 == [other; 3]), "background {bg}");
            assert_eq!(img.get_pixel(20, 11).0, [0; 3], "the edge beyond the arm's end");
        }
    }

    #[test]
    fn leaves_are_numbered_from_the_base_upward() {
        let leaf = |id: u32, bottom: u32, x: f32| crate::result::Instance {
            id,
            class: phyllo_contract::LEAF,
            class_name: "leaf".into(),
            area: 1,
            bbox: [0, 0, 10, bottom],
            centre: [x, 0.0],
            score: 1.0,
        };
        let leaves = [
            leaf(1, 300, 5.0),
            leaf(2, 900, 5.0),
            leaf(3, 600, 9.0),
            leaf(4, 600, 1.0),
        ];
        let ids: Vec<u32> = from_the_base(&leaves).iter().map(|l| l.id).collect();
        assert_eq!(ids, [2, 4, 3, 1]);
    }
}
