//! Panoptic labels in the contract's encoding (16-bit grey PNG, value =
//! class * divisor + instance) and the human-viewable colour mask.

use image::{ImageBuffer, Luma, RgbImage};
use phyllo_contract::{Contract, LEAF};
use std::collections::BTreeMap;

/// A label image.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major label values.
    pub data: Vec<u16>,
}

impl LabelImage {
    /// Pixel count of each leaf instance present.
    pub fn leaf_pixels(&self) -> BTreeMap<u16, u32> {
        let c = Contract::embedded();
        let mut m = BTreeMap::new();
        for &v in &self.data {
            let (class, inst) = c.decode_label(v);
            if class == LEAF {
                *m.entry(inst).or_insert(0) += 1;
            }
        }
        m
    }

    /// Distinct leaf instances present.
    pub fn visible_leaf_count(&self) -> usize {
        self.leaf_pixels().len()
    }

    /// The 16-bit grey image.
    pub fn to_image(&self) -> ImageBuffer<Luma<u16>, Vec<u16>> {
        ImageBuffer::from_raw(self.width, self.height, self.data.clone()).expect("label buffer matches size")
    }

    /// The human-viewable mask: contract colours per class, palette per leaf.
    pub fn mask(&self) -> RgbImage {
        let c = Contract::embedded();
        let mut img = RgbImage::new(self.width, self.height);
        for (p, &v) in img.pixels_mut().zip(&self.data) {
            let (class, inst) = c.decode_label(v);
            p.0 = c.mask_colour(class, inst);
        }
        img
    }
}
