//! Panoptic-DeepLab post-processing: from the three model heads to instances.
//!
//! 1. semantic argmax per pixel;
//! 2. instance centres = local maxima of the centre heatmap above a threshold
//!    after max-pool NMS, keeping the `top_k` strongest;
//! 3. every "thing" pixel moves by its predicted offset and joins the nearest
//!    centre, so pieces of one leaf split by an occluding leaf still join one
//!    instance;
//! 4. each instance takes the majority class of its pixels;
//! 5. instances smaller than the minimum area are dropped;
//! 6. with a model that has a tip output, leaf tips = local maxima of the
//!    tip heatmap, found like the centres (see [`crate::tips`]).
//!
//! Everything here works in output pixels (the model's stride).

use ndarray::{Array2, Array3};
use phyllo_contract::{Contract, PostprocessDefaults, NUM_CLASSES};
use serde::{Deserialize, Serialize};

use crate::panoptic::{extents, TipPeak};
use crate::pieces::{
    DEFAULT_SPECK_DISTANCE, DEFAULT_SPLIT_GAP, DEFAULT_SPLIT_MAX_LEAF_SHARE, DEFAULT_SPLIT_MIN_AREA,
};
use crate::tips::{CountRule, DEFAULT_TIP_REACH};

/// Re-exported because the daemon's evaluation code names them by this
/// path, from before they moved to [`crate::panoptic`].
pub use crate::panoptic::{Panoptic, Segment};

/// The three heads of a Panoptic-DeepLab model for one image (or one stitched canvas).
#[derive(Debug, Clone)]
pub struct RawOutputs {
    /// Semantic logits, `[classes, h, w]`.
    pub semantic: Array3<f32>,
    /// Centre heatmap, `[h, w]`.
    pub center: Array2<f32>,
    /// Offsets `(dy, dx)` to the instance centre in output pixels, `[2, h, w]`.
    pub offset: Array3<f32>,
    /// Leaf-tip heatmap `[h, w]`, for models with the optional tip output.
    pub tip: Option<Array2<f32>>,
}

impl RawOutputs {
    /// All-zero outputs of `h` x `w` output pixels.
    pub fn zeros(h: usize, w: usize) -> Self {
        Self {
            semantic: Array3::zeros((NUM_CLASSES, h, w)),
            center: Array2::zeros((h, w)),
            offset: Array3::zeros((2, h, w)),
            tip: None,
        }
    }

    /// Height and width in output pixels.
    pub fn dim(&self) -> (usize, usize) {
        self.center.dim()
    }
}

/// Post-processing parameters (defaults from the contract).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PostprocessParams {
    /// Minimum heatmap value of a centre.
    pub center_threshold: f32,
    /// Max-pool kernel side for centre NMS (odd), in output pixels.
    pub nms_kernel: u32,
    /// Most centres kept.
    pub top_k: usize,
    /// Smallest instance kept, in output pixels.
    pub min_leaf_area: u32,
    /// Gaps up to this many output pixels still join plant pixels into one
    /// body; instances apart from the plant's body are dropped (0: keep all).
    /// See [`crate::attachment`].
    pub attach_radius: u32,
    /// Minimum tip heatmap value of a leaf tip (models with a tip output).
    pub tip_threshold: f32,
    /// Max-pool kernel side for tip NMS (odd), in output pixels.
    pub tip_nms_kernel: u32,
    /// A tip belongs to a leaf with a pixel this many output pixels away or
    /// nearer (Chebyshev). See [`crate::tips`].
    pub tip_reach: u32,
    /// How leaves are counted; every rule counts centres with a model that
    /// has no tip output. See [`CountRule`].
    pub count_rule: CountRule,
    /// A leaf instance's separate pieces of at least this many output
    /// pixels become leaves of their own (0: off). See [`crate::pieces`].
    pub split_min_area: u32,
    /// Pieces of an instance this many output pixels apart or nearer
    /// (Chebyshev) are one piece.
    pub split_gap: u32,
    /// A piece stays with its instance when more than this share of the
    /// shortest route to the instance's largest piece runs over another leaf
    /// (occlusion, not a second leaf); 1 splits every large piece.
    pub split_max_leaf_share: f32,
    /// Crumbs of a leaf instance (pieces under `split_min_area`) farther
    /// than this many output pixels from its largest piece are taken from
    /// it: specks on the chamber joined to a far leaf (0: keep them).
    pub speck_distance: u32,
}

/// Default [`PostprocessParams::attach_radius`]: 3 output pixels, 24 pixels
/// of the full 2454x2056 camera frame.
pub const DEFAULT_ATTACH_RADIUS: u32 = 3;

impl From<&PostprocessDefaults> for PostprocessParams {
    fn from(d: &PostprocessDefaults) -> Self {
        Self {
            center_threshold: d.center_threshold,
            nms_kernel: d.nms_kernel,
            top_k: d.top_k,
            min_leaf_area: d.min_leaf_area,
            attach_radius: DEFAULT_ATTACH_RADIUS,
            tip_threshold: d.tip_threshold,
            tip_nms_kernel: d.tip_nms_kernel,
            tip_reach: DEFAULT_TIP_REACH,
            count_rule: CountRule::default(),
            split_min_area: DEFAULT_SPLIT_MIN_AREA,
            split_gap: DEFAULT_SPLIT_GAP,
            split_max_leaf_share: DEFAULT_SPLIT_MAX_LEAF_SHARE,
            speck_distance: DEFAULT_SPECK_DISTANCE,
        }
    }
}

impl Default for PostprocessParams {
    fn default() -> Self {
        (&Contract::embedded().postprocess).into()
    }
}

/// Instance centres `(y, x, score)`, strongest first.
pub fn find_centres(center: &Array2<f32>, params: &PostprocessParams) -> Vec<(usize, usize, f32)> {
    find_peaks(center, params.center_threshold, params.nms_kernel, params.top_k)
}

/// Peaks `(y, x, score)` of a heatmap, strongest first (ties in raster
/// order): pixels at or above `threshold` that are the maximum of the
/// `kernel` x `kernel` window around them (max-pool NMS), one per plateau,
/// at most `top_k` of them.
pub fn find_peaks(heat: &Array2<f32>, threshold: f32, kernel: u32, top_k: usize) -> Vec<(usize, usize, f32)> {
    let (h, w) = heat.dim();
    let r = (kernel / 2) as usize;
    let heat = heat.as_standard_layout();
    let heat = heat.as_slice().expect("standard layout");
    // Separable max filter: rows, then columns.
    let mut row_max = vec![f32::NEG_INFINITY; h * w];
    for y in 0..h {
        let row = &heat[y * w..(y + 1) * w];
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r + 1).min(w));
            row_max[y * w + x] = row[a..b].iter().copied().fold(f32::NEG_INFINITY, f32::max);
        }
    }
    let mut peaks = Vec::new();
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let v = heat[y * w + x];
            if v < threshold {
                continue;
            }
            let m = (a..b)
                .map(|yy| row_max[yy * w + x])
                .fold(f32::NEG_INFINITY, f32::max);
            if v < m {
                continue;
            }
            // A plateau would give several equal maxima: keep the first in
            // raster order so one peak yields one centre.
            let earlier_tie = (a..=y).any(|yy| {
                let (xa, xb) = (x.saturating_sub(r), (x + r + 1).min(w));
                (xa..xb).any(|xx| (yy < y || xx < x) && heat[yy * w + xx] == v)
            });
            if !earlier_tie {
                peaks.push((y, x, v));
            }
        }
    }
    peaks.sort_by(|a, b| b.2.total_cmp(&a.2).then((a.0, a.1).cmp(&(b.0, b.1))));
    peaks.truncate(top_k);
    peaks
}

/// Runs the whole post-processing on `out`.
pub fn panoptic(out: &RawOutputs, contract: &Contract, params: &PostprocessParams) -> Panoptic {
    let (h, w) = out.dim();
    let n = h * w;
    let sem = out.semantic.as_standard_layout();
    let sem = sem.as_slice().expect("standard layout");
    let off = out.offset.as_standard_layout();
    let off = off.as_slice().expect("standard layout");

    // Semantic argmax; the softmax probability of the winner is only needed
    // on thing pixels (for instance scores), so only they pay for the exps.
    let mut semantic = vec![0u8; n];
    let mut prob = vec![0f32; n];
    for i in 0..n {
        let logits: [f32; NUM_CLASSES] = std::array::from_fn(|c| sem[c * n + i]);
        let mut best = 0;
        for c in 1..NUM_CLASSES {
            if logits[c] > logits[best] {
                best = c;
            }
        }
        semantic[i] = best as u8;
        if contract.is_thing(best as u8) {
            let top = logits[best];
            prob[i] = 1.0 / logits.iter().map(|&l| (l - top).exp()).sum::<f32>();
        }
    }

    let centres = find_centres(&out.center, params);
    let mut instance = vec![0u32; n];
    let k = centres.len();
    let mut class_votes = vec![[0u32; NUM_CLASSES]; k];
    if k > 0 {
        let cy: Vec<f32> = centres.iter().map(|c| c.0 as f32).collect();
        let cx: Vec<f32> = centres.iter().map(|c| c.1 as f32).collect();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if !contract.is_thing(semantic[i]) {
                    continue;
                }
                let ty = y as f32 + off[i];
                let tx = x as f32 + off[n + i];
                let mut best = 0;
                let mut best_d = f32::INFINITY;
                for j in 0..k {
                    let d = (cy[j] - ty).powi(2) + (cx[j] - tx).powi(2);
                    if d < best_d {
                        best_d = d;
                        best = j;
                    }
                }
                instance[i] = best as u32 + 1;
                class_votes[best][semantic[i] as usize] += 1;
            }
        }
    }

    // Per-instance statistics: area and box, and the class probability sum for the score.
    let ext = extents(&instance, w, k);
    let mut prob_sum = vec![0f32; k + 1];
    for (i, &id) in instance.iter().enumerate() {
        prob_sum[id as usize] += prob[i];
    }
    // Keep instances above the minimum area; renumber densely in score order.
    let mut renumber = vec![0u32; k + 1];
    let mut segments = Vec::new();
    for (j, &(area, bbox)) in ext.iter().enumerate().skip(1).map(|(id, e)| (id - 1, e)) {
        if area < params.min_leaf_area.max(1) {
            continue;
        }
        let class = class_votes[j]
            .iter()
            .enumerate()
            .max_by_key(|(c, v)| (**v, std::cmp::Reverse(*c)))
            .map(|(c, _)| c as u8)
            .expect("4 classes");
        let id = segments.len() as u32 + 1;
        renumber[j + 1] = id;
        let (py, px, peak) = centres[j];
        segments.push(Segment {
            id,
            class,
            area,
            bbox,
            centre: [px as f32, py as f32],
            score: peak.min(1.0) * prob_sum[j + 1] / area as f32,
        });
    }
    for v in instance.iter_mut() {
        *v = renumber[*v as usize];
    }
    let tips = out.tip.as_ref().map(|tip| {
        find_peaks(tip, params.tip_threshold, params.tip_nms_kernel, params.top_k)
            .into_iter()
            .map(|(y, x, score)| TipPeak {
                x: x as u32,
                y: y as u32,
                score,
            })
            .collect()
    });
    Panoptic {
        height: h,
        width: w,
        semantic,
        instance,
        segments,
        tips,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> PostprocessParams {
        PostprocessParams {
            center_threshold: 0.1,
            nms_kernel: 7,
            top_k: 10,
            min_leaf_area: 1,
            attach_radius: 0,
            ..PostprocessParams::default()
        }
    }

    #[test]
    fn nms_keeps_one_centre_per_peak_even_on_a_plateau() {
        let mut c = Array2::zeros((20, 20));
        c[[5, 5]] = 0.9;
        c[[5, 6]] = 0.5;
        c[[15, 15]] = 0.7;
        c[[15, 16]] = 0.7;
        c[[2, 18]] = 0.05; // below threshold
        let got = find_centres(&c, &params());
        assert_eq!(got, vec![(5, 5, 0.9), (15, 15, 0.7)]);
    }

    #[test]
    fn top_k_keeps_the_strongest() {
        let mut c = Array2::zeros((10, 40));
        for i in 0..4 {
            c[[5, 5 + 10 * i]] = 0.2 + 0.1 * i as f32;
        }
        let p = PostprocessParams { top_k: 2, ..params() };
        let got: Vec<_> = find_centres(&c, &p).iter().map(|c| c.1).collect();
        assert_eq!(got, vec![35, 25]);
    }

    #[test]
    fn find_centres_is_find_peaks_with_the_centre_parameters() {
        // A bumpy deterministic heatmap with plateaus and many local maxima.
        let c = Array2::from_shape_fn((40, 50), |(y, x)| ((y * 7 + x * 13) % 17) as f32 / 16.0);
        for p in [
            params(),
            PostprocessParams::default(),
            PostprocessParams { top_k: 3, ..params() },
        ] {
            let got = find_centres(&c, &p);
            assert!(!got.is_empty());
            assert_eq!(got, find_peaks(&c, p.center_threshold, p.nms_kernel, p.top_k));
        }
    }

    #[test]
    fn find_peaks_takes_its_own_kernel_and_threshold() {
        // Two tips three pixels apart: one NMS window of 7 holds both, one of
        // 5 does not.
        let mut t = Array2::zeros((12, 12));
        t[[6, 4]] = 0.8;
        t[[6, 7]] = 0.6;
        assert_eq!(find_peaks(&t, 0.3, 7, 64), vec![(6, 4, 0.8)]);
        assert_eq!(find_peaks(&t, 0.3, 5, 64), vec![(6, 4, 0.8), (6, 7, 0.6)]);
        assert_eq!(find_peaks(&t, 0.7, 5, 64), vec![(6, 4, 0.8)]);
        assert_eq!(find_peaks(&t, 0.3, 5, 1), vec![(6, 4, 0.8)]);
    }

    #[test]
    fn panoptic_finds_tips_only_with_a_tip_map() {
        let c = Contract::embedded();
        let p = PostprocessParams::default();
        let mut out = RawOutputs::zeros(16, 16);
        assert_eq!(panoptic(&out, c, &p).tips, None, "no tip output, no tips");
        out.tip = Some(Array2::from_elem((16, 16), 0.01));
        assert_eq!(
            panoptic(&out, c, &p).tips,
            Some(vec![]),
            "a tip output that found none"
        );
        let tip = out.tip.as_mut().unwrap();
        tip[[3, 9]] = 0.9;
        tip[[12, 2]] = 0.5;
        tip[[12, 3]] = 0.4; // inside the first peak's NMS window
        assert_eq!(
            panoptic(&out, c, &p).tips,
            Some(vec![
                TipPeak {
                    x: 9,
                    y: 3,
                    score: 0.9
                },
                TipPeak {
                    x: 2,
                    y: 12,
                    score: 0.5
                },
            ])
        );
    }
}
