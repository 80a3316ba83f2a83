//! What counting one image produces.

use serde::{Deserialize, Serialize};

use crate::camera_scale::CameraScale;

/// One panoptic instance found in an image, in the original image's pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Instance {
    /// Instance number within the image, from 1.
    pub id: u32,
    /// Semantic class id (contract: 1 leaf, 3 panicle).
    pub class: u8,
    /// Semantic class name.
    pub class_name: String,
    /// Area in original-image pixels.
    pub area: u64,
    /// Bounding box `[x0, y0, x1, y1]` (x1, y1 exclusive) in original-image pixels.
    pub bbox: [u32; 4],
    /// Predicted instance centre `[x, y]` in original-image pixels.
    pub centre: [f32; 2],
    /// Mean confidence: centre heatmap peak times mean class probability.
    pub score: f32,
}

/// Wall-clock time per stage, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimings {
    /// Reading and decoding the file.
    pub decode: f64,
    /// Finding the plant, scaling and cutting tiles.
    pub tile: f64,
    /// ONNX Runtime.
    pub inference: f64,
    /// Stitching tiles and panoptic post-processing.
    pub postprocess: f64,
    /// Everything.
    pub total: f64,
}

/// The result of counting one image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CountResult {
    /// Number of leaf instances at or above the minimum area.
    pub leaf_count: u32,
    /// All thing instances (leaves and panicles) that passed the minimum area.
    pub instances: Vec<Instance>,
    /// Original image width and height.
    pub image_size: [u32; 2],
    /// Plant region `[x0, y0, x1, y1]` in original-image pixels.
    pub region: [u32; 4],
    /// Model pixels per image pixel the count was made at (above the
    /// contract's scale when a small plant was enlarged).
    #[serde(default)]
    pub scale: f32,
    /// Number of 512x512 tiles run through the model (both passes when a
    /// small plant was enlarged).
    pub tiles: u32,
    /// Time per stage.
    pub ms: StageTimings,
    /// Leaf tips `[x, y, score]` in original-image pixels, strongest first,
    /// for models with a tip output (empty, and left out of JSON, otherwise).
    /// Every tip inside the plant's box, whether or not it lies on a leaf.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tips: Vec<[f32; 3]>,
    /// For each of `tips`, the id of the leaf instance it joins (within the
    /// tip reach) or `None`: what the `tips` and `split` count rules count,
    /// so other rules can be scored offline from one run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tip_instances: Vec<Option<u32>>,
    /// The scale before any small-plant enlargement, the camera zoom it
    /// assumes and how that was found (the counter always sets it; results
    /// written before it existed read back without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraScale>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(tips: Vec<[f32; 3]>) -> CountResult {
        CountResult {
            leaf_count: 1,
            instances: vec![],
            image_size: [10, 10],
            region: [0, 0, 10, 10],
            scale: 0.5,
            tiles: 1,
            ms: StageTimings::default(),
            tip_instances: vec![],
            tips,
            camera: None,
        }
    }

    #[test]
    fn results_without_tips_keep_their_json() {
        // What a tip-less count wrote before tips existed reads back, and
        // writes back the same.
        let old = r#"{"leaf_count":1,"instances":[],"image_size":[10,10],"region":[0,0,10,10],"scale":0.5,"tiles":1,"ms":{"decode":0.0,"tile":0.0,"inference":0.0,"postprocess":0.0,"total":0.0}}"#;
        let r: CountResult = serde_json::from_str(old).unwrap();
        assert_eq!(r, result(vec![]));
        assert_eq!(serde_json::to_string(&r).unwrap(), old);
        let with = serde_json::to_value(result(vec![[1.0, 2.0, 0.5]])).unwrap();
        assert_eq!(with["tips"], serde_json::json!([[1.0, 2.0, 0.5]]));
    }
}
