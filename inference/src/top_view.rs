//! Top views, counted by a model of their own.
//!
//! The side-view model never saw a plant from above and misses about five
//! leaves of every top view (models/MODEL.md). A model trained on top views
//! alone counts them; the side views keep the model their numbers were
//! measured with. Which images are top views is the caller's to say
//! ([`crate::image::ImageFacts`]): the daemon reads it from the file name by
//! its `[names]` patterns, once, where it parses the name.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

pub use crate::model_path::{default_top_model_path, TOP_MODEL_ENV, TOP_MODEL_FILE};

/// NMS window of the shipped top-view model, in output pixels, chosen with
/// its centre threshold.
pub const DEFAULT_TOP_NMS_KERNEL: u32 = 3;

/// Centre threshold of the shipped top-view model, chosen on the top views
/// of the calibration set `calib-top-s700301` (models/MODEL.md).
pub const DEFAULT_TOP_CENTER_THRESHOLD: f32 = 0.15;

/// Which model counts the top views.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum TopModel {
    /// The shipped top-view model, when the side-view model is the shipped
    /// one too; a side-view model named by hand counts every view.
    #[default]
    Default,
    /// None: the side-view model counts the top views too.
    Off,
    /// This file.
    File(PathBuf),
}

impl std::str::FromStr for TopModel {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "" => Err("a top-view model is `default`, `none` or a file".into()),
            "default" => Ok(TopModel::Default),
            "none" => Ok(TopModel::Off),
            path => Ok(TopModel::File(PathBuf::from(path))),
        }
    }
}

impl TryFrom<String> for TopModel {
    type Error = String;

    fn try_from(s: String) -> Result<Self, String> {
        s.parse()
    }
}

impl From<TopModel> for String {
    fn from(m: TopModel) -> String {
        match m {
            TopModel::Default => "default".into(),
            TopModel::Off => "none".into(),
            TopModel::File(p) => p.display().to_string(),
        }
    }
}

/// How top views are counted.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TopViewConfig {
    /// The model that counts them.
    pub model: TopModel,
    /// The top-view model's centre threshold; `None` takes
    /// [`DEFAULT_TOP_CENTER_THRESHOLD`].
    pub center_threshold: Option<f32>,
    /// The top-view model's NMS window (odd, output pixels); `None` takes
    /// [`DEFAULT_TOP_NMS_KERNEL`]. Leaves crowd at the whorl more from above
    /// than from the side.
    pub nms_kernel: Option<u32>,
}

impl TopViewConfig {
    /// The top-view model file to load, if any. `side_model_chosen` says
    /// that the side-view model was named (in the configuration or by
    /// `$PHYLLO_MODEL`): a model under study then counts every view, unless
    /// a top-view model is named too.
    pub fn model_path(&self, side_model_chosen: bool) -> Option<PathBuf> {
        match &self.model {
            TopModel::Off => None,
            TopModel::File(p) => Some(p.clone()),
            TopModel::Default if side_model_chosen => None,
            TopModel::Default => default_top_model_path(),
        }
    }

    /// The centre threshold the top-view model counts with.
    pub fn center_threshold(&self) -> f32 {
        self.center_threshold.unwrap_or(DEFAULT_TOP_CENTER_THRESHOLD)
    }

    /// The NMS window the top-view model counts with.
    pub fn nms_kernel(&self) -> u32 {
        self.nms_kernel.unwrap_or(DEFAULT_TOP_NMS_KERNEL)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_side_model_named_by_hand_counts_every_view() {
        let c = TopViewConfig::default();
        assert_eq!(c.model_path(true), None);
        let named = TopViewConfig {
            model: TopModel::File("t.onnx".into()),
            ..TopViewConfig::default()
        };
        assert_eq!(named.model_path(true), Some(PathBuf::from("t.onnx")));
        let off = TopViewConfig {
            model: TopModel::Off,
            ..TopViewConfig::default()
        };
        assert_eq!(off.model_path(false), None);
    }

    #[test]
    fn top_model_choices_read_and_write_as_text() {
        for (text, m) in [
            ("default", TopModel::Default),
            ("none", TopModel::Off),
            ("models/t.onnx", TopModel::File("models/t.onnx".into())),
        ] {
            assert_eq!(text.parse::<TopModel>().unwrap(), m);
            assert_eq!(String::from(m), text);
        }
        assert!("".parse::<TopModel>().is_err());
    }
}
