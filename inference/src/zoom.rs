//! The contract's zoom rule: a small plant is counted a second time,
//! enlarged, because at frame scale a seedling's leaves are a few pixels
//! wide, below what the stride-2 heads separate.
//!
//! The plant's height is measured on the first pass's own instances rather
//! than by colour: in the chamber, dark posts and jambs pass the colour test
//! and make a seedling's colour box many times its size. Training measures
//! the same height on the label (`phyllo_train/augment.py`).
//!
//! The label has no specks, while the first pass may: a few pixels on the
//! chamber's frame far above a seedling make it look tall enough to be left
//! unenlarged. [`HeightMeasure::Plant`] measures without them.

use std::fmt;
use std::str::FromStr;

use phyllo_contract::Contract;
use serde::{Deserialize, Serialize};

use crate::panoptic::Panoptic;
use crate::pieces::box_gap;

/// Margin added above and below the instances' rows, in model pixels (the
/// same as the colour box's, so the rule reads like a box height).
pub const BOX_MARGIN: u32 = 12;

/// Enlargements below this are not worth a second pass (training snaps them
/// to 1 as well).
pub const MIN_ZOOM: f32 = 1.1;

/// How small plants are enlarged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Zoom {
    /// Plants whose box is shorter than this (model pixels) are enlarged to
    /// it; 0 disables the rule.
    pub plant_height: u32,
    /// Largest enlargement.
    pub max: f32,
}

impl Zoom {
    /// Never enlarge.
    pub const OFF: Zoom = Zoom {
        plant_height: 0,
        max: 1.0,
    };

    /// The contract's rule.
    pub fn from_contract(c: &Contract) -> Self {
        Zoom {
            plant_height: c.input.zoom_plant_height,
            max: c.input.max_zoom,
        }
    }

    /// Enlargement for a plant box `box_height` model pixels tall; 1.0 when
    /// none is due.
    pub fn factor(&self, box_height: u32) -> f32 {
        if self.plant_height == 0 || box_height == 0 {
            return 1.0;
        }
        let z = (self.plant_height as f32 / box_height as f32).clamp(1.0, self.max.max(1.0));
        if z < MIN_ZOOM {
            1.0
        } else {
            z
        }
    }
}

/// Which instances the small-plant rule measures the plant's height on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HeightMeasure {
    /// Every instance the first pass kept, specks included. The default:
    /// the plant measure counts the synthetic calibration sets better but
    /// raises the real over-count (models/EXPERIMENTS.md).
    #[default]
    All,
    /// The plant's body: the first pass tidied of specks (far crumbs of a
    /// leaf, pixels outside the plant's box), then without small instances
    /// lying far from every large one ([`plant_height`]).
    Plant,
}

impl HeightMeasure {
    /// Every measure, in the order the CLI lists them.
    pub const ALL: [HeightMeasure; 2] = [HeightMeasure::All, HeightMeasure::Plant];

    /// The measure's name, as written on the command line.
    pub fn name(self) -> &'static str {
        match self {
            HeightMeasure::All => "all",
            HeightMeasure::Plant => "plant",
        }
    }
}

impl fmt::Display for HeightMeasure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for HeightMeasure {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        HeightMeasure::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown height measure {s:?} (expected all or plant)"))
    }
}

/// Height in model pixels of the box around `pan`'s instances (the rows
/// they span, plus [`BOX_MARGIN`] above and below), or `None` without any.
pub fn instances_height(pan: &Panoptic, stride: u32) -> Option<u32> {
    boxes_height(pan.segments.iter().map(|s| s.bbox), stride)
}

/// Like [`instances_height`], over the plant's body only: instances of at
/// least `min_area` output pixels, and smaller ones whose box lies within
/// `distance` output pixels (Chebyshev, box to box) of a large one's. A
/// small instance far from every large one is a speck on the chamber, not a
/// leaf of the plant. Without any large instance, every instance counts, so a
/// seedling of small leaves is still measured.
pub fn plant_height(pan: &Panoptic, stride: u32, min_area: u32, distance: u32) -> Option<u32> {
    let wide = |b: [u32; 4]| b.map(|v| v as usize);
    let large: Vec<[usize; 4]> = pan
        .segments
        .iter()
        .filter(|s| s.area >= min_area)
        .map(|s| wide(s.bbox))
        .collect();
    let near = |b: [u32; 4]| large.iter().any(|&l| box_gap(wide(b), l) <= distance as usize);
    let kept = pan
        .segments
        .iter()
        .map(|s| s.bbox)
        .filter(|&b| large.is_empty() || near(b));
    boxes_height(kept, stride)
}

/// Height in model pixels of the rows `boxes` span, plus the margins.
fn boxes_height(boxes: impl Iterator<Item = [u32; 4]> + Clone, stride: u32) -> Option<u32> {
    let y0 = boxes.clone().map(|b| b[1]).min()?;
    let y1 = boxes.map(|b| b[3]).max()?;
    Some((y1 - y0) * stride + 2 * BOX_MARGIN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_plants_are_enlarged_up_to_the_limit() {
        let z = Zoom {
            plant_height: 320,
            max: 2.0,
        };
        assert_eq!(z.factor(400), 1.0);
        assert_eq!(z.factor(310), 1.0, "below the smallest step worth a pass");
        assert!((z.factor(200) - 1.6).abs() < 1e-6);
        assert_eq!(z.factor(50), 2.0);
        assert_eq!(Zoom::OFF.factor(50), 1.0);
        assert_eq!(z.factor(0), 1.0);
    }

    #[test]
    fn height_spans_every_instance_plus_margins() {
        use crate::panoptic::Segment;
        let seg = |y0, y1| Segment {
            id: 1,
            class: 1,
            area: 10,
            bbox: [0, y0, 5, y1],
            centre: [2.0, 2.0],
            score: 1.0,
        };
        let mut pan = Panoptic {
            height: 100,
            width: 100,
            semantic: vec![0; 10_000],
            instance: vec![0; 10_000],
            segments: vec![seg(40, 60), seg(20, 45)],
            tips: None,
        };
        assert_eq!(instances_height(&pan, 2), Some(40 * 2 + 24));
        pan.segments.clear();
        assert_eq!(instances_height(&pan, 2), None);
    }

    fn segment(area: u32, bbox: [u32; 4]) -> crate::panoptic::Segment {
        crate::panoptic::Segment {
            id: 1,
            class: 1,
            area,
            bbox,
            centre: [0.0, 0.0],
            score: 1.0,
        }
    }

    fn panoptic(segments: Vec<crate::panoptic::Segment>) -> Panoptic {
        Panoptic {
            height: 200,
            width: 200,
            semantic: vec![0; 40_000],
            instance: vec![0; 40_000],
            segments,
            tips: None,
        }
    }

    #[test]
    fn a_small_instance_far_from_the_plant_leaves_its_height_alone() {
        // A seedling (rows 150..190) and a speck on the chamber's frame at rows 10..12.
        let pan = panoptic(vec![
            segment(300, [90, 150, 110, 190]),
            segment(200, [100, 160, 130, 180]),
            segment(4, [20, 10, 22, 12]),
        ]);
        assert_eq!(
            instances_height(&pan, 2),
            Some(180 * 2 + 24),
            "the speck stretches every instance's box"
        );
        assert_eq!(plant_height(&pan, 2, 20, 24), Some(40 * 2 + 24));
    }

    #[test]
    fn a_small_leaf_beside_the_plant_is_measured() {
        // A young leaf of 10 pixels just above the large ones is the plant's.
        let pan = panoptic(vec![
            segment(300, [90, 150, 110, 190]),
            segment(10, [95, 130, 99, 140]),
        ]);
        assert_eq!(plant_height(&pan, 2, 20, 24), Some(60 * 2 + 24));
    }

    #[test]
    fn a_plant_of_small_leaves_only_is_measured_whole() {
        let pan = panoptic(vec![
            segment(10, [90, 150, 95, 160]),
            segment(12, [90, 100, 95, 110]),
        ]);
        assert_eq!(plant_height(&pan, 2, 20, 24), instances_height(&pan, 2));
        assert_eq!(plant_height(&panoptic(Vec::new()), 2, 20, 24), None);
    }

    #[test]
    fn height_measures_read_and_print_their_names() {
        for m in HeightMeasure::ALL {
            assert_eq!(m.name().parse::<HeightMeasure>(), Ok(m));
        }
        assert!("specks"
            .parse::<HeightMeasure>()
            .unwrap_err()
            .contains("all or plant"));
    }
}
