//! Where count errors come from, leaf by leaf: each true leaf is found,
//! partly found, merged into another leaf's instance, or not seen as leaf at
//! all; each predicted leaf without a true partner is a piece split off a
//! leaf, or lies on stem or background. Missed leaves lower the count and
//! extra ones raise it, so the table says which failure dominates.

use std::collections::BTreeMap;

use serde::Serialize;

use super::segmentation::Overlaps;

/// Upper bounds (exclusive) of the visible-area classes, in image pixels;
/// the last class is open.
pub const AREA_CLASSES: [f64; 3] = [64.0, 256.0, 1024.0];

/// What became of the true leaves whose visible area falls in one class.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct TrueLeaves {
    /// Smallest visible area of the class, in image pixels.
    pub min_px: u32,
    /// First area above the class (`None` for the last, open class).
    pub below_px: Option<u32>,
    /// Matched one to one with a predicted leaf at IoU above 0.5.
    pub found: usize,
    /// The predicted instance covering most of it is its own, but the IoU is
    /// 0.5 or less (only part found, or spilling over); the count is right.
    pub partly_found: usize,
    /// Most of it is predicted leaf, inside an instance that belongs to
    /// another true leaf: one fewer in the count.
    pub merged: usize,
    /// Less than half of it is predicted leaf: one fewer in the count.
    pub not_seen: usize,
}

impl TrueLeaves {
    /// All true leaves of the class.
    pub fn total(&self) -> usize {
        self.found + self.partly_found + self.merged + self.not_seen
    }
}

/// Predicted leaves without a true partner: each one more in the count.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct ExtraLeaves {
    /// Mostly on a true leaf that another predicted instance already covers.
    pub split: usize,
    /// Mostly on true stem (a sheath or collar read as a leaf).
    pub on_stem: usize,
    /// Mostly on background (chamber, pot, panicle).
    pub on_background: usize,
}

/// The breakdown over a set of images.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LeafErrors {
    /// True leaves by visible area, smallest first.
    pub true_leaves: Vec<TrueLeaves>,
    /// Extra predicted leaves.
    pub extra: ExtraLeaves,
}

impl Default for LeafErrors {
    fn default() -> Self {
        let mut lo = 1.0;
        let mut classes = Vec::new();
        for hi in AREA_CLASSES.iter().map(Some).chain([None]) {
            classes.push(TrueLeaves {
                min_px: lo as u32,
                below_px: hi.map(|h| *h as u32),
                ..TrueLeaves::default()
            });
            lo = hi.copied().unwrap_or(lo);
        }
        Self {
            true_leaves: classes,
            extra: ExtraLeaves::default(),
        }
    }
}

/// What one predicted leaf is, against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PredictedLeaf {
    /// Matched one to one with a true leaf at IoU above 0.5.
    Found,
    /// The instance covering most of a partly found true leaf.
    Partner,
    /// An extra one, mostly on a true leaf another instance already covers.
    Split,
    /// An extra one, mostly on true stem.
    OnStem,
    /// An extra one, mostly on background.
    OnBackground,
}

impl PredictedLeaf {
    /// Lower-case name for tables.
    pub fn name(self) -> &'static str {
        match self {
            PredictedLeaf::Found => "found",
            PredictedLeaf::Partner => "partner",
            PredictedLeaf::Split => "split",
            PredictedLeaf::OnStem => "on_stem",
            PredictedLeaf::OnBackground => "on_background",
        }
    }
}

/// Who owns what in one image: the one-to-one matches, and which true and
/// predicted leaves cover each other most.
struct Ownership {
    /// True leaf to its predicted match at IoU above 0.5.
    matched: BTreeMap<u32, u32>,
    /// Predicted leaf to its true match.
    found_by: BTreeMap<u32, u32>,
    /// For each predicted leaf the true leaf it covers most.
    owner: BTreeMap<u32, (u32, f64)>,
    /// For each true leaf the predicted leaf covering most of it.
    cover: BTreeMap<u32, (u32, f64)>,
    /// Predicted-leaf pixels on each true leaf.
    covered: BTreeMap<u32, f64>,
    /// Pixels of each predicted leaf on any true leaf.
    on_leaf: BTreeMap<u32, f64>,
}

impl Ownership {
    fn of(o: &Overlaps) -> Self {
        let matched: BTreeMap<u32, u32> = o
            .pairs
            .iter()
            .filter(|(iou, _, _)| *iou > 0.5)
            .map(|&(_, t, p)| (t, p))
            .collect();
        let found_by = matched.iter().map(|(t, p)| (*p, *t)).collect();
        let mut w = Ownership {
            matched,
            found_by,
            owner: BTreeMap::new(),
            cover: BTreeMap::new(),
            covered: BTreeMap::new(),
            on_leaf: BTreeMap::new(),
        };
        for (&(t, p), &n) in &o.shared {
            if w.owner.get(&p).is_none_or(|b| n > b.1) {
                w.owner.insert(p, (t, n));
            }
            if w.cover.get(&t).is_none_or(|b| n > b.1) {
                w.cover.insert(t, (p, n));
            }
            *w.covered.entry(t).or_default() += n;
            *w.on_leaf.entry(p).or_default() += n;
        }
        w
    }

    fn predicted(&self, o: &Overlaps, p: u32, area: f64) -> PredictedLeaf {
        if self.found_by.contains_key(&p) {
            return PredictedLeaf::Found;
        }
        // The instance covering most of a partly found leaf is that leaf's
        // partner, not an extra one, however much it spills over.
        if let Some(&(t, _)) = self.owner.get(&p) {
            if self.cover.get(&t).map(|c| c.0) == Some(p) && !self.matched.contains_key(&t) {
                return PredictedLeaf::Partner;
            }
        }
        let leaf = self.on_leaf.get(&p).copied().unwrap_or(0.0);
        let stem = o.pred_on_stem.get(&p).copied().unwrap_or(0.0);
        let background = area - leaf - stem;
        if leaf >= stem && leaf >= background {
            PredictedLeaf::Split
        } else if stem >= background {
            PredictedLeaf::OnStem
        } else {
            PredictedLeaf::OnBackground
        }
    }
}

/// What each predicted leaf of one image is, by instance id.
pub fn classify_predicted(o: &Overlaps) -> BTreeMap<u32, PredictedLeaf> {
    let w = Ownership::of(o);
    o.pred_area
        .iter()
        .map(|(&p, &area)| (p, w.predicted(o, p, area)))
        .collect()
}

impl LeafErrors {
    /// Adds one image's leaves.
    pub fn add(&mut self, o: &Overlaps) {
        let w = Ownership::of(o);
        for (&t, &area) in &o.truth_area {
            let class = AREA_CLASSES.iter().take_while(|hi| area >= **hi).count();
            let row = &mut self.true_leaves[class];
            if w.matched.contains_key(&t) {
                row.found += 1;
            } else if w.covered.get(&t).copied().unwrap_or(0.0) < 0.5 * area {
                row.not_seen += 1;
            } else {
                let p = w.cover[&t].0;
                let own = w.owner.get(&p).map(|o| o.0) == Some(t) && !w.found_by.contains_key(&p);
                if own {
                    row.partly_found += 1;
                } else {
                    row.merged += 1;
                }
            }
        }
        for (&p, &area) in &o.pred_area {
            match w.predicted(o, p, area) {
                PredictedLeaf::Found | PredictedLeaf::Partner => {}
                PredictedLeaf::Split => self.extra.split += 1,
                PredictedLeaf::OnStem => self.extra.on_stem += 1,
                PredictedLeaf::OnBackground => self.extra.on_background += 1,
            }
        }
    }

    /// True leaves missed (merged or not seen), lowering the count.
    pub fn missed(&self) -> usize {
        self.true_leaves.iter().map(|r| r.merged + r.not_seen).sum()
    }

    /// Extra predicted leaves, raising the count.
    pub fn extra_total(&self) -> usize {
        self.extra.split + self.extra.on_stem + self.extra.on_background
    }

    /// A Markdown table of the true leaves and a line of the extra ones.
    pub fn table(&self) -> String {
        let mut s = String::from(
            "| visible area (px) | true leaves | found | partly found | merged into another | not seen as leaf |\n\
             |---|---:|---:|---:|---:|---:|\n",
        );
        let mut all = TrueLeaves::default();
        for r in &self.true_leaves {
            let range = match r.below_px {
                Some(hi) => format!("{}–{}", r.min_px, hi - 1),
                None => format!("≥ {}", r.min_px),
            };
            s += &format!(
                "| {range} | {} | {} | {} | {} | {} |\n",
                r.total(),
                r.found,
                r.partly_found,
                r.merged,
                r.not_seen
            );
            all.found += r.found;
            all.partly_found += r.partly_found;
            all.merged += r.merged;
            all.not_seen += r.not_seen;
        }
        s += &format!(
            "| all | {} | {} | {} | {} | {} |\n",
            all.total(),
            all.found,
            all.partly_found,
            all.merged,
            all.not_seen
        );
        s += &format!(
            "\nmissed leaves (merged or not seen) {}; extra predicted leaves {} \
             (split off a leaf {}, on stem {}, on background {})\n",
            self.missed(),
            self.extra_total(),
            self.extra.split,
            self.extra.on_stem,
            self.extra.on_background
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segmentation::PixelMap;
    use phyllo_contract::{LEAF, STEM};

    fn map(rows: &[&str]) -> PixelMap {
        // '.' background, 's' stem, digits = leaf instance.
        let mut class = Vec::new();
        let mut instance = Vec::new();
        for ch in rows.concat().chars() {
            match ch {
                '.' => (class.push(0), instance.push(0)),
                's' => (class.push(STEM), instance.push(0)),
                d => (class.push(LEAF), instance.push(d.to_digit(10).unwrap())),
            };
        }
        PixelMap {
            width: rows[0].len(),
            height: rows.len(),
            class,
            instance,
        }
    }

    fn errors(truth: &[&str], pred: &[&str]) -> LeafErrors {
        let mut e = LeafErrors::default();
        e.add(&Overlaps::of(&map(truth), &map(pred)));
        e
    }

    fn row(found: usize, partly_found: usize, merged: usize, not_seen: usize) -> TrueLeaves {
        TrueLeaves {
            min_px: 1,
            below_px: Some(64),
            found,
            partly_found,
            merged,
            not_seen,
        }
    }

    #[test]
    fn a_perfect_prediction_finds_every_leaf() {
        let t = ["11..22", "11s.22"];
        let e = errors(&t, &t);
        assert_eq!(e.true_leaves[0], row(2, 0, 0, 0));
        assert_eq!((e.missed(), e.extra_total()), (0, 0));
    }

    #[test]
    fn two_leaves_in_one_instance_are_one_found_and_one_merged() {
        let e = errors(&["111122"], &["333333"]);
        assert_eq!(e.true_leaves[0], row(1, 0, 1, 0));
        assert_eq!(e.missed(), 1);
    }

    #[test]
    fn a_leaf_predicted_as_background_is_not_seen() {
        let e = errors(&["1111..22"], &["1111...."]);
        assert_eq!(e.true_leaves[0], row(1, 0, 0, 1));
    }

    #[test]
    fn extras_are_told_apart_by_what_they_lie_on() {
        let e = errors(&["1111ss...."], &["1122334..5"]);
        // Leaf 1 keeps its two pixels at IoU 0.5 (not above): partly found,
        // and instance 2 is the piece split off it.
        assert_eq!(e.true_leaves[0], row(0, 1, 0, 0));
        assert_eq!(e.extra.split, 1);
        assert_eq!(e.extra.on_stem, 1);
        assert_eq!(e.extra.on_background, 2);
        let kinds = classify_predicted(&Overlaps::of(&map(&["1111ss...."]), &map(&["1122334..5"])));
        let names: Vec<&str> = kinds.values().map(|k| k.name()).collect();
        assert_eq!(
            names,
            ["partner", "split", "on_stem", "on_background", "on_background"]
        );
    }

    #[test]
    fn every_leaf_lands_in_one_cell_on_both_sides() {
        // Truth minus prediction is exactly missed minus extra leaves.
        let truth = ["1111222233334444ss....", "11112222333344445s...."];
        let pred = ["1111111122224455677.8.", "11111111222244556.7..."];
        let e = errors(&truth, &pred);
        let all: usize = e.true_leaves.iter().map(TrueLeaves::total).sum();
        assert_eq!(all, 5);
        let kept: usize = e.true_leaves.iter().map(|r| r.found + r.partly_found).sum();
        assert_eq!(kept + e.extra_total(), 7);
        assert_eq!(5 - 7, e.missed() as i64 - e.extra_total() as i64);
    }

    #[test]
    fn leaves_are_classed_by_visible_area() {
        let big = "1".repeat(300);
        let truth = [format!("{big}2")];
        let pred = [format!("{big}.")];
        let t: Vec<&str> = truth.iter().map(|s| s.as_str()).collect();
        let p: Vec<&str> = pred.iter().map(|s| s.as_str()).collect();
        let e = errors(&t, &p);
        assert_eq!(e.true_leaves[0].not_seen, 1);
        assert_eq!(e.true_leaves[2].found, 1);
        assert!(e.table().contains("| 256–1023 | 1 | 1 | 0 | 0 | 0 |"));
    }
}
