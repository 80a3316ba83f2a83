//! Keeping only the instances that belong to the plant.
//!
//! Every leaf grows from the stem, so in a side view the plant is one
//! connected body: leaves overlap each other or meet the stem. What the model
//! sometimes takes for a leaf in the chamber (a ceiling edge, a corner
//! bracket, a rail where it meets a post) lies apart from that body, across
//! bright wall. This stage groups the model's plant pixels (any non-background
//! class) into bodies, bridging gaps of up to `radius` output pixels, picks the
//! plant's body by colour (the one with most green or senescent pixels, as in
//! [`crate::region`]), keeps the bodies with a fair share of plant colour too
//! (a leaf cut off by a thin missed stretch), and drops instances that lie
//! mostly outside the kept bodies.

use image::{GrayImage, Luma, RgbImage};
use imageproc::distance_transform::Norm;
use imageproc::morphology;
use imageproc::region_labelling::{connected_components, Connectivity};
use phyllo_contract::Contract;

use crate::panoptic::Panoptic;
use crate::region::{is_plant_pixel, median_colour};

/// A body counts as plant when it holds at least this share of the plant
/// colour of the most plant-coloured body.
const MIN_COLOUR_SHARE: f32 = 0.25;

/// An instance is kept when at least this share of its pixels is in a kept body.
const MIN_INSTANCE_SHARE: f32 = 0.5;

/// Drops the instances of `pan` that lie apart from the plant. `canvas` is
/// the image the model saw (`stride` input pixels per output pixel); gaps of
/// up to `radius` output pixels between plant pixels are bridged. A radius of
/// 0 disables the stage. An instance mostly apart from the plant whose part
/// on it is at least twice `min_leaf_area` is cut down to that part.
pub fn keep_attached(
    pan: &mut Panoptic,
    canvas: &RgbImage,
    contract: &Contract,
    radius: u32,
    min_leaf_area: u32,
) {
    if radius == 0 || pan.segments.is_empty() {
        return;
    }
    let (w, h) = (pan.width, pan.height);
    let plant: Vec<bool> = pan.semantic.iter().map(|&c| c != 0).collect();
    let mask = GrayImage::from_fn(w as u32, h as u32, |x, y| {
        Luma([if plant[y as usize * w + x as usize] {
            255
        } else {
            0
        }])
    });
    let (body, bodies) = label_components(&dilate(&mask, radius));
    if bodies == 0 {
        return;
    }

    // Plant colour per body, sampled at the centre of each output pixel.
    let stride = contract.outputs.stride as usize;
    let white = median_colour(canvas);
    let (cw, ch) = (canvas.width() as usize, canvas.height() as usize);
    let mut colour = vec![0u32; bodies + 1];
    let mut size = vec![0u32; bodies + 1];
    for i in 0..w * h {
        if !plant[i] {
            continue;
        }
        let b = body[i] as usize;
        size[b] += 1;
        let (x, y) = ((i % w) * stride + stride / 2, (i / w) * stride + stride / 2);
        if x < cw && y < ch && is_plant_pixel(canvas.get_pixel(x as u32, y as u32).0, white) {
            colour[b] += 1;
        }
    }
    // Without any plant colour (a grey image) the largest body is the plant.
    let score = if colour.iter().any(|&c| c > 0) {
        &colour
    } else {
        &size
    };
    let best = score.iter().copied().max().unwrap_or(0) as f32;
    let kept: Vec<bool> = score
        .iter()
        .map(|&s| s > 0 && s as f32 >= MIN_COLOUR_SHARE * best)
        .collect();

    let mut inside = vec![0u32; pan.segments.len() + 1];
    let mut area = vec![0u32; pan.segments.len() + 1];
    for i in 0..w * h {
        let id = pan.instance[i] as usize;
        if id == 0 {
            continue;
        }
        area[id] += 1;
        if kept[body[i] as usize] {
            inside[id] += 1;
        }
    }
    let attached: Vec<bool> = (0..=pan.segments.len())
        .map(|id| inside[id] as f32 >= MIN_INSTANCE_SHARE * area[id] as f32)
        .collect();
    // An instance mostly off the plant may still hold a leaf: the offset head
    // sometimes sends a leaf's pixels and a bracket's to one centre. Its part
    // on the plant is kept as the instance when that part is leaf-sized.
    let trim_min = trim_min_area(min_leaf_area);
    let trimmed: Vec<bool> = (0..=pan.segments.len())
        .map(|id| id > 0 && !attached[id] && inside[id] >= trim_min)
        .collect();
    if trimmed.contains(&true) {
        for i in 0..w * h {
            let id = pan.instance[i] as usize;
            if trimmed[id] && !kept[body[i] as usize] {
                pan.instance[i] = 0;
            }
        }
        pan.refresh_extents();
    }
    pan.retain(|seg| attached[seg.id as usize] || trimmed[seg.id as usize]);
}

/// Smallest on-plant part (output pixels) of a mostly detached instance that
/// is kept as a leaf: twice the smallest leaf, so a few pixels of a bracket
/// that happen to touch the plant never count.
fn trim_min_area(min_leaf_area: u32) -> u32 {
    2 * min_leaf_area.max(1)
}

/// Square dilation of `mask` by `r` pixels (`L∞` distance at most `r`).
fn dilate(mask: &GrayImage, r: u32) -> GrayImage {
    // imageproc takes the radius as a u8; past 255 output pixels every
    // realistic plant is one body anyway.
    morphology::dilate(mask, Norm::LInf, r.min(255) as u8)
}

/// 8-connected components of `mask`: a label per pixel (0 outside the mask,
/// bodies from 1) and the number of bodies.
fn label_components(mask: &GrayImage) -> (Vec<u32>, usize) {
    let labels = connected_components(mask, Connectivity::Eight, Luma([0u8]));
    let bodies = labels.pixels().map(|p| p.0[0]).max().unwrap_or(0) as usize;
    (labels.into_raw(), bodies)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::panoptic::Segment;

    /// A 40x20 output grid (stride 2) with three leaves: two touching the
    /// green stem, one grey "leaf" on the chamber frame far away.
    fn scene() -> (Panoptic, RgbImage) {
        let (w, h) = (40usize, 20usize);
        let mut semantic = vec![0u8; w * h];
        let mut instance = vec![0u32; w * h];
        let mut img = RgbImage::from_pixel(80, 40, image::Rgb([235, 232, 228]));
        let mut paint = |x0: usize, x1: usize, y0: usize, y1: usize, class: u8, id: u32, rgb: [u8; 3]| {
            for y in y0..y1 {
                for x in x0..x1 {
                    semantic[y * w + x] = class;
                    instance[y * w + x] = id;
                    for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        img.put_pixel((2 * x + dx) as u32, (2 * y + dy) as u32, image::Rgb(rgb));
                    }
                }
            }
        };
        let green = [60, 120, 40];
        paint(10, 11, 2, 18, 2, 0, green); // stem
        paint(4, 10, 5, 7, 1, 1, green); // leaf touching the stem
        paint(13, 20, 9, 11, 1, 2, green); // leaf two pixels from the stem
        paint(34, 40, 0, 2, 1, 3, [150, 150, 150]); // grey bracket
        let seg = |id: u32| Segment {
            id,
            class: 1,
            area: 0,
            bbox: [0, 0, 1, 1],
            centre: [0.0, 0.0],
            score: 1.0,
        };
        let pan = Panoptic {
            height: h,
            width: w,
            semantic,
            instance,
            segments: vec![seg(1), seg(2), seg(3)],
            tips: None,
        };
        (pan, img)
    }

    #[test]
    fn drops_the_detached_grey_instance_and_keeps_the_leaves() {
        let (mut pan, img) = scene();
        keep_attached(&mut pan, &img, Contract::embedded(), 3, 24);
        assert_eq!(pan.segments.len(), 2);
        assert!(pan.instance[..].iter().all(|&i| i <= 2));
        assert_eq!(pan.instance[5 * 40 + 4], 1);
        assert_eq!(pan.instance[9 * 40 + 13], 2);
        assert_eq!(pan.instance[39], 0, "the bracket's pixels are cleared");
    }

    /// `scene` with a 48-pixel bracket whose instance (3) also takes a
    /// 24-pixel leaf touching the stem: a third of the instance on the plant.
    fn bracket_sharing_a_leaf() -> (Panoptic, RgbImage) {
        let (mut pan, mut img) = scene();
        let w = pan.width;
        let mut paint = |x0: usize, x1: usize, y0: usize, y1: usize, rgb: [u8; 3]| {
            for y in y0..y1 {
                for x in x0..x1 {
                    pan.semantic[y * w + x] = 1;
                    pan.instance[y * w + x] = 3;
                    for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        img.put_pixel((2 * x + dx) as u32, (2 * y + dy) as u32, image::Rgb(rgb));
                    }
                }
            }
        };
        paint(28, 40, 0, 4, [150, 150, 150]);
        paint(4, 10, 12, 16, [60, 120, 40]);
        (pan, img)
    }

    #[test]
    fn a_leaf_sharing_an_instance_with_a_bracket_keeps_its_part_on_the_plant() {
        let (mut pan, img) = bracket_sharing_a_leaf();
        keep_attached(&mut pan, &img, Contract::embedded(), 3, 12);
        assert_eq!(pan.segments.len(), 3, "the leaf part survives");
        assert_eq!(pan.instance[39], 0, "the bracket's pixels are cleared");
        assert_eq!(pan.instance[12 * 40 + 4], 3);
        assert_eq!(pan.segments[2].area, 24);
        assert_eq!(pan.segments[2].bbox, [4, 12, 10, 16]);
    }

    #[test]
    fn a_sliver_of_a_detached_instance_on_the_plant_is_not_kept() {
        // 24 pixels on the plant are less than twice a 13-pixel smallest leaf.
        let (mut pan, img) = bracket_sharing_a_leaf();
        keep_attached(&mut pan, &img, Contract::embedded(), 3, 13);
        assert_eq!(pan.segments.len(), 2);
        assert!(pan.instance.iter().all(|&i| i <= 2));
    }

    #[test]
    fn radius_zero_keeps_everything() {
        let (mut pan, img) = scene();
        keep_attached(&mut pan, &img, Contract::embedded(), 0, 24);
        assert_eq!(pan.segments.len(), 3);
    }

    #[test]
    fn a_green_body_apart_from_the_plant_is_kept() {
        // Recolour the bracket green and as big as a leaf: a leaf whose link to
        // the stem the model missed is still plant.
        let (mut pan, mut img) = scene();
        for y in 0..4 {
            for x in 68..80 {
                img.put_pixel(x, y, image::Rgb([60, 120, 40]));
            }
        }
        keep_attached(&mut pan, &img, Contract::embedded(), 3, 24);
        assert_eq!(pan.segments.len(), 3);
    }

    #[test]
    fn dilation_and_components() {
        let mask = GrayImage::from_raw(7, 1, vec![255, 0, 0, 0, 0, 0, 255]).unwrap();
        let d = dilate(&mask, 2);
        assert_eq!(d.as_raw(), &vec![255, 255, 255, 0, 255, 255, 255]);
        let (label, n) = label_components(&d);
        assert_eq!(n, 2);
        assert_eq!(label, vec![1, 1, 1, 0, 2, 2, 2]);
    }
}
