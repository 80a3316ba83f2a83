//! Leaf tips, and the count rules that use them.
//!
//! Panoptic-DeepLab finds a leaf by its centre. Young leaves still rolled in
//! the whorl lie side by side, so their centres merge into one peak and two
//! or three leaves come out as one segment. Their tips do not merge: each
//! young leaf ends in its own tip, which is also how human annotators count
//! leaves (they click each tip). A model with the contract's optional `tip`
//! output marks every visible tip with a peak of a heatmap; this module turns
//! those peaks into counts.
//!
//! A tip counts only where it lies on a leaf the post-processing kept (a
//! pixel of a kept leaf segment within `reach` output pixels): peaks on the
//! chamber, the stem or a dropped instance are no leaves. Each such tip joins
//! the segment of its nearest leaf pixel. The rules ([`CountRule`]) are then:
//!
//! * `centres`: the leaf segments, as without tips;
//! * `tips`: the tips that joined a leaf;
//! * `split`: each leaf segment counts as many leaves as tips joined it, and
//!   at least one: two tips on a segment are two merged leaves, while a leaf
//!   whose tip is hidden (behind another leaf, out of frame) is still a leaf.
//!
//! A model without a tip output counts centres under every rule, so choosing
//! a rule never changes the counts of such a model.

use std::fmt;
use std::str::FromStr;

use phyllo_contract::LEAF;
use serde::{Deserialize, Serialize};

use crate::panoptic::Panoptic;

/// Default [`crate::postprocess::PostprocessParams::tip_reach`]: 2 output
/// pixels, a tip's Gaussian target (`tip_sigma` 1.5) plus rounding, so a tip
/// the model puts just past the end of its leaf still reaches it.
pub const DEFAULT_TIP_REACH: u32 = 2;

/// How leaves are counted. See the [module documentation](self) for why.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CountRule {
    /// The leaf segments (one per centre that survived post-processing).
    #[default]
    Centres,
    /// The tips that lie on a kept leaf segment.
    Tips,
    /// Per leaf segment, the tips that joined it, but at least one.
    Split,
}

impl CountRule {
    /// Every rule, in the order the CLI lists them.
    pub const ALL: [CountRule; 3] = [CountRule::Centres, CountRule::Tips, CountRule::Split];

    /// The rule's name, as written in configurations and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CountRule::Centres => "centres",
            CountRule::Tips => "tips",
            CountRule::Split => "split",
        }
    }
}

impl fmt::Display for CountRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for CountRule {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        CountRule::ALL
            .into_iter()
            .find(|r| r.name() == s)
            .ok_or_else(|| format!("unknown count rule {s:?} (expected centres, tips or split)"))
    }
}

impl Panoptic {
    /// Whether the tips come from a tip heatmap, i.e. the model has a tip
    /// output (it may still have found none).
    pub fn has_tip_map(&self) -> bool {
        self.tips.is_some()
    }

    /// For each tip (in [`Panoptic::tips`] order), the id of the leaf segment
    /// it joins: the segment of the nearest leaf pixel (Euclidean; ties in
    /// raster order) among those within `reach` output pixels (Chebyshev), or
    /// `None` when no leaf pixel is that near. Empty without a tip map.
    ///
    /// Worked out from the current instance map, so it stays right after
    /// [`Panoptic::retain`] drops and renumbers segments.
    pub fn tip_segments(&self, reach: u32) -> Vec<Option<u32>> {
        let Some(tips) = &self.tips else {
            return Vec::new();
        };
        let mut is_leaf = vec![false; self.segments.iter().map(|s| s.id as usize + 1).max().unwrap_or(1)];
        for seg in &self.segments {
            is_leaf[seg.id as usize] = seg.class == LEAF;
        }
        let r = reach as usize;
        tips.iter()
            .map(|t| {
                let (x, y) = (t.x as usize, t.y as usize);
                if x >= self.width || y >= self.height {
                    return None;
                }
                let mut best: Option<(usize, u32)> = None;
                for yy in y.saturating_sub(r)..(y + r + 1).min(self.height) {
                    for xx in x.saturating_sub(r)..(x + r + 1).min(self.width) {
                        let id = self.instance[yy * self.width + xx];
                        if !is_leaf.get(id as usize).copied().unwrap_or(false) {
                            continue;
                        }
                        let d = yy.abs_diff(y).pow(2) + xx.abs_diff(x).pow(2);
                        if best.is_none_or(|(bd, _)| d < bd) {
                            best = Some((d, id));
                        }
                    }
                }
                best.map(|(_, id)| id)
            })
            .collect()
    }

    /// The number of leaves under `rule`, tips joining leaves within `reach`
    /// output pixels. Without a tip map every rule counts the leaf segments.
    pub fn leaf_count(&self, rule: CountRule, reach: u32) -> usize {
        self.leaf_count_of(rule, &self.tip_segments(reach))
    }

    /// [`Panoptic::leaf_count`] from tip segments already found with
    /// [`Panoptic::tip_segments`], for a caller that keeps them too.
    pub fn leaf_count_of(&self, rule: CountRule, tip_segments: &[Option<u32>]) -> usize {
        let centres = self.count(LEAF);
        if !self.has_tip_map() {
            return centres;
        }
        match rule {
            CountRule::Centres => centres,
            CountRule::Tips => tip_segments.iter().flatten().count(),
            CountRule::Split => {
                let mut joined =
                    vec![0usize; self.segments.iter().map(|s| s.id as usize + 1).max().unwrap_or(1)];
                for &id in tip_segments.iter().flatten() {
                    joined[id as usize] += 1;
                }
                self.segments
                    .iter()
                    .filter(|s| s.class == LEAF)
                    .map(|s| joined[s.id as usize].max(1))
                    .sum()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::panoptic::{Segment, TipPeak};
    use phyllo_contract::{PANICLE, STEM};

    const W: usize = 20;
    const H: usize = 10;

    fn seg(id: u32, class: u8) -> Segment {
        Segment {
            id,
            class,
            area: 1,
            bbox: [0, 0, 1, 1],
            centre: [0.0, 0.0],
            score: 1.0,
        }
    }

    fn tip(x: u32, y: u32) -> TipPeak {
        TipPeak { x, y, score: 0.9 }
    }

    /// A 20x10 output grid: leaf 1 (x 0..6, rows 2..4), leaf 2 (x 8..12, rows
    /// 2..4), panicle 3 (x 15..18, rows 0..3), a stem column at x 7, no tips.
    fn scene() -> Panoptic {
        let mut semantic = vec![0u8; W * H];
        let mut instance = vec![0u32; W * H];
        let mut paint = |x0: usize, x1: usize, y0: usize, y1: usize, class: u8, id: u32| {
            for y in y0..y1 {
                for x in x0..x1 {
                    semantic[y * W + x] = class;
                    instance[y * W + x] = id;
                }
            }
        };
        paint(0, 6, 2, 4, LEAF, 1);
        paint(8, 12, 2, 4, LEAF, 2);
        paint(15, 18, 0, 3, PANICLE, 3);
        paint(7, 8, 0, H, STEM, 0);
        Panoptic {
            height: H,
            width: W,
            semantic,
            instance,
            segments: vec![seg(1, LEAF), seg(2, LEAF), seg(3, PANICLE)],
            tips: Some(Vec::new()),
        }
    }

    fn counts(p: &Panoptic, reach: u32) -> [usize; 3] {
        CountRule::ALL.map(|r| p.leaf_count(r, reach))
    }

    #[test]
    fn a_merged_segment_with_two_tips_is_two_leaves_under_split() {
        let mut p = scene();
        // Two tips at either end of leaf 1 (two young leaves merged), one on leaf 2.
        p.tips = Some(vec![tip(0, 2), tip(5, 3), tip(10, 3)]);
        assert_eq!(p.tip_segments(2), vec![Some(1), Some(1), Some(2)]);
        assert_eq!(counts(&p, 2), [2, 3, 3]);
    }

    #[test]
    fn a_segment_without_a_tip_is_one_leaf_under_split_and_none_under_tips() {
        let mut p = scene();
        p.tips = Some(vec![tip(3, 2)]);
        assert_eq!(counts(&p, 2), [2, 1, 2]);
    }

    #[test]
    fn tips_off_every_leaf_are_ignored() {
        let mut p = scene();
        // On the stem, on the panicle, on bare background far from anything.
        p.tips = Some(vec![tip(7, 8), tip(16, 1), tip(2, 9)]);
        assert_eq!(p.tip_segments(2), vec![None, None, None]);
        assert_eq!(counts(&p, 2), [2, 0, 2]);
    }

    #[test]
    fn reach_is_a_chebyshev_distance_and_the_nearest_leaf_wins() {
        let mut p = scene();
        // Two rows below the leaves, on the stem's column between them.
        p.tips = Some(vec![tip(7, 5)]);
        assert_eq!(p.tip_segments(1), vec![None]);
        // Within 2 of both leaves (x 5 and x 8): leaf 2 is nearer (dx 1 vs 2).
        assert_eq!(p.tip_segments(2), vec![Some(2)]);
        p.tips = Some(vec![tip(3, 6)]);
        assert_eq!(p.tip_segments(2), vec![None], "three rows below leaf 1");
        assert_eq!(p.tip_segments(3), vec![Some(1)]);
        assert_eq!(p.leaf_count(CountRule::Tips, 2), 0);
        assert_eq!(p.leaf_count(CountRule::Tips, 3), 1);
        assert_eq!(p.leaf_count(CountRule::Tips, 0), 0);
    }

    #[test]
    fn without_a_tip_map_every_rule_counts_centres() {
        let mut p = scene();
        p.tips = None;
        assert!(!p.has_tip_map());
        assert!(p.tip_segments(2).is_empty());
        assert_eq!(counts(&p, 2), [2, 2, 2]);
        // A map that found nothing is another matter: no tip on any leaf.
        p.tips = Some(Vec::new());
        assert!(p.has_tip_map());
        assert_eq!(counts(&p, 2), [2, 0, 2]);
    }

    #[test]
    fn tips_follow_segments_through_retain() {
        let mut p = scene();
        p.tips = Some(vec![tip(1, 2), tip(9, 2), tip(11, 3)]);
        p.retain(|s| s.id != 1);
        // Leaf 2 is now segment 1; the tip on the dropped leaf counts no more.
        assert_eq!(p.tip_segments(2), vec![None, Some(1), Some(1)]);
        assert_eq!(counts(&p, 2), [1, 2, 2]);
    }

    #[test]
    fn rules_read_and_print_their_names() {
        for r in CountRule::ALL {
            assert_eq!(r.to_string().parse::<CountRule>(), Ok(r));
            assert_eq!(serde_json::to_string(&r).unwrap(), format!("\"{r}\""));
        }
        assert!("centers".parse::<CountRule>().is_err());
        assert_eq!(CountRule::default(), CountRule::Centres);
    }
}
