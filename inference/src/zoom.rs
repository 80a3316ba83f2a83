//! The contract's zoom rule: a small plant is counted a second time,
//! enlarged, because at frame scale a seedling's leaves are a few pixels
//! wide, below what the stride-2 heads separate.
//!
//! The plant's height is measured on the first pass's own instances rather
//! than by colour: in the chamber, dark posts and jambs pass the colour test
//! and make a seedling's colour box many times its size. Training measures
//! the same height on the label (`phyllo_train/augment.py`).

use phyllo_contract::Contract;

use crate::panoptic::Panoptic;

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

/// Height in model pixels of the box around `pan`'s instances (the rows
/// they span, plus [`BOX_MARGIN`] above and below), or `None` without any.
pub fn instances_height(pan: &Panoptic, stride: u32) -> Option<u32> {
    let y0 = pan.segments.iter().map(|s| s.bbox[1]).min()?;
    let y1 = pan.segments.iter().map(|s| s.bbox[3]).max()?;
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
}
