//! Errors of the inference core. Each names the file or library involved.

use std::path::PathBuf;

/// Everything that can go wrong between an image path and a count.
#[derive(Debug, thiserror::Error)]
pub enum InferenceError {
    /// The ONNX Runtime shared library could not be found or loaded.
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
    /// The model file could not be read, or does not follow the contract.
    #[error("model {path}: {reason}")]
    Model {
        /// Path of the model file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The image could not be read or decoded, or breaks the decode limits.
    #[error("image {path}: {reason}")]
    Image {
        /// Path of the image file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// ONNX Runtime failed while running the model.
    #[error("inference failed: {0}")]
    Inference(String),
}

impl InferenceError {
    /// Builds an [`InferenceError::Image`] for `path`.
    pub fn image(path: impl Into<PathBuf>, reason: impl std::fmt::Display) -> Self {
        Self::Image {
            path: path.into(),
            reason: reason.to_string(),
        }
    }

    /// Builds an [`InferenceError::Model`] for `path`.
    pub fn model(path: impl Into<PathBuf>, reason: impl std::fmt::Display) -> Self {
        Self::Model {
            path: path.into(),
            reason: reason.to_string(),
        }
    }
}
