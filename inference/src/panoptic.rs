//! The panoptic segmentation every stage after the decoder works on.
//!
//! [`crate::postprocess`] makes it, and [`crate::attachment`],
//! [`crate::pieces`], [`crate::tips`] and [`crate::zoom`] read or edit it.
//! It lives apart from all of them and uses nothing else in the crate, so
//! the stages share it without depending on each other.

use serde::{Deserialize, Serialize};

/// One leaf tip: a peak of the tip heatmap, in output pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TipPeak {
    /// Column, in output pixels.
    pub x: u32,
    /// Row, in output pixels.
    pub y: u32,
    /// Heatmap value at the peak.
    pub score: f32,
}

/// One instance found by post-processing, in output pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Instance number, from 1, in order of decreasing centre score.
    pub id: u32,
    /// Majority semantic class of its pixels.
    pub class: u8,
    /// Number of pixels.
    pub area: u32,
    /// Bounding box `[x0, y0, x1, y1]`, x1 and y1 exclusive.
    pub bbox: [u32; 4],
    /// Centre `[x, y]` (the heatmap peak).
    pub centre: [f32; 2],
    /// Heatmap peak times mean class probability of its pixels.
    pub score: f32,
}

/// Panoptic segmentation of one image, in output pixels.
#[derive(Debug, Clone)]
pub struct Panoptic {
    /// Height in output pixels.
    pub height: usize,
    /// Width in output pixels.
    pub width: usize,
    /// Semantic class per pixel (row-major).
    pub semantic: Vec<u8>,
    /// Instance id per pixel, 0 for none (row-major).
    pub instance: Vec<u32>,
    /// Instances that passed the minimum area.
    pub segments: Vec<Segment>,
    /// Leaf tips, strongest first; `None` when the model has no tip output
    /// (not the same as `Some` of none: a model that looked and found no tip).
    pub tips: Option<Vec<TipPeak>>,
}

impl Panoptic {
    /// Keeps the segments for which `keep` holds, clearing the others'
    /// pixels and renumbering the rest densely in their current order.
    /// Tips are left as they are: which segment a tip belongs to is worked
    /// out from the instance map when it is asked for
    /// ([`Panoptic::tip_segments`]), so it follows the renumbering.
    pub fn retain(&mut self, keep: impl Fn(&Segment) -> bool) {
        let mut renumber = vec![0u32; self.segments.len() + 1];
        let mut kept = Vec::with_capacity(self.segments.len());
        for seg in self.segments.drain(..) {
            if keep(&seg) {
                renumber[seg.id as usize] = kept.len() as u32 + 1;
                kept.push(Segment {
                    id: kept.len() as u32 + 1,
                    ..seg
                });
            }
        }
        for v in self.instance.iter_mut() {
            *v = renumber[*v as usize];
        }
        self.segments = kept;
    }

    /// Recomputes each segment's area and box from the instance map, after
    /// pixels were taken from it.
    pub fn refresh_extents(&mut self) {
        let ext = extents(&self.instance, self.width, self.segments.len());
        for seg in &mut self.segments {
            let (area, bbox) = ext[seg.id as usize];
            seg.area = area;
            if area > 0 {
                seg.bbox = bbox;
            }
        }
    }

    /// Number of instances of `class`.
    pub fn count(&self, class: u8) -> usize {
        self.segments.iter().filter(|s| s.class == class).count()
    }
}

/// Area and box `[x0, y0, x1, y1]` (exclusive ends) of instances 0..=`n` in a
/// row-major instance map `width` pixels wide; an absent instance has area 0.
pub(crate) fn extents(instance: &[u32], width: usize, n: usize) -> Vec<(u32, [u32; 4])> {
    let mut ext = vec![(0u32, [u32::MAX, u32::MAX, 0u32, 0u32]); n + 1];
    for (i, &id) in instance.iter().enumerate() {
        if id == 0 {
            continue;
        }
        let (area, b) = &mut ext[id as usize];
        *area += 1;
        let (x, y) = ((i % width) as u32, (i / width) as u32);
        *b = [b[0].min(x), b[1].min(y), b[2].max(x + 1), b[3].max(y + 1)];
    }
    ext
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retain_clears_and_renumbers() {
        let seg = |id, x| Segment {
            id,
            class: 1,
            area: 1,
            bbox: [x, 0, x + 1, 1],
            centre: [x as f32, 0.0],
            score: 1.0,
        };
        let mut p = Panoptic {
            height: 1,
            width: 3,
            semantic: vec![1, 1, 1],
            instance: vec![1, 2, 3],
            segments: vec![seg(1, 0), seg(2, 1), seg(3, 2)],
            tips: None,
        };
        p.retain(|s| s.id != 2);
        assert_eq!(p.instance, vec![1, 0, 2]);
        assert_eq!(
            p.segments.iter().map(|s| (s.id, s.bbox[0])).collect::<Vec<_>>(),
            vec![(1, 0), (2, 2)]
        );
    }
}
