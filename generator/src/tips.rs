//! Apparent leaf tips, the targets of a leaf-tip detector.
//!
//! A tip detector learns to mark where a human annotator would mark a leaf's
//! tip, and a human marks the *visible* end of a leaf: the blade's tip where it
//! can be seen, otherwise (tip behind another leaf or the stem, or outside the
//! image) the end of what can be seen of that leaf. The geometric tip alone
//! would teach the detector to point at hidden places; the label alone does not
//! say which end of a blade is its tip. So the apparent tip of leaf instance `k`
//! is found from both:
//!
//! 1. the blade's 3D tip (end of the midrib, [`Plant::leaf_tips`]) is turned
//!    by the view's turntable rotation ([`Scene::to_chamber`]), projected by
//!    the camera and shifted by the render window's origin, giving image
//!    coordinates (x, y) in which pixel (i, j) spans [i, i+1) x [j, j+1);
//! 2. if the label pixel containing that point holds leaf instance `k`, the
//!    apparent tip is the projected point itself;
//! 3. otherwise it is the centre (i + 0.5, j + 0.5) of the instance-`k` label
//!    pixel nearest (Euclidean) to the projected point; of equally near
//!    pixels, the first in row-major order.
//!
//! The blade tapers to zero width, so its last few pixels are narrower than a
//! pixel and seldom cover a pixel centre (the label's ray): even an unhidden
//! tip usually
//! takes rule 3, landing on the leaf's last labelled pixel, typically 1 to 5
//! pixels inward of the geometric tip, more for a tip seen edge-on.
//!
//! Only instances with at least one label pixel get a tip, so the keys are
//! exactly those of [`LabelImage::leaf_pixels`]. A tip that does not project
//! (behind the camera; the chamber's cameras never see that) falls back to the
//! instance's pixel nearest its pixel centroid.

use crate::label::LabelImage;
use crate::plant::Plant;
use crate::render::{camera::Camera, Scene, Window};
use phyllo_contract::{Contract, LEAF};
use std::collections::BTreeMap;

/// Image coordinates of each leaf's projected blade tip (instance -> (x, y)
/// in the pixels of `window`), `None` where the tip does not project. Every
/// living leaf has an entry, visible or not.
pub fn projected_tips(
    plant: &Plant,
    scene: &Scene,
    camera: &Camera,
    window: Window,
) -> BTreeMap<u16, Option<[f32; 2]>> {
    plant
        .leaf_tips
        .iter()
        .enumerate()
        .map(|(k, &tip)| {
            let p = camera
                .project(scene.to_chamber(tip))
                .map(|(x, y)| [x - window.x0 as f32, y - window.y0 as f32])
                .filter(|p| p[0].is_finite() && p[1].is_finite());
            ((k + 1) as u16, p)
        })
        .collect()
}

/// The apparent tip of every leaf instance present in `label`, given each
/// instance's projected tip (see the module comment for the rule).
pub fn apparent_tips(
    label: &LabelImage,
    projected: &BTreeMap<u16, Option<[f32; 2]>>,
) -> BTreeMap<u16, [f32; 2]> {
    #[derive(Default)]
    struct Acc {
        /// The pixel containing the projected tip holds this instance.
        on_leaf: bool,
        /// Nearest pixel centre so far and its squared distance.
        nearest: Option<(f64, [f32; 2])>,
        /// Sum of pixel centres and count, for the centroid fallback.
        sum: [f64; 2],
        n: u64,
    }
    let c = Contract::embedded();
    let w = label.width as usize;
    let target = |inst: u16| projected.get(&inst).copied().flatten();
    let leaf_pixels = || {
        label.data.iter().enumerate().filter_map(move |(idx, &v)| {
            let (class, inst) = c.decode_label(v);
            (class == LEAF).then_some((inst, idx % w, idx / w))
        })
    };
    let mut acc: BTreeMap<u16, Acc> = BTreeMap::new();
    for (inst, i, j) in leaf_pixels() {
        let a = acc.entry(inst).or_default();
        let centre = [i as f64 + 0.5, j as f64 + 0.5];
        a.sum[0] += centre[0];
        a.sum[1] += centre[1];
        a.n += 1;
        if let Some(p) = target(inst) {
            if p[0].floor() == i as f32 && p[1].floor() == j as f32 {
                a.on_leaf = true;
            }
            nearer(&mut a.nearest, centre, [f64::from(p[0]), f64::from(p[1])]);
        }
    }
    // Instances whose tip does not project: nearest pixel to their centroid.
    let centroids: BTreeMap<u16, [f64; 2]> = acc
        .iter()
        .filter(|(inst, _)| target(**inst).is_none())
        .map(|(inst, a)| (*inst, [a.sum[0] / a.n as f64, a.sum[1] / a.n as f64]))
        .collect();
    if !centroids.is_empty() {
        for (inst, i, j) in leaf_pixels() {
            if let Some(&q) = centroids.get(&inst) {
                let a = acc.get_mut(&inst).expect("seen in the first pass");
                nearer(&mut a.nearest, [i as f64 + 0.5, j as f64 + 0.5], q);
            }
        }
    }
    acc.into_iter()
        .map(|(inst, a)| {
            let tip = match target(inst) {
                Some(p) if a.on_leaf => p,
                _ => a.nearest.expect("an instance in the label has a pixel").1,
            };
            (inst, tip)
        })
        .collect()
}

/// Keeps `centre` in `best` if it is strictly nearer to `to` (so the first of
/// equally near pixels wins).
fn nearer(best: &mut Option<(f64, [f32; 2])>, centre: [f64; 2], to: [f64; 2]) {
    let d = (centre[0] - to[0]).powi(2) + (centre[1] - to[1]).powi(2);
    if best.is_none_or(|(b, _)| d < b) {
        *best = Some((d, [centre[0] as f32, centre[1] as f32]));
    }
}

/// How far each apparent tip lies from its leaf's projected tip, in image
/// pixels: 0 where the label shows the leaf at the projected tip, small where
/// the blade thins out below a pixel or runs out of the image (the projected
/// tip is first clamped into the `width` x `height` image, so a tip cut by
/// the image's edge counts as seen there, as annotators count cut tips), and
/// large where something hides the tip. Instances whose tip does not project
/// get no entry. Human annotators count leaves by the tips they can see; this
/// lets a dataset's truth follow that rule (`python -m phyllo_train.tools.truth_rules
/// --tip-gaps`).
pub fn tip_gaps(
    projected: &BTreeMap<u16, Option<[f32; 2]>>,
    apparent: &BTreeMap<u16, [f32; 2]>,
    width: u32,
    height: u32,
) -> BTreeMap<u16, f32> {
    apparent
        .iter()
        .filter_map(|(inst, tip)| {
            let p = projected.get(inst).copied().flatten()?;
            let q = [p[0].clamp(0.0, width as f32), p[1].clamp(0.0, height as f32)];
            let gap = if p == *tip {
                0.0
            } else {
                ((q[0] - tip[0]).powi(2) + (q[1] - tip[1]).powi(2)).sqrt()
            };
            Some((*inst, gap))
        })
        .collect()
}

/// The manifest's `leaf_tips` and `leaf_tip_gaps` for one rendered view:
/// [`projected_tips`] resolved against the view's label by [`apparent_tips`],
/// and [`tip_gaps`] between the two.
pub fn leaf_tips(
    plant: &Plant,
    scene: &Scene,
    camera: &Camera,
    window: Window,
    label: &LabelImage,
) -> (BTreeMap<u16, [f32; 2]>, BTreeMap<u16, f32>) {
    let projected = projected_tips(plant, scene, camera, window);
    let tips = apparent_tips(label, &projected);
    let gaps = tip_gaps(&projected, &tips, label.width, label.height);
    (tips, gaps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A label from rows of (class, instance) codes: `.` background, a digit
    /// = that leaf instance, `s` = stem.
    fn label(rows: &[&str]) -> LabelImage {
        let c = Contract::embedded();
        let data = rows
            .iter()
            .flat_map(|r| r.chars())
            .map(|ch| match ch {
                '.' => 0,
                's' => c.encode_label(phyllo_contract::STEM, 0),
                d => c.encode_label(LEAF, d.to_digit(10).unwrap() as u16),
            })
            .collect();
        LabelImage {
            width: rows[0].len() as u32,
            height: rows.len() as u32,
            data,
        }
    }

    #[test]
    fn a_tip_on_its_own_leaf_is_the_projected_point() {
        let l = label(&["....", ".11.", "..22"]);
        let p = BTreeMap::from([(1, Some([2.75, 1.25])), (2, Some([3.5, 2.9]))]);
        let t = apparent_tips(&l, &p);
        assert_eq!(t, BTreeMap::from([(1, [2.75, 1.25]), (2, [3.5, 2.9])]));
    }

    #[test]
    fn a_hidden_or_outside_tip_moves_to_the_nearest_pixel_of_its_leaf() {
        // Leaf 1's tip lies on the stem pixel (3, 1); its nearest pixel is
        // (2, 1), nearer than (3, 0).
        // Leaf 2's tip is outside the image, below and left of (0, 2).
        // Leaf 3 has no pixel, leaf 4 has no projection: centroid fallback.
        let l = label(&["4441", "s11s", "2.22"]);
        let p = BTreeMap::from([
            (1, Some([3.4, 1.6])),
            (2, Some([-3.0, 9.0])),
            (3, Some([1.0, 1.0])),
            (4, None),
        ]);
        let t = apparent_tips(&l, &p);
        assert_eq!(
            t,
            BTreeMap::from([(1, [2.5, 1.5]), (2, [0.5, 2.5]), (4, [1.5, 0.5])])
        );
        assert_eq!(
            t.keys().collect::<Vec<_>>(),
            l.leaf_pixels().keys().collect::<Vec<_>>()
        );
    }

    #[test]
    fn tip_gaps_are_zero_on_the_leaf_small_at_the_edge_and_large_when_hidden() {
        // Leaf 1's tip is on the leaf; leaf 2's is hidden by leaf 3 four
        // pixels from leaf 2's last pixel; leaf 3 runs off the right edge and
        // its tip lies far outside; leaf 4 does not project.
        let l = label(&["1........", "222233333", "4........"]);
        let p = BTreeMap::from([
            (1, Some([0.5, 0.5])),
            (2, Some([7.5, 1.5])),
            (3, Some([40.0, 1.5])),
            (4, None),
        ]);
        let t = apparent_tips(&l, &p);
        let g = tip_gaps(&p, &t, l.width, l.height);
        assert_eq!(g[&1], 0.0);
        assert_eq!(g[&2], 4.0, "tip at x 7.5, leaf 2 ends at the centre 3.5");
        assert_eq!(g[&3], 0.5, "clamped to the edge x 9, the last centre is 8.5");
        assert!(!g.contains_key(&4));
    }

    #[test]
    fn equally_near_pixels_resolve_to_the_first_in_row_major_order() {
        let l = label(&["1.1"]);
        let t = apparent_tips(&l, &BTreeMap::from([(1, Some([1.5, 0.5]))]));
        assert_eq!(t[&1], [0.5, 0.5]);
    }
}
