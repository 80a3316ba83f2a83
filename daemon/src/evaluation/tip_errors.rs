//! Where count errors on real images come from, read off the leaf tips
//! people marked (`leaf_tips.csv`): each tip is reached by a predicted leaf
//! of its own, shares one predicted leaf with other tips (leaves merged), or
//! is reached by none (a leaf missed); each predicted leaf that reaches no
//! tip is an extra one. Real frames have no pixel labels, so this is their
//! counterpart of the synthetic leaf-error table ([`super::leaf_errors`]).

use std::collections::BTreeMap;

use phyllo_contract::LEAF;
use serde::Serialize;

use super::segmentation::PixelMap;

/// Upper bounds (exclusive) of the extra leaves' area classes, in image
/// pixels; the last class is open.
pub const EXTRA_AREA_CLASSES: [u64; 2] = [256, 1024];

/// One image's tips against its predicted leaves.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct TipOutcome {
    /// Tips marked on the image.
    pub tips: usize,
    /// Tips whose nearest predicted leaf reaches no other tip.
    pub own_leaf: usize,
    /// Tips whose nearest predicted leaf also reaches other tips.
    pub sharing: usize,
    /// How many fewer leaves the shared ones make: Σ (tips − 1) over
    /// predicted leaves reaching two or more tips.
    pub merged_away: usize,
    /// Tips with no predicted leaf pixel within the radius.
    pub unreached: usize,
    /// Predicted leaves reaching no tip, by area class (see
    /// [`EXTRA_AREA_CLASSES`]).
    pub extra: Vec<usize>,
    /// Predicted leaves.
    pub predicted: usize,
}

impl TipOutcome {
    /// Matches `tips` (`[x, y]` in image pixels) to the leaves of `pred`: a
    /// tip belongs to the leaf with the nearest pixel within `radius`.
    ///
    /// A predicted leaf often stops a few pixels short of the thin tip a
    /// person marks, hence the radius rather than the pixel under the tip.
    pub fn of(tips: &[[f32; 2]], pred: &PixelMap, radius: f32) -> Self {
        let mut area: BTreeMap<u32, u64> = BTreeMap::new();
        for (c, i) in pred.class.iter().zip(&pred.instance) {
            if *c == LEAF && *i > 0 {
                *area.entry(*i).or_default() += 1;
            }
        }
        let mut reached: BTreeMap<u32, usize> = BTreeMap::new();
        let mut out = TipOutcome {
            tips: tips.len(),
            extra: vec![0; EXTRA_AREA_CLASSES.len() + 1],
            predicted: area.len(),
            ..Self::default()
        };
        for tip in tips {
            match nearest_leaf(pred, *tip, radius) {
                Some(id) => *reached.entry(id).or_default() += 1,
                None => out.unreached += 1,
            }
        }
        for (&id, &px) in &area {
            match reached.get(&id).copied().unwrap_or(0) {
                0 => out.extra[EXTRA_AREA_CLASSES.iter().take_while(|hi| px >= **hi).count()] += 1,
                1 => out.own_leaf += 1,
                k => {
                    out.sharing += k;
                    out.merged_away += k - 1;
                }
            }
        }
        out
    }

    /// Predicted leaves reaching no tip.
    pub fn extra_total(&self) -> usize {
        self.extra.iter().sum()
    }
}

/// The predicted leaf with a pixel nearest to `tip`, if one lies within `radius`.
fn nearest_leaf(pred: &PixelMap, [tx, ty]: [f32; 2], radius: f32) -> Option<u32> {
    let r = radius.max(0.0).ceil() as i64;
    let (cx, cy) = (tx.floor() as i64, ty.floor() as i64);
    let mut best: Option<(f32, u32)> = None;
    for y in (cy - r).max(0)..=(cy + r).min(pred.height as i64 - 1) {
        for x in (cx - r).max(0)..=(cx + r).min(pred.width as i64 - 1) {
            let i = y as usize * pred.width + x as usize;
            if pred.class[i] != LEAF || pred.instance[i] == 0 {
                continue;
            }
            // Distance from the tip to the pixel's centre.
            let d2 = (x as f32 + 0.5 - tx).powi(2) + (y as f32 + 0.5 - ty).powi(2);
            if d2 <= radius * radius && best.is_none_or(|(b, _)| d2 < b) {
                best = Some((d2, pred.instance[i]));
            }
        }
    }
    best.map(|(_, id)| id)
}

/// The tip outcomes summed over a set of images.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct TipErrors {
    /// Images with marked tips.
    pub images: usize,
    /// Search radius around each tip, in image pixels.
    pub radius: f32,
    /// Sums over the images.
    pub total: TipOutcome,
}

impl TipErrors {
    /// An empty sum for tips matched within `radius` image pixels.
    pub fn new(radius: f32) -> Self {
        Self {
            radius,
            total: TipOutcome {
                extra: vec![0; EXTRA_AREA_CLASSES.len() + 1],
                ..TipOutcome::default()
            },
            ..Self::default()
        }
    }

    /// Adds one image.
    pub fn add(&mut self, o: &TipOutcome) {
        let t = &mut self.total;
        self.images += 1;
        t.tips += o.tips;
        t.own_leaf += o.own_leaf;
        t.sharing += o.sharing;
        t.merged_away += o.merged_away;
        t.unreached += o.unreached;
        t.predicted += o.predicted;
        for (a, b) in t.extra.iter_mut().zip(&o.extra) {
            *a += b;
        }
    }

    /// A Markdown table: what became of the tips, and the extra leaves.
    pub fn table(&self) -> String {
        let t = &self.total;
        let mut s = format!(
            "| tips | own leaf | sharing a leaf (fewer leaves) | reached by no leaf | predicted leaves | \
             extra, < {} px | extra, {}–{} px | extra, ≥ {} px |\n",
            EXTRA_AREA_CLASSES[0],
            EXTRA_AREA_CLASSES[0],
            EXTRA_AREA_CLASSES[1] - 1,
            EXTRA_AREA_CLASSES[1]
        );
        s += "|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        s += &format!(
            "| {} | {} | {} ({}) | {} | {} | {} | {} | {} |",
            t.tips,
            t.own_leaf,
            t.sharing,
            t.merged_away,
            t.unreached,
            t.predicted,
            t.extra[0],
            t.extra[1],
            t.extra[2]
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(rows: &[&str]) -> PixelMap {
        // '.' background, digits = leaf instance.
        let mut class = Vec::new();
        let mut instance = Vec::new();
        for r in rows {
            for ch in r.chars() {
                let i = ch.to_digit(10).unwrap_or(0);
                class.push(if i > 0 { LEAF } else { 0 });
                instance.push(i);
            }
        }
        PixelMap {
            width: rows[0].len(),
            height: rows.len(),
            class,
            instance,
        }
    }

    #[test]
    fn tips_are_own_shared_unreached_and_leaves_extra() {
        let pred = map(&["11........", "11.....22.", "..........", "3........4"]);
        // Two tips on leaf 1, one beside leaf 2, one far from everything.
        let tips = [[0.5, 0.5], [1.5, 1.5], [6.0, 1.5], [5.0, 3.5]];
        let o = TipOutcome::of(&tips, &pred, 1.5);
        assert_eq!(o.tips, 4);
        assert_eq!((o.own_leaf, o.sharing, o.merged_away, o.unreached), (1, 2, 1, 1));
        assert_eq!(o.predicted, 4);
        assert_eq!(o.extra, vec![2, 0, 0]);
        // truth − predicted = unreached + merged away − extra
        let diff = o.tips as i64 - o.predicted as i64;
        assert_eq!(
            diff,
            o.unreached as i64 + o.merged_away as i64 - o.extra_total() as i64
        );
    }

    #[test]
    fn a_tip_goes_to_the_nearest_leaf_only() {
        let pred = map(&["1..2"]);
        let o = TipOutcome::of(&[[1.4, 0.5]], &pred, 3.0);
        assert_eq!((o.own_leaf, o.extra_total()), (1, 1));
        // Outside the image, nothing is reached.
        let o = TipOutcome::of(&[[40.0, 40.0]], &pred, 3.0);
        assert_eq!((o.unreached, o.extra_total()), (1, 2));
    }

    #[test]
    fn sums_over_images_and_prints_a_row() {
        let pred = map(&["11..22"]);
        let mut e = TipErrors::new(2.0);
        e.add(&TipOutcome::of(&[[0.5, 0.5]], &pred, 2.0));
        e.add(&TipOutcome::of(&[[0.5, 0.5], [1.5, 0.5]], &pred, 2.0));
        assert_eq!(e.images, 2);
        assert_eq!((e.total.tips, e.total.own_leaf, e.total.sharing), (3, 1, 2));
        assert_eq!(e.total.extra, vec![2, 0, 0]);
        assert!(
            e.table().contains("| 3 | 1 | 2 (1) | 0 | 4 | 2 | 0 | 0 |"),
            "{}",
            e.table()
        );
    }
}
