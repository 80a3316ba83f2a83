//! Segmentation quality against exact labels: per-image mean leaf IoU with the
//! paper's lenient stem rule, and panoptic quality (PQ) of leaves.

use std::collections::{BTreeMap, BTreeSet};

use phyllo_contract::{Contract, LEAF, STEM};
use phyllo_inference::counter::Analysis;
use serde::Serialize;

/// A per-pixel panoptic map at image resolution.
#[derive(Debug, Clone)]
pub struct PixelMap {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Semantic class per pixel.
    pub class: Vec<u8>,
    /// Instance per pixel (0: none).
    pub instance: Vec<u32>,
}

impl PixelMap {
    /// Decodes a contract label (class * divisor + instance per pixel).
    pub fn from_label(c: &Contract, width: usize, height: usize, values: &[u16]) -> Self {
        let (class, instance) = values
            .iter()
            .map(|&v| {
                let (cl, i) = c.decode_label(v);
                (cl, u32::from(i))
            })
            .unzip();
        Self {
            width,
            height,
            class,
            instance,
        }
    }

    /// The model's prediction brought back to image pixels (nearest output pixel).
    pub fn from_analysis(c: &Contract, a: &Analysis, width: usize, height: usize) -> Self {
        let pan = &a.panoptic;
        let s = c.outputs.stride as f32;
        let mut class = vec![0u8; width * height];
        let mut instance = vec![0u32; width * height];
        for y in 0..height {
            let cy = (y as f32 + 0.5) * a.canvas.scale - a.canvas.origin[1] as f32;
            for x in 0..width {
                let cx = (x as f32 + 0.5) * a.canvas.scale - a.canvas.origin[0] as f32;
                if cx < 0.0 || cy < 0.0 {
                    continue;
                }
                let (ox, oy) = ((cx / s) as usize, (cy / s) as usize);
                if ox < pan.width && oy < pan.height {
                    let i = oy * pan.width + ox;
                    class[y * width + x] = pan.semantic[i];
                    let id = pan.instance[i];
                    instance[y * width + x] = id;
                    if id > 0 {
                        class[y * width + x] = pan.segments[id as usize - 1].class;
                    }
                }
            }
        }
        Self {
            width,
            height,
            class,
            instance,
        }
    }

    /// Number of leaf instances with at least `min_pixels` pixels.
    pub fn countable_leaves(&self, min_pixels: usize) -> u32 {
        let mut area = BTreeMap::<u32, usize>::new();
        for (c, i) in self.class.iter().zip(&self.instance) {
            if *c == LEAF && *i > 0 {
                *area.entry(*i).or_default() += 1;
            }
        }
        area.values().filter(|a| **a >= min_pixels).count() as u32
    }
}

/// Leaf segmentation scores of one image.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LeafMatch {
    /// Mean over true leaves of the IoU with their matched predicted leaf (0 if unmatched).
    pub mean_iou: f64,
    /// Sum of IoUs of true positives (IoU > 0.5), for dataset-wide PQ.
    pub tp_iou_sum: f64,
    /// True positives.
    pub tp: usize,
    /// Predicted leaves without a match.
    pub fp: usize,
    /// True leaves without a match.
    pub fn_: usize,
}

/// Pixel overlaps between the true and the predicted leaves of one image.
#[derive(Debug, Default)]
pub struct Overlaps {
    /// Pixels of each true leaf.
    pub truth_area: BTreeMap<u32, f64>,
    /// Pixels of each predicted leaf.
    pub pred_area: BTreeMap<u32, f64>,
    /// Pixels of each predicted leaf that are stem in the truth.
    pub pred_on_stem: BTreeMap<u32, f64>,
    /// Pixels shared by a true leaf and a predicted leaf, keyed `(true, predicted)`.
    pub shared: BTreeMap<(u32, u32), f64>,
    /// One-to-one pairs `(iou, true, predicted)`, chosen greedily by
    /// decreasing IoU (see [`Overlaps::of`] for the IoU rule).
    pub pairs: Vec<(f64, u32, u32)>,
}

impl Overlaps {
    /// Counts the overlaps of two maps of the same size and pairs their leaves.
    ///
    /// IoU follows the paper's lenient rule: a pixel that is stem in the truth
    /// but belongs to the predicted leaf counts as agreement (leaf sheaths and
    /// the stem are hard to tell apart, even for annotators), so it is dropped
    /// from the union instead of counting against the prediction.
    pub fn of(truth: &PixelMap, pred: &PixelMap) -> Self {
        let mut o = Self::default();
        for i in 0..truth.class.len() {
            let t = (truth.class[i] == LEAF && truth.instance[i] > 0).then_some(truth.instance[i]);
            let p = (pred.class[i] == LEAF && pred.instance[i] > 0).then_some(pred.instance[i]);
            if let Some(t) = t {
                *o.truth_area.entry(t).or_default() += 1.0;
            }
            if let Some(p) = p {
                *o.pred_area.entry(p).or_default() += 1.0;
                if truth.class[i] == STEM {
                    *o.pred_on_stem.entry(p).or_default() += 1.0;
                }
            }
            if let (Some(t), Some(p)) = (t, p) {
                *o.shared.entry((t, p)).or_default() += 1.0;
            }
        }
        o.pairs = o.greedy_pairs();
        o
    }

    fn greedy_pairs(&self) -> Vec<(f64, u32, u32)> {
        let mut candidates: Vec<(f64, u32, u32)> = self
            .shared
            .iter()
            .map(|(&(t, p), &n)| {
                let on_stem = self.pred_on_stem.get(&p).copied().unwrap_or(0.0);
                let union = self.truth_area[&t] + self.pred_area[&p] - n - on_stem;
                (n / union.max(1.0), t, p)
            })
            .collect();
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut t_used = BTreeSet::new();
        let mut p_used = BTreeSet::new();
        candidates.retain(|&(_, t, p)| {
            let free = !t_used.contains(&t) && !p_used.contains(&p);
            if free {
                t_used.insert(t);
                p_used.insert(p);
            }
            free
        });
        candidates
    }
}

impl LeafMatch {
    /// Scores one image's overlaps; a pair with IoU above 0.5 is a true positive.
    pub fn of(o: &Overlaps) -> Self {
        let mut m = LeafMatch::default();
        let mut iou_sum = 0.0;
        for &(iou, _, _) in &o.pairs {
            iou_sum += iou;
            if iou > 0.5 {
                m.tp += 1;
                m.tp_iou_sum += iou;
            }
        }
        m.mean_iou = if o.truth_area.is_empty() {
            1.0
        } else {
            iou_sum / o.truth_area.len() as f64
        };
        m.fp = o.pred_area.len() - m.tp;
        m.fn_ = o.truth_area.len() - m.tp;
        m
    }
}

/// Dataset-wide panoptic quality of leaves: Σ IoU(TP) / (TP + FP/2 + FN/2).
pub fn panoptic_quality(matches: &[LeafMatch]) -> f64 {
    let tp: usize = matches.iter().map(|m| m.tp).sum();
    let fp: usize = matches.iter().map(|m| m.fp).sum();
    let fn_: usize = matches.iter().map(|m| m.fn_).sum();
    let iou: f64 = matches.iter().map(|m| m.tp_iou_sum).sum();
    let denom = tp as f64 + 0.5 * (fp + fn_) as f64;
    if denom == 0.0 {
        1.0
    } else {
        iou / denom
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn match_leaves(truth: &PixelMap, pred: &PixelMap) -> LeafMatch {
        LeafMatch::of(&Overlaps::of(truth, pred))
    }

    fn map(rows: &[&str]) -> PixelMap {
        // '.' background, 's' stem, digits = leaf instance.
        let w = rows[0].len();
        let mut class = Vec::new();
        let mut instance = Vec::new();
        for r in rows {
            for ch in r.chars() {
                match ch {
                    '.' => (class.push(0), instance.push(0)),
                    's' => (class.push(STEM), instance.push(0)),
                    d => (class.push(LEAF), instance.push(d.to_digit(10).unwrap())),
                };
            }
        }
        PixelMap {
            width: w,
            height: rows.len(),
            class,
            instance,
        }
    }

    #[test]
    fn identical_maps_score_one() {
        let t = map(&["11..22", "11s.22"]);
        let m = match_leaves(&t, &t);
        assert_eq!((m.mean_iou, m.tp, m.fp, m.fn_), (1.0, 2, 0, 0));
        assert_eq!(panoptic_quality(&[m]), 1.0);
    }

    #[test]
    fn predicted_leaf_over_true_stem_is_not_penalised() {
        let t = map(&["11ss", "11ss"]);
        let p = map(&["1111", "1111"]);
        let m = match_leaves(&t, &p);
        assert_eq!(m.mean_iou, 1.0);
        // Over background it is.
        let p = map(&["1111", "1111"]);
        let t = map(&["11..", "11.."]);
        assert_eq!(match_leaves(&t, &p).mean_iou, 0.5);
    }

    #[test]
    fn merged_leaves_cost_a_false_negative() {
        let t = map(&["1122", "1122"]);
        let p = map(&["3333", "3333"]);
        let m = match_leaves(&t, &p);
        assert_eq!((m.tp, m.fp, m.fn_), (0, 1, 2));
        assert_eq!(m.mean_iou, 0.25);
        assert_eq!(t.countable_leaves(1), 2);
        assert_eq!(t.countable_leaves(5), 0);
    }
}
