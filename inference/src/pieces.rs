//! Splitting a leaf instance that lies in separate pieces.
//!
//! The decoder joins every thing pixel to the centre its offset points at, so
//! when the centre head draws one peak for two leaves, both leaves become one
//! instance even where they lie apart (two leaves on opposite sides of the
//! stem, a young leaf above an older one). This stage labels each leaf
//! instance's pixels into pieces, joining pixels up to `gap` output pixels
//! apart (Chebyshev), and gives every piece beyond the largest that holds at
//! least `min_area` pixels an instance of its own. Smaller pieces stay with
//! their instance: a leaf crossed by a thin neighbour leaves such crumbs.
//!
//! One leaf seen on both sides of a leaf in front of it also lies in two
//! pieces, and grouping those is what the decoder's offsets are for. So a
//! piece stays with its instance when the shortest route to the largest
//! piece runs mostly over another leaf instance; across stem or background
//! it becomes a leaf.

use std::collections::VecDeque;

use phyllo_contract::LEAF;

use crate::panoptic::{Panoptic, Segment};

/// Default smallest piece that becomes a leaf, in output pixels: about a
/// young leaf's blade at the contract scale. Chosen on the synthetic
/// calibration sets (models/EXPERIMENTS.md, "Leaves in separate pieces").
pub const DEFAULT_SPLIT_MIN_AREA: u32 = 128;

/// Default gap within one piece, in output pixels: a leaf edge-on for a
/// pixel or two is still one piece.
pub const DEFAULT_SPLIT_GAP: u32 = 2;

/// Default largest share of another leaf on the route between two pieces
/// for them to be two leaves.
pub const DEFAULT_SPLIT_MAX_LEAF_SHARE: f32 = 0.2;

/// Gives each large separate piece of a leaf instance its own instance.
/// `min_area` 0 disables the stage; `gap` 0 is taken as 1 (8-connected).
pub fn split_pieces(pan: &mut Panoptic, min_area: u32, gap: u32, max_leaf_share: f32) {
    if min_area == 0 || pan.segments.is_empty() {
        return;
    }
    let w = pan.width;
    // Piece number + 1 of every pixel labelled so far (0: none); each pixel
    // belongs to one instance, so one map serves them all.
    let mut piece = vec![0u32; w * pan.height];
    let mut new_segments: Vec<Segment> = Vec::new();
    let mut next_id = pan.segments.len() as u32 + 1;
    for seg in pan.segments.clone() {
        if seg.class != LEAF || seg.area < 2 * min_area {
            continue;
        }
        let id = seg.id;
        let pieces = label_pieces(pan, &seg, gap.max(1) as usize, &mut piece);
        if pieces.len() < 2 {
            continue;
        }
        let largest = pieces
            .iter()
            .enumerate()
            .max_by_key(|(n, px)| (px.len(), std::cmp::Reverse(*n)))
            .map(|(n, _)| n)
            .expect("two or more pieces");
        let bridges = bridge_leaf_shares(pan, &piece, &pieces, largest, id);
        for (n, pixels) in pieces.iter().enumerate() {
            if n == largest || (pixels.len() as u32) < min_area {
                continue;
            }
            // A piece reached across another leaf is most likely the same
            // leaf seen on both sides of the one in front of it.
            if bridges[n] > max_leaf_share {
                continue;
            }
            let new_id = next_id;
            next_id += 1;
            let (mut sx, mut sy) = (0f64, 0f64);
            let mut bbox = [u32::MAX, u32::MAX, 0, 0];
            for &k in pixels {
                pan.instance[k] = new_id;
                let (x, y) = ((k % w) as u32, (k / w) as u32);
                sx += f64::from(x);
                sy += f64::from(y);
                bbox = [
                    bbox[0].min(x),
                    bbox[1].min(y),
                    bbox[2].max(x + 1),
                    bbox[3].max(y + 1),
                ];
            }
            let n_px = pixels.len() as f64;
            new_segments.push(Segment {
                id: new_id,
                class: seg.class,
                area: pixels.len() as u32,
                bbox,
                centre: [(sx / n_px) as f32, (sy / n_px) as f32],
                score: seg.score,
            });
        }
    }
    if new_segments.is_empty() {
        return;
    }
    pan.segments.extend(new_segments);
    pan.refresh_extents();
}

/// Default distance, in output pixels, beyond which a crumb of a leaf
/// instance is a speck: farther from the leaf's body than any blade is wide
/// at the contract scale.
pub const DEFAULT_SPECK_DISTANCE: u32 = 24;

/// Takes from each leaf instance the pieces too small to be a leaf of their
/// own (under `min_area` output pixels) that lie more than `distance` output
/// pixels from its largest piece (box to box): specks on the chamber's frames
/// that the decoder's offsets joined to a leaf far away. They leave the
/// count alone but would draw the leaf across the frame. `distance` 0, or
/// `min_area` 0 (splitting off), disables the stage.
pub fn drop_far_specks(pan: &mut Panoptic, min_area: u32, gap: u32, distance: u32) {
    if min_area == 0 || distance == 0 || pan.segments.is_empty() {
        return;
    }
    let w = pan.width;
    let mut piece = vec![0u32; w * pan.height];
    let mut cleared = false;
    for seg in pan.segments.clone() {
        if seg.class != LEAF {
            continue;
        }
        let pieces = label_pieces(pan, &seg, gap.max(1) as usize, &mut piece);
        if pieces.len() < 2 {
            continue;
        }
        let boxes: Vec<[usize; 4]> = pieces.iter().map(|px| pixel_box(px, w)).collect();
        let largest = (0..pieces.len())
            .max_by_key(|&n| (pieces[n].len(), std::cmp::Reverse(n)))
            .expect("pieces");
        for (n, pixels) in pieces.iter().enumerate() {
            let far = box_gap(boxes[n], boxes[largest]) > distance as usize;
            if n != largest && (pixels.len() as u32) < min_area && far {
                for &k in pixels {
                    pan.instance[k] = 0;
                }
                cleared = true;
            }
        }
    }
    if cleared {
        pan.refresh_extents();
    }
}

/// `[x0, y0, x1, y1]` (exclusive) of raster indices `pixels` in rows `w` wide.
fn pixel_box(pixels: &[usize], w: usize) -> [usize; 4] {
    pixels.iter().fold([usize::MAX, usize::MAX, 0, 0], |b, &k| {
        let (x, y) = (k % w, k / w);
        [b[0].min(x), b[1].min(y), b[2].max(x + 1), b[3].max(y + 1)]
    })
}

/// Chebyshev gap between two boxes (0 where they touch or overlap).
pub(crate) fn box_gap(a: [usize; 4], b: [usize; 4]) -> usize {
    let dx = a[0].saturating_sub(b[2]).max(b[0].saturating_sub(a[2]));
    let dy = a[1].saturating_sub(b[3]).max(b[1].saturating_sub(a[3]));
    dx.max(dy)
}

/// The pieces of `seg`'s instance: its pixels grouped so that pixels up to
/// `gap` apart (Chebyshev) share a piece, in raster order of their first
/// pixel. Marks each pixel's piece number + 1 in `piece`.
fn label_pieces(pan: &Panoptic, seg: &Segment, gap: usize, piece: &mut [u32]) -> Vec<Vec<usize>> {
    let w = pan.width;
    let id = seg.id;
    let [bx0, by0, bx1, by1] = seg.bbox.map(|v| v as usize);
    let mut pieces: Vec<Vec<usize>> = Vec::new();
    let mut queue = VecDeque::new();
    for y in by0..by1 {
        for x in bx0..bx1 {
            let i = y * w + x;
            if pan.instance[i] != id || piece[i] != 0 {
                continue;
            }
            let label = pieces.len() as u32 + 1;
            let mut pixels = vec![i];
            piece[i] = label;
            queue.push_back(i);
            while let Some(j) = queue.pop_front() {
                let (jx, jy) = (j % w, j / w);
                for ny in jy.saturating_sub(gap)..(jy + gap + 1).min(by1) {
                    for nx in jx.saturating_sub(gap)..(jx + gap + 1).min(bx1) {
                        let k = ny * w + nx;
                        if pan.instance[k] == id && piece[k] == 0 {
                            piece[k] = label;
                            pixels.push(k);
                            queue.push_back(k);
                        }
                    }
                }
            }
            pieces.push(pixels);
        }
    }
    pieces
}

/// For each piece, the share of the pixels on the shortest 8-connected route
/// from the largest piece to it that belong to another leaf instance (0 for
/// the largest piece itself and for pieces no route reaches).
fn bridge_leaf_shares(
    pan: &Panoptic,
    piece: &[u32],
    pieces: &[Vec<usize>],
    largest: usize,
    id: u32,
) -> Vec<f32> {
    let (w, h) = (pan.width, pan.height);
    let mut parent = vec![usize::MAX; w * h];
    let mut queue = VecDeque::new();
    for &k in &pieces[largest] {
        parent[k] = k;
        queue.push_back(k);
    }
    let target_label = |k: usize| -> Option<usize> {
        (pan.instance[k] == id)
            .then(|| piece[k] as usize)
            .filter(|&l| l > 0)
            .map(|l| l - 1)
    };
    let mut reached = vec![usize::MAX; pieces.len()];
    let mut left = pieces.len() - 1;
    'search: while let Some(j) = queue.pop_front() {
        let (jx, jy) = (j % w, j / w);
        for ny in jy.saturating_sub(1)..(jy + 2).min(h) {
            for nx in jx.saturating_sub(1)..(jx + 2).min(w) {
                let k = ny * w + nx;
                if parent[k] != usize::MAX {
                    continue;
                }
                parent[k] = j;
                if let Some(n) = target_label(k) {
                    if n != largest && reached[n] == usize::MAX {
                        reached[n] = k;
                        left -= 1;
                        if left == 0 {
                            break 'search;
                        }
                    }
                    // Routes do not pass through other pieces of the instance.
                    continue;
                }
                queue.push_back(k);
            }
        }
    }
    reached
        .iter()
        .map(|&end| {
            if end == usize::MAX {
                return 0.0;
            }
            let (mut leaf, mut total) = (0u32, 0u32);
            let mut k = parent[end];
            while parent[k] != k {
                total += 1;
                let other = pan.instance[k];
                if other != 0 && other != id && pan.semantic[k] == LEAF {
                    leaf += 1;
                }
                k = parent[k];
            }
            if total == 0 {
                0.0
            } else {
                leaf as f32 / total as f32
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(id: u32, area: u32, bbox: [u32; 4]) -> Segment {
        Segment {
            id,
            class: 1,
            area,
            bbox,
            centre: [0.0, 0.0],
            score: 0.9,
        }
    }

    /// A 12x4 map with instance 1 in two blocks of 4x4 at x 0..4 and 8..12
    /// and instance 2 between them, touching neither.
    fn two_blocks() -> Panoptic {
        let (w, h) = (12, 4);
        let mut instance = vec![0u32; w * h];
        for y in 0..h {
            for x in 0..w {
                instance[y * w + x] = match x {
                    0..=3 | 8..=11 => 1,
                    5..=6 => 2,
                    _ => 0,
                };
            }
        }
        Panoptic {
            height: h,
            width: w,
            semantic: instance.iter().map(|&i| u8::from(i > 0)).collect(),
            instance,
            segments: vec![leaf(1, 32, [0, 0, 12, 4]), leaf(2, 8, [5, 0, 7, 4])],
            tips: None,
        }
    }

    #[test]
    fn far_specks_leave_the_leaf_and_near_crumbs_stay() {
        // Leaf 1: a 10x4 body at x 0..10, a 1-pixel crumb 2 columns right of
        // it and a 1-pixel speck 30 columns right of it.
        let (w, h) = (48, 4);
        let mut instance = vec![0u32; w * h];
        for y in 0..h {
            for x in 0..10 {
                instance[y * w + x] = 1;
            }
        }
        instance[12] = 1;
        instance[w + 40] = 1;
        let mut pan = Panoptic {
            height: h,
            width: w,
            semantic: instance.iter().map(|&i| u8::from(i > 0)).collect(),
            instance,
            segments: vec![leaf(1, 42, [0, 0, 41, 4])],
            tips: None,
        };
        drop_far_specks(&mut pan, 8, 1, 24);
        assert_eq!(pan.instance[w + 40], 0, "the far speck is gone");
        assert_eq!(pan.instance[12], 1, "the near crumb stays");
        assert_eq!((pan.segments[0].area, pan.segments[0].bbox), (41, [0, 0, 13, 4]));
        // Disabled with splitting.
        let before = pan.clone();
        drop_far_specks(&mut pan, 0, 1, 0);
        assert_eq!(pan.instance, before.instance);
    }

    #[test]
    fn a_leaf_in_two_large_pieces_becomes_two_leaves() {
        let mut p = two_blocks();
        split_pieces(&mut p, 16, 1, 1.0);
        assert_eq!(p.count(1), 3);
        let new = &p.segments[2];
        assert_eq!((new.id, new.area, new.bbox), (3, 16, [8, 0, 12, 4]));
        assert_eq!(new.centre, [9.5, 1.5]);
        assert_eq!(p.segments[0].area, 16, "the first piece keeps the old id");
        assert_eq!(p.segments[0].bbox, [0, 0, 4, 4]);
        assert!(p.instance[8..12].iter().all(|&i| i == 3));
    }

    #[test]
    fn small_pieces_and_bridged_gaps_stay_with_their_leaf() {
        let mut p = two_blocks();
        split_pieces(&mut p, 17, 1, 1.0);
        assert_eq!(p.count(1), 2, "a piece under the minimum area stays");
        let mut p = two_blocks();
        split_pieces(&mut p, 16, 5, 1.0);
        assert_eq!(p.count(1), 2, "a gap of 4 empty pixels is bridged at gap 5");
        let mut p = two_blocks();
        split_pieces(&mut p, 0, 1, 1.0);
        assert_eq!(p.count(1), 2, "0 is off");
    }

    #[test]
    fn a_piece_reached_across_another_leaf_stays_and_one_across_the_stem_splits() {
        // The route from one block to the other is 4 pixels, 2 of them on leaf 2.
        let mut p = two_blocks();
        split_pieces(&mut p, 16, 1, 0.4);
        assert_eq!(p.count(1), 2, "half the route on another leaf: occlusion");
        let mut p = two_blocks();
        split_pieces(&mut p, 16, 1, 0.6);
        assert_eq!(p.count(1), 3);
        // The same layout with stem where leaf 2 was.
        let mut p = two_blocks();
        for (i, v) in p.instance.iter_mut().enumerate() {
            if *v == 2 {
                *v = 0;
                p.semantic[i] = phyllo_contract::STEM;
            }
        }
        p.segments.truncate(1);
        split_pieces(&mut p, 16, 1, 0.0);
        assert_eq!(p.count(1), 2, "two leaves either side of the stem");
    }
}
