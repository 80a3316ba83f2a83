//! What a caller tells the counter about an image besides its pixels: which
//! way the camera looked and the camera zoom its station pins.
//!
//! Inference reads no file names. Whoever knows the image's name classifies
//! it once and hands these facts in: the daemon by its `[names]` patterns
//! and `[[inference.camera_zoom_rules]]`, the evaluation and the loose-file
//! commands by the data's own naming (`phyllo_evaluation::image_names`).

use crate::camera_scale::CameraZoom;

/// Which way the camera looked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum View {
    /// A side view, at this turntable angle in degrees when the caller knows it.
    Side {
        /// Turntable angle, degrees.
        angle: Option<u16>,
    },
    /// The top view: counted by the top-view model when there is one.
    Top,
}

impl Default for View {
    /// A side view at an unknown angle: what an image is unless told otherwise.
    fn default() -> Self {
        View::Side { angle: None }
    }
}

impl View {
    /// True for the top view.
    pub fn is_top(self) -> bool {
        self == View::Top
    }
}

/// The facts about one image that decide how it is counted.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImageFacts {
    /// Which way the camera looked; a top view goes to the top-view model.
    pub view: View,
    /// The camera zoom a station rule pins for this image; `None` takes the
    /// counter's configured `camera_zoom`.
    pub camera_zoom: Option<CameraZoom>,
}

impl ImageFacts {
    /// A side view at an unknown angle, with the configured camera zoom.
    pub fn side() -> Self {
        Self::default()
    }

    /// A top view, with the configured camera zoom.
    pub fn top() -> Self {
        Self {
            view: View::Top,
            camera_zoom: None,
        }
    }

    /// The facts of an image seen from `view`, with the configured camera zoom.
    pub fn of_view(view: View) -> Self {
        Self {
            view,
            camera_zoom: None,
        }
    }
}
