//! Centres confirmed by offset votes, for leaves whose heatmap peak is lost.
//!
//! A small leaf tucked against a larger one often gets no centre of its own:
//! its heatmap peak is weak, or it merges into the neighbour's peak inside
//! the NMS window, so its pixels join the neighbour's instance (the dominant
//! synthetic error, see `models/MODEL.md`). Its offsets can still point at
//! its own centre. Every thing pixel casts a vote at `pixel + offset`; a
//! cluster of votes far enough from every heatmap centre, on a spot the
//! heatmap does not rule out, becomes a centre too (a Hough-style check).
//! Lowering the heatmap threshold alone also adds centres, but on spots no
//! pixel points at, which over-counts real leaves.

use ndarray::Array2;

/// Vote-confirmation settings, all in output pixels; `min_votes` 0 turns it off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoteParams {
    /// Smallest number of votes within one pixel of a new centre.
    pub min_votes: u32,
    /// Smallest heatmap value at a new centre.
    pub min_heat: f32,
    /// Smallest distance from a new centre to every other centre.
    pub min_distance: f32,
}

/// Extra centres `(y, x, heat)` supported by votes, strongest vote first,
/// none closer than `min_distance` to `centres` or to one another.
///
/// `thing` marks the pixels that vote; `offset` is `(dy, dx)` row-major,
/// `[2, h, w]` flattened.
pub fn vote_centres(
    center: &Array2<f32>,
    thing: &[bool],
    offset: &[f32],
    centres: &[(usize, usize, f32)],
    params: &VoteParams,
) -> Vec<(usize, usize, f32)> {
    if params.min_votes == 0 {
        return Vec::new();
    }
    let (h, w) = center.dim();
    let n = h * w;
    let mut votes = vec![0u32; n];
    for (i, _) in thing.iter().enumerate().filter(|(_, t)| **t) {
        let ty = (i / w) as f32 + offset[i];
        let tx = (i % w) as f32 + offset[n + i];
        let (ty, tx) = (ty.round(), tx.round());
        if ty >= 0.0 && tx >= 0.0 && (ty as usize) < h && (tx as usize) < w {
            votes[ty as usize * w + tx as usize] += 1;
        }
    }
    // Votes within one pixel (3x3 box): offsets are not exact to the pixel.
    let mut support = vec![0u32; n];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0;
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    s += votes[yy * w + xx];
                }
            }
            support[y * w + x] = s;
        }
    }
    let mut candidates: Vec<(usize, usize, u32)> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let s = support[y * w + x];
            let key = (s, votes[y * w + x]);
            if s < params.min_votes || center[[y, x]] < params.min_heat || !heat_peak(center, y, x) {
                continue;
            }
            // A local maximum of the support in its 3x3 window; on a plateau
            // the pixel with most votes of its own, then the first in raster
            // order.
            let mut is_max = true;
            'window: for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    let o = (support[yy * w + xx], votes[yy * w + xx]);
                    if o > key || (o == key && (yy, xx) < (y, x)) {
                        is_max = false;
                        break 'window;
                    }
                }
            }
            if is_max {
                candidates.push((y, x, s));
            }
        }
    }
    candidates.sort_by(|a, b| b.2.cmp(&a.2).then((a.0, a.1).cmp(&(b.0, b.1))));
    let d2 = params.min_distance * params.min_distance;
    let near = |y: usize, x: usize, other: &(usize, usize, f32)| {
        let (dy, dx) = (other.0 as f32 - y as f32, other.1 as f32 - x as f32);
        dy * dy + dx * dx < d2
    };
    let mut found: Vec<(usize, usize, f32)> = Vec::new();
    for (y, x, _) in candidates {
        if !centres.iter().chain(found.iter()).any(|o| near(y, x, o)) {
            found.push((y, x, center[[y, x]]));
        }
    }
    found
}

/// Whether `(y, x)` is a maximum of the heatmap in its 3x3 window: a peak
/// of its own, however weak, not the slope of a neighbour's.
fn heat_peak(center: &Array2<f32>, y: usize, x: usize) -> bool {
    let (h, w) = center.dim();
    let v = center[[y, x]];
    (y.saturating_sub(1)..(y + 2).min(h))
        .all(|yy| (x.saturating_sub(1)..(x + 2).min(w)).all(|xx| center[[yy, xx]] <= v))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `h` x `w` field where the pixels of each `(y0, y1, x0, x1, cy, cx)`
    /// box are things pointing at `(cy, cx)`.
    fn field(h: usize, w: usize, boxes: &[(usize, usize, usize, usize, f32, f32)]) -> (Vec<bool>, Vec<f32>) {
        let n = h * w;
        let mut thing = vec![false; n];
        let mut off = vec![0f32; 2 * n];
        for &(y0, y1, x0, x1, cy, cx) in boxes {
            for y in y0..y1 {
                for x in x0..x1 {
                    let i = y * w + x;
                    thing[i] = true;
                    off[i] = cy - y as f32;
                    off[n + i] = cx - x as f32;
                }
            }
        }
        (thing, off)
    }

    const PARAMS: VoteParams = VoteParams {
        min_votes: 10,
        min_heat: 0.05,
        min_distance: 4.0,
    };

    #[test]
    fn a_leaf_pointing_away_from_the_known_centre_gets_its_own() {
        let (thing, off) = field(30, 30, &[(5, 15, 5, 15, 10.0, 10.0), (5, 15, 16, 20, 10.0, 18.0)]);
        let heat = Array2::from_elem((30, 30), 0.1);
        let got = vote_centres(&heat, &thing, &off, &[(10, 10, 0.9)], &PARAMS);
        assert_eq!(got, vec![(10, 18, 0.1)]);
    }

    #[test]
    fn votes_near_a_known_centre_add_nothing() {
        let (thing, off) = field(30, 30, &[(5, 15, 5, 15, 10.0, 10.0), (5, 15, 16, 20, 10.0, 12.0)]);
        let heat = Array2::from_elem((30, 30), 0.1);
        assert!(vote_centres(&heat, &thing, &off, &[(10, 10, 0.9)], &PARAMS).is_empty());
    }

    #[test]
    fn too_few_votes_cold_heatmap_or_off_add_nothing() {
        let (thing, off) = field(30, 30, &[(5, 15, 5, 15, 10.0, 10.0), (5, 7, 16, 20, 10.0, 18.0)]);
        let heat = Array2::from_elem((30, 30), 0.1);
        assert!(vote_centres(&heat, &thing, &off, &[(10, 10, 0.9)], &PARAMS).is_empty());

        let (thing, off) = field(30, 30, &[(5, 15, 5, 15, 10.0, 10.0), (5, 15, 16, 20, 10.0, 18.0)]);
        let cold = Array2::from_elem((30, 30), 0.01);
        assert!(vote_centres(&cold, &thing, &off, &[(10, 10, 0.9)], &PARAMS).is_empty());
        let off_params = VoteParams {
            min_votes: 0,
            ..PARAMS
        };
        assert!(vote_centres(&heat, &thing, &off, &[(10, 10, 0.9)], &off_params).is_empty());
    }
}
