//! Finding the plant in a chamber image.
//!
//! The LemnaTec chamber is bright and nearly neutral (white wall, translucent
//! panels, aluminium frames, black carrier), while the plant is green or, where
//! it senesces, yellow-brown. A chroma test is therefore enough to bound the
//! plant; the bounding box is trimmed of stray pixels so a green label on a
//! pot or a reflection cannot stretch it across the frame.

use image::RgbImage;
use serde::{Deserialize, Serialize};

/// How the region the model looks at is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case", tag = "mode", deny_unknown_fields)]
pub enum RegionMode {
    /// Detect the plant by colour (default).
    #[default]
    Auto,
    /// Use the whole image.
    Full,
    /// A fixed box in original-image pixels (x1, y1 exclusive), for stations
    /// whose plant is always in the same place.
    Fixed {
        /// Left edge.
        x0: u32,
        /// Top edge.
        y0: u32,
        /// Right edge (exclusive).
        x1: u32,
        /// Bottom edge (exclusive).
        y1: u32,
    },
}

/// Per-channel median of `img`: the chamber's colour, since the plant covers
/// a small part of every frame. Used as the white reference.
pub fn median_colour(img: &RgbImage) -> [u8; 3] {
    let mut hist = [[0u32; 256]; 3];
    for p in img.pixels() {
        for c in 0..3 {
            hist[c][p.0[c] as usize] += 1;
        }
    }
    let half = (img.width() * img.height()).div_ceil(2);
    std::array::from_fn(|c| {
        let mut acc = 0;
        hist[c]
            .iter()
            .position(|&n| {
                acc += n;
                acc >= half
            })
            .unwrap_or(255) as u8
    })
}

/// Whether a pixel looks like plant tissue once white-balanced against the
/// chamber colour `white`: green leaves by green over red and blue, senescent
/// leaves by a yellow-brown tint the chamber never has, and leaves seen
/// against the backlit wall by being dark with green at least level with red
/// and clearly above blue. White balancing first matters: real chambers are
/// lit warm, and a fixed excess-green test then fires on the white wall and
/// the translucent panels.
#[inline]
pub fn is_plant_pixel(p: [u8; 3], white: [u8; 3]) -> bool {
    let n = |c: usize| f32::from(p[c]) / f32::from(white[c].max(1));
    let (r, g, b) = (n(0), n(1), n(2));
    let green = g - r.max(b) > 0.06;
    let senescent = r - b > 0.25 && g - b > 0.15;
    // Backlit maize and sorghum leaves are nearly black-olive, e.g. (41, 44, 13)
    // under a (252, 246, 222) wall: too dark for the chroma margin above, yet
    // the black carrier and the aluminium grooves stay neutral.
    let backlit = r.max(g).max(b) < 0.5 && g - b > 0.05 && g >= r - 0.03;
    green || senescent || backlit
}

/// Bounding box `[x0, y0, x1, y1]` of the plant pixels of `img`, trimmed so
/// that at most `trim` of the plant pixels fall outside it on each side (stray
/// colour fringes on the chamber's frames must not stretch it), grown by
/// `margin` pixels. `None` when fewer than `min_pixels` look like plant.
pub fn plant_bbox(img: &RgbImage, trim: f32, margin: u32, min_pixels: u32) -> Option<[u32; 4]> {
    let (w, h) = img.dimensions();
    let white = median_colour(img);
    let mut cols = vec![0u32; w as usize];
    let mut rows = vec![0u32; h as usize];
    let mut total = 0u32;
    for (x, y, p) in img.enumerate_pixels() {
        if is_plant_pixel(p.0, white) {
            cols[x as usize] += 1;
            rows[y as usize] += 1;
            total += 1;
        }
    }
    if total < min_pixels {
        return None;
    }
    let cut = (total as f32 * trim) as u32;
    let (x0, x1) = trimmed_span(&cols, cut);
    let (y0, y1) = trimmed_span(&rows, cut);
    Some([
        x0.saturating_sub(margin),
        y0.saturating_sub(margin),
        (x1 + margin).min(w),
        (y1 + margin).min(h),
    ])
}

/// The span `[lo, hi)` of a histogram after dropping up to `cut` counts from each end.
fn trimmed_span(hist: &[u32], cut: u32) -> (u32, u32) {
    let mut acc = 0;
    let mut lo = 0;
    for (i, &c) in hist.iter().enumerate() {
        acc += c;
        if acc > cut {
            lo = i;
            break;
        }
    }
    acc = 0;
    let mut hi = hist.len();
    for (i, &c) in hist.iter().enumerate().rev() {
        acc += c;
        if acc > cut {
            hi = i + 1;
            break;
        }
    }
    (lo as u32, hi.max(lo + 1) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_green_plant_on_white_chamber_and_ignores_a_speck() {
        let mut img = RgbImage::from_pixel(300, 200, image::Rgb([235, 230, 228]));
        for y in 50..150 {
            for x in 100..140 {
                img.put_pixel(x, y, image::Rgb([60, 120, 40]));
            }
        }
        img.put_pixel(290, 5, image::Rgb([0, 255, 0]));
        let bb = plant_bbox(&img, 0.005, 0, 10).unwrap();
        assert_eq!(bb, [100, 50, 140, 150]);
        let bb = plant_bbox(&img, 0.005, 8, 10).unwrap();
        assert_eq!(bb, [92, 42, 148, 158]);
    }

    #[test]
    fn empty_chamber_has_no_plant() {
        let img = RgbImage::from_pixel(100, 100, image::Rgb([240, 240, 240]));
        assert_eq!(plant_bbox(&img, 0.005, 0, 10), None);
        // Black carrier and grey frames are not plant.
        let warm_white = [251, 249, 226];
        assert!(!is_plant_pixel([20, 20, 22], warm_white));
        assert!(
            !is_plant_pixel([168, 167, 141], warm_white),
            "a panel lit warm is not plant"
        );
        assert!(!is_plant_pixel(warm_white, warm_white));
        assert!(is_plant_pixel([70, 110, 50], warm_white));
        assert!(is_plant_pixel([190, 160, 80], warm_white));
        // Backlit leaves measured on a real crop (81-133, wall 252/246/222).
        let wall = [252, 246, 222];
        assert!(is_plant_pixel([41, 44, 13], wall));
        assert!(is_plant_pixel([49, 47, 24], wall));
        assert!(!is_plant_pixel([12, 8, 7], wall), "black is not plant");
        assert!(!is_plant_pixel([60, 45, 30], wall), "brown soil is not plant");
    }
}
