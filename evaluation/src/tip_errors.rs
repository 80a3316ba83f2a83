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

/// What became of one marked tip.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum TipFate {
    /// Reached by this predicted leaf, which reaches no other tip.
    OwnLeaf(u32),
    /// Reached by this predicted leaf, which reaches other tips too.
    Sharing(u32),
    /// No predicted leaf pixel within the radius.
    Unreached,
}

/// One image's tips matched to its predicted leaves, tip by tip.
#[derive(Debug, Clone, PartialEq)]
pub struct TipMatch {
    /// The fate of each tip, in the order given.
    pub fates: Vec<TipFate>,
    /// Predicted leaves reaching no tip, with their areas in image pixels.
    pub extras: Vec<(u32, u64)>,
    /// The tally.
    pub outcome: TipOutcome,
}

impl TipMatch {
    /// Matches `tips` (`[x, y]` in image pixels) to the leaves of `pred`
    /// that have a pixel within `radius` of them (see [`assign_tips`]).
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
        let nearest = assign_tips(tips, pred, radius);
        let mut reached: BTreeMap<u32, usize> = BTreeMap::new();
        for id in nearest.iter().flatten() {
            *reached.entry(*id).or_default() += 1;
        }
        let fates = nearest
            .iter()
            .map(|n| match n {
                None => TipFate::Unreached,
                Some(id) if reached[id] == 1 => TipFate::OwnLeaf(*id),
                Some(id) => TipFate::Sharing(*id),
            })
            .collect();
        let mut outcome = TipOutcome {
            tips: tips.len(),
            extra: vec![0; EXTRA_AREA_CLASSES.len() + 1],
            predicted: area.len(),
            unreached: nearest.iter().filter(|n| n.is_none()).count(),
            ..TipOutcome::default()
        };
        let mut extras = Vec::new();
        for (&id, &px) in &area {
            match reached.get(&id).copied().unwrap_or(0) {
                0 => {
                    outcome.extra[EXTRA_AREA_CLASSES.iter().take_while(|hi| px >= **hi).count()] += 1;
                    extras.push((id, px));
                }
                1 => outcome.own_leaf += 1,
                k => {
                    outcome.sharing += k;
                    outcome.merged_away += k - 1;
                }
            }
        }
        Self {
            fates,
            extras,
            outcome,
        }
    }
}

impl TipOutcome {
    /// Predicted leaves reaching no tip.
    pub fn extra_total(&self) -> usize {
        self.extra.iter().sum()
    }
}

/// Gives each tip a predicted leaf with a pixel within `radius`, or none.
///
/// Pairs are made one to one first, nearest first, so two tips that lie
/// close together at the ends of two leaves go one to each; only a tip whose
/// every leaf in reach is already taken shares its nearest one (a merge).
pub fn assign_tips(tips: &[[f32; 2]], pred: &PixelMap, radius: f32) -> Vec<Option<u32>> {
    let mut pairs: Vec<(f32, usize, u32)> = Vec::new();
    for (t, tip) in tips.iter().enumerate() {
        pairs.extend(
            leaves_in_reach(pred, *tip, radius)
                .into_iter()
                .map(|(id, d2)| (d2, t, id)),
        );
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut leaf_of: Vec<Option<u32>> = vec![None; tips.len()];
    let mut taken = std::collections::BTreeSet::new();
    for &(_, t, id) in &pairs {
        if leaf_of[t].is_none() && !taken.contains(&id) {
            leaf_of[t] = Some(id);
            taken.insert(id);
        }
    }
    // Pairs are sorted nearest first, so the first pair of a tip is its nearest leaf.
    for &(_, t, id) in &pairs {
        if leaf_of[t].is_none() {
            leaf_of[t] = Some(id);
        }
    }
    leaf_of
}

/// Each predicted leaf with a pixel within `radius` of `tip`, with the
/// squared distance of its nearest such pixel's centre.
fn leaves_in_reach(pred: &PixelMap, [tx, ty]: [f32; 2], radius: f32) -> BTreeMap<u32, f32> {
    let r = radius.max(0.0).ceil() as i64;
    let (cx, cy) = (tx.floor() as i64, ty.floor() as i64);
    let mut near: BTreeMap<u32, f32> = BTreeMap::new();
    for y in (cy - r).max(0)..=(cy + r).min(pred.height as i64 - 1) {
        for x in (cx - r).max(0)..=(cx + r).min(pred.width as i64 - 1) {
            let i = y as usize * pred.width + x as usize;
            if pred.class[i] != LEAF || pred.instance[i] == 0 {
                continue;
            }
            let d2 = (x as f32 + 0.5 - tx).powi(2) + (y as f32 + 0.5 - ty).powi(2);
            if d2 <= radius * radius {
                let e = near.entry(pred.instance[i]).or_insert(d2);
                *e = e.min(d2);
            }
        }
    }
    near
}

/// The tip outcomes summed over a set of images.
#[derive(Debug, Clone, Serialize, PartialEq)]
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
            images: 0,
            radius,
            total: TipOutcome {
                extra: vec![0; EXTRA_AREA_CLASSES.len() + 1],
                ..TipOutcome::default()
            },
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
        let o = TipMatch::of(&tips, &pred, 1.5).outcome;
        assert_eq!(o.tips, 4);
        assert_eq!((o.own_leaf, o.sharing, o.merged_away, o.unreached), (1, 2, 1, 1));
        assert_eq!(o.predicted, 4);
        assert_eq!(o.extra, vec![2, 0, 0]);
        let m = TipMatch::of(&tips, &pred, 1.5);
        assert_eq!(
            m.fates,
            vec![
                TipFate::Sharing(1),
                TipFate::Sharing(1),
                TipFate::OwnLeaf(2),
                TipFate::Unreached
            ]
        );
        assert_eq!(m.extras, vec![(3, 1), (4, 1)]);
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
        let o = TipMatch::of(&[[1.4, 0.5]], &pred, 3.0).outcome;
        assert_eq!((o.own_leaf, o.extra_total()), (1, 1));
        // Outside the image, nothing is reached.
        let o = TipMatch::of(&[[40.0, 40.0]], &pred, 3.0).outcome;
        assert_eq!((o.unreached, o.extra_total()), (1, 2));
    }

    #[test]
    fn two_tips_between_two_leaves_go_one_to_each() {
        // Both tips are nearer leaf 1, but leaf 2 is within reach of the second.
        let pred = map(&["11..2"]);
        let tips = [[2.2, 0.5], [2.6, 0.5]];
        assert_eq!(assign_tips(&tips, &pred, 3.0), vec![Some(1), Some(2)]);
        let o = TipMatch::of(&tips, &pred, 3.0).outcome;
        assert_eq!((o.own_leaf, o.sharing, o.extra_total()), (2, 0, 0));
        // With leaf 2 out of reach, they share leaf 1.
        assert_eq!(assign_tips(&tips, &pred, 1.5), vec![Some(1), Some(1)]);
    }

    #[test]
    fn sums_over_images_and_prints_a_row() {
        let pred = map(&["11..22"]);
        let mut e = TipErrors::new(2.0);
        e.add(&TipMatch::of(&[[0.5, 0.5]], &pred, 2.0).outcome);
        e.add(&TipMatch::of(&[[0.5, 0.5], [1.5, 0.5]], &pred, 2.0).outcome);
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
