//! phyllo's inference core: from an image file to a leaf count.
//!
//! Data flows one way through these stages, each in its own module:
//!
//! ```text
//! decode ─► region ─► tiling ─► model (ONNX Runtime) ─► stitch ─► postprocess ─► attachment ─► pieces ─► CountResult
//! ```
//!
//! From postprocess on, the stages hand one [`panoptic::Panoptic`] along; it
//! has a module of its own so that no stage depends on another for it.
//!
//! With a model that has a leaf-tip output, [`tips`] counts leaves by their
//! tips as well as by their centres.
//!
//! A small plant goes through the stages twice: [`zoom`] measures it on the
//! first pass and the second sees it enlarged.
//!
//! Before tiling, [`camera_scale`] measures the side camera's zoom on the
//! chamber's back panel, so a zoomed frame is counted at the contract's scale.
//!
//! [`Counter`] ties the stages together; the daemon and the CLI only use it.
//! It reads no file names: the caller says what an image is ([`ImageFacts`]).

pub mod attachment;
pub mod camera_scale;
pub mod counter;
pub mod decode;
pub mod error;
pub mod flip;
pub mod image;
pub mod model;
pub mod model_path;
pub mod overlay;
pub mod panoptic;
pub mod pieces;
pub mod postprocess;
pub mod region;
pub mod result;
pub mod runtime;
pub mod stitch;
pub mod tiling;
pub mod tips;
pub mod top_view;
pub mod zoom;

pub use counter::{Counter, CounterConfig};
pub use error::InferenceError;
pub use image::{ImageFacts, View};
pub use result::{CountResult, Instance, StageTimings};
