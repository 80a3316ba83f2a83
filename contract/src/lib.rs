//! The phyllo label and model contract.
//!
//! `models/contract.toml` is the single definition of classes, the on-disk
//! label encoding, the model's input and outputs and the post-processing
//! defaults. This crate embeds that file at compile time so the generator and
//! the daemon can never disagree with each other, and the Python trainer reads
//! the same file.

use serde::Deserialize;
use std::sync::OnceLock;

/// The contract file's text, exactly as shipped in `models/contract.toml`.
pub const CONTRACT_TOML: &str = include_str!("../../models/contract.toml");

/// Semantic class id of the background.
pub const BACKGROUND: u8 = 0;
/// Semantic class id of a leaf.
pub const LEAF: u8 = 1;
/// Semantic class id of the stem.
pub const STEM: u8 = 2;
/// Semantic class id of a panicle.
pub const PANICLE: u8 = 3;
/// Number of semantic classes.
pub const NUM_CLASSES: usize = 4;

/// Error raised when the contract text cannot be parsed or is inconsistent.
#[derive(Debug, thiserror::Error)]
pub enum ContractError {
    /// The TOML did not parse into the contract's shape.
    #[error("contract does not parse: {0}")]
    Parse(#[from] toml::de::Error),
    /// The TOML parsed but a value breaks an invariant the code relies on.
    #[error("contract is inconsistent: {0}")]
    Invalid(String),
}

/// The whole contract.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Contract {
    /// Contract version; models stamped with another one are refused.
    pub version: u32,
    /// Semantic classes.
    pub classes: Classes,
    /// On-disk label encoding and palette.
    pub label: LabelEncoding,
    /// Model input tensor.
    pub input: InputSpec,
    /// Model output tensors.
    pub outputs: OutputSpec,
    /// Post-processing defaults.
    pub postprocess: PostprocessDefaults,
    /// ONNX metadata keys.
    pub metadata: MetadataKeys,
}

/// Semantic classes.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Classes {
    /// Human names, indexed by class id.
    pub names: Vec<String>,
    /// Class ids, in the same order as `names`.
    pub ids: Vec<u8>,
    /// Classes that have instances.
    pub things: Vec<u8>,
    /// The class whose instances are counted.
    pub leaf: u8,
}

/// On-disk panoptic label encoding and the human-viewable palette.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LabelEncoding {
    /// File format of labels (`png16`).
    pub format: String,
    /// Label value = class * divisor + instance.
    pub divisor: u16,
    /// Largest instance number in one label.
    pub max_instances: u16,
    /// Mask colour of background pixels.
    pub background_rgb: [u8; 3],
    /// Mask colour of stem pixels.
    pub stem_rgb: [u8; 3],
    /// Mask colour of panicle pixels.
    pub panicle_rgb: [u8; 3],
    /// Mask colours of leaves, cycled by instance number.
    pub leaf_palette: Vec<[u8; 3]>,
}

/// Model input tensor and the scale at which the model sees plants.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// Tensor name.
    pub name: String,
    /// Tensor layout (`NCHW`).
    pub layout: String,
    /// Element type (`float32`).
    pub dtype: String,
    /// Channel order (`RGB`).
    pub channels: String,
    /// Tile side in pixels.
    pub tile: u32,
    /// Range pixel values are scaled into before normalisation.
    pub value_range: [f32; 2],
    /// Per-channel mean subtracted after scaling.
    pub mean: [f32; 3],
    /// Per-channel standard deviation divided by after subtracting the mean.
    pub std: [f32; 3],
    /// Height a full camera frame is resized to.
    pub frame_height: u32,
    /// Width / height of a camera frame.
    pub frame_aspect: f32,
    /// Relative tolerance when recognising a frame by its aspect.
    pub frame_aspect_tolerance: f32,
    /// Factor a non-frame image (a crop cut from a half-size frame) is resized by.
    pub crop_scale: f32,
    /// Overlap between neighbouring tiles in pixels.
    pub tile_overlap: u32,
    /// A plant whose leaves span fewer rows than this many model pixels
    /// (margins included) is counted again, enlarged to it, so young plants'
    /// leaves are seen at a size the model resolves (0: never enlarge).
    pub zoom_plant_height: u32,
    /// Largest such enlargement.
    pub max_zoom: f32,
}

/// Model output tensors.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Output stride relative to the input tile.
    pub stride: u32,
    /// Name of the semantic logits output.
    pub semantic: String,
    /// Name of the centre heatmap output.
    pub center: String,
    /// Name of the centre offset output.
    pub offset: String,
    /// Sigma of the Gaussian centre target, in output pixels.
    pub center_sigma: f32,
    /// Name of the optional leaf-tip heatmap output (models with a tip head).
    pub tip: String,
    /// Sigma of the Gaussian tip target, in output pixels.
    pub tip_sigma: f32,
}

/// Default post-processing parameters.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PostprocessDefaults {
    /// Minimum heatmap value of a centre.
    pub center_threshold: f32,
    /// Max-pool kernel side for centre NMS, in output pixels (odd).
    pub nms_kernel: u32,
    /// Most centres kept per image.
    pub top_k: usize,
    /// Smallest leaf instance counted, in output pixels.
    pub min_leaf_area: u32,
    /// Minimum tip heatmap value of a leaf tip.
    pub tip_threshold: f32,
    /// Max-pool kernel side for tip NMS, in output pixels (odd).
    pub tip_nms_kernel: u32,
}

/// Keys of the ONNX metadata the contract stamps into models.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetadataKeys {
    /// Key holding the contract version.
    pub contract_version: String,
    /// Key holding the model's name.
    pub model_name: String,
    /// Key holding "true" for trained models, "false" for untrained ones.
    pub trained: String,
    /// Key describing the training data.
    pub training_data: String,
}

impl Contract {
    /// Parses and validates a contract from TOML text.
    pub fn parse(text: &str) -> Result<Self, ContractError> {
        let contract: Contract = toml::from_str(text)?;
        contract.validate()?;
        Ok(contract)
    }

    /// The contract this build was compiled with.
    pub fn embedded() -> &'static Contract {
        static CONTRACT: OnceLock<Contract> = OnceLock::new();
        CONTRACT.get_or_init(|| {
            Contract::parse(CONTRACT_TOML).expect("models/contract.toml is checked by the test suite")
        })
    }

    fn validate(&self) -> Result<(), ContractError> {
        let invalid = |msg: String| Err(ContractError::Invalid(msg));
        if self.classes.names.len() != NUM_CLASSES || self.classes.ids != [0, 1, 2, 3] {
            return invalid(format!(
                "classes must be background, leaf, stem, panicle with ids 0..3, got {:?} {:?}",
                self.classes.names, self.classes.ids
            ));
        }
        if self.classes.leaf != LEAF {
            return invalid(format!("leaf class must be {LEAF}"));
        }
        if self.label.format != "png16" {
            return invalid(format!("label format {:?} is not png16", self.label.format));
        }
        if u32::from(self.label.divisor) * NUM_CLASSES as u32 > u32::from(u16::MAX) {
            return invalid("label divisor too large for 16-bit labels".into());
        }
        if self.label.max_instances >= self.label.divisor {
            return invalid("max_instances must be below divisor".into());
        }
        if self.label.leaf_palette.is_empty() {
            return invalid("leaf_palette is empty".into());
        }
        if self.input.layout != "NCHW" || self.input.dtype != "float32" || self.input.channels != "RGB" {
            return invalid("input must be NCHW float32 RGB".into());
        }
        if self.outputs.stride == 0 || !self.input.tile.is_multiple_of(self.outputs.stride) {
            return invalid("tile must be a multiple of the output stride".into());
        }
        if self.input.tile_overlap >= self.input.tile {
            return invalid("tile_overlap must be smaller than tile".into());
        }
        if !(self.input.max_zoom >= 1.0 && self.input.max_zoom <= 8.0) {
            return invalid("max_zoom must lie in 1..=8".into());
        }
        if self.postprocess.nms_kernel.is_multiple_of(2) {
            return invalid("nms_kernel must be odd".into());
        }
        if self.postprocess.tip_nms_kernel.is_multiple_of(2) {
            return invalid("tip_nms_kernel must be odd".into());
        }
        Ok(())
    }

    /// Side of one tile's outputs in output pixels.
    pub fn output_tile(&self) -> u32 {
        self.input.tile / self.outputs.stride
    }

    /// Encodes a class and instance into a label value.
    pub fn encode_label(&self, class: u8, instance: u16) -> u16 {
        u16::from(class) * self.label.divisor + instance
    }

    /// Decodes a label value into (class, instance).
    pub fn decode_label(&self, value: u16) -> (u8, u16) {
        ((value / self.label.divisor) as u8, value % self.label.divisor)
    }

    /// Colour of a pixel in the human-viewable mask.
    pub fn mask_colour(&self, class: u8, instance: u16) -> [u8; 3] {
        match class {
            LEAF => {
                let palette = &self.label.leaf_palette;
                palette[(usize::from(instance.max(1)) - 1) % palette.len()]
            }
            STEM => self.label.stem_rgb,
            PANICLE => self.label.panicle_rgb,
            _ => self.label.background_rgb,
        }
    }

    /// Whether `class` has instances.
    pub fn is_thing(&self, class: u8) -> bool {
        self.classes.things.contains(&class)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_contract_parses_and_validates() {
        let c = Contract::embedded();
        assert_eq!(c.version, 1);
        assert_eq!(c.classes.names[LEAF as usize], "leaf");
        assert_eq!(c.output_tile() * c.outputs.stride, c.input.tile);
    }

    #[test]
    fn label_round_trips() {
        let c = Contract::embedded();
        for class in 0..4u8 {
            for inst in [0u16, 1, 17, 999] {
                assert_eq!(c.decode_label(c.encode_label(class, inst)), (class, inst));
            }
        }
    }

    #[test]
    fn broken_contract_is_refused_with_reason() {
        let text = CONTRACT_TOML.replace("nms_kernel = 7", "nms_kernel = 6");
        let err = Contract::parse(&text).unwrap_err().to_string();
        assert!(err.contains("nms_kernel"), "{err}");
        let err = Contract::parse("version = 1").unwrap_err().to_string();
        assert!(err.contains("missing field"), "{err}");
    }
}
