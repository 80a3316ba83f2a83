//! The side camera's zoom, measured in the frame, and the scale it sets.
//!
//! The contract's scale rule brings every frame to one height, which is
//! right for one camera zoom only; the facility zooms some chambers' side
//! camera in about 2× (issue 41). The chamber's back wall is a backlit panel
//! between two dark posts. Unlike the carrier it does not turn with the
//! plant, and unlike the pot it stands out from the white wall, so its width
//! in the frame depends on the camera's zoom alone: 243–244 model pixels on
//! every unzoomed dev frame and 482–487 on both zoomed ones
//! (`scripts/camera-zoom.sh`). Dividing the contract's scale by the measured
//! zoom shows the model a plant as large as it was trained on.

use image::RgbImage;
use phyllo_contract::Contract;
use serde::{Deserialize, Serialize};

use crate::tiling::{is_frame, scale_for};

/// Width of the back panel between its posts' inner edges, in model pixels
/// at the contract's frame scale, at the zoom the contract's scale assumes.
pub const REFERENCE_PANEL_WIDTH: f32 = 244.0;

/// Measured zooms this close to 1 are taken as 1, so that frames of the
/// camera the contract was made for count exactly as before.
const SNAP_TO_ONE: f32 = 0.06;

/// Measured zooms outside this range are taken as a failed measurement.
const ZOOM_RANGE: (f32, f32) = (0.5, 4.0);

/// Share of the sampled rows where a column must be dark to be a post.
const POST_SHARE: f32 = 0.5;

/// Share of the panel's columns that must be mostly bright wall.
const BRIGHT_SHARE: f32 = 0.5;

/// How the side camera's zoom is decided.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum CameraZoom {
    /// A fixed zoom, as a station that knows its camera pins it.
    Fixed(f32),
    /// `measure` or `contract`.
    Rule(ZoomRule),
}

/// The zoom rules that need no number.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZoomRule {
    /// Measure it from the back panel; frames where it is not found fall
    /// back to the contract's rule.
    #[default]
    Measure,
    /// Assume the contract's zoom (every frame to the contract's height).
    Contract,
}

impl Default for CameraZoom {
    fn default() -> Self {
        CameraZoom::Rule(ZoomRule::Measure)
    }
}

impl std::str::FromStr for CameraZoom {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "measure" => Ok(CameraZoom::Rule(ZoomRule::Measure)),
            "contract" => Ok(CameraZoom::Rule(ZoomRule::Contract)),
            _ => {
                let z: f32 = s
                    .parse()
                    .map_err(|_| format!("{s:?} is not `measure`, `contract` or a zoom such as 2"))?;
                CameraZoom::fixed(z)
            }
        }
    }
}

impl CameraZoom {
    /// A fixed zoom, checked to lie in the believable range.
    pub fn fixed(z: f32) -> Result<Self, String> {
        if z.is_finite() && (ZOOM_RANGE.0..=ZOOM_RANGE.1).contains(&z) {
            Ok(CameraZoom::Fixed(z))
        } else {
            Err(format!(
                "camera zoom {z} must lie in {}..={}",
                ZOOM_RANGE.0, ZOOM_RANGE.1
            ))
        }
    }
}

/// The back panel found in a frame: its posts' inner edges, in image pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BackPanel {
    /// Inner edge of the left post.
    pub left: f32,
    /// Inner edge of the right post.
    pub right: f32,
}

impl BackPanel {
    /// Width between the posts, in image pixels.
    pub fn width(&self) -> f32 {
        self.right - self.left
    }
}

/// Where a count's scale came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ScaleSource {
    /// The contract's rule (frame height, or the crop factor).
    Contract,
    /// The contract's rule divided by the zoom measured on the back panel.
    BackPanel,
    /// The contract's rule divided by a configured zoom.
    Pinned,
    /// A scale given outright (`--scale`).
    Given,
}

/// The scale an image is counted at and how it was found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraScale {
    /// Model pixels per image pixel, before any small-plant enlargement.
    pub scale: f32,
    /// How it was found.
    pub source: ScaleSource,
    /// The camera zoom it assumes relative to the contract's.
    pub camera_zoom: f32,
    /// The back panel measured, when one was found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub panel: Option<BackPanel>,
    /// Why the measurement was not used, when it was tried and failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// Decides the scale of `img`: `given` outright, else the contract's rule
/// divided by the camera zoom that `zoom` pins or measures.
pub fn choose(contract: &Contract, img: &RgbImage, given: Option<f32>, zoom: CameraZoom) -> CameraScale {
    let (w, h) = img.dimensions();
    let base = scale_for(contract, w, h);
    let plain = |source, camera_zoom: f32, note: Option<String>| CameraScale {
        scale: base / camera_zoom,
        source,
        camera_zoom,
        panel: None,
        note,
    };
    if let Some(scale) = given {
        return CameraScale {
            scale,
            ..plain(ScaleSource::Given, 1.0, None)
        };
    }
    match zoom {
        CameraZoom::Fixed(z) => plain(ScaleSource::Pinned, z, None),
        CameraZoom::Rule(ZoomRule::Contract) => plain(ScaleSource::Contract, 1.0, None),
        CameraZoom::Rule(ZoomRule::Measure) if !is_frame(contract, w, h) => {
            plain(ScaleSource::Contract, 1.0, None)
        }
        CameraZoom::Rule(ZoomRule::Measure) => match find_back_panel(img) {
            None => plain(
                ScaleSource::Contract,
                1.0,
                Some("no back panel between two dark posts: the contract's scale".into()),
            ),
            Some(panel) => {
                let measured = panel.width() * base / REFERENCE_PANEL_WIDTH;
                if !(ZOOM_RANGE.0..=ZOOM_RANGE.1).contains(&measured) {
                    let note =
                        format!("back panel gives an unbelievable zoom {measured:.2}: the contract's scale");
                    return CameraScale {
                        panel: Some(panel),
                        ..plain(ScaleSource::Contract, 1.0, Some(note))
                    };
                }
                let z = if (measured - 1.0).abs() < SNAP_TO_ONE {
                    1.0
                } else {
                    measured
                };
                CameraScale {
                    panel: Some(panel),
                    ..plain(ScaleSource::BackPanel, z, None)
                }
            }
        },
    }
}

/// Finds the backlit panel between two dark posts around the frame's
/// centre, or `None`.
///
/// Columns are sampled about 600 across, rows over the frame's upper part
/// (5–60 % of its height: above the pot and the carrier, which are dark
/// too). A post's column is neutral and dark in most sampled rows; a stem
/// is dark too but green, and leaves cross a column in few rows.
pub fn find_back_panel(img: &RgbImage) -> Option<BackPanel> {
    let (w, h) = img.dimensions();
    if w < 64 || h < 64 {
        return None;
    }
    let step = (w / 600).max(1);
    let (top, bottom) = (h / 20, h * 3 / 5);
    let rows: Vec<u32> = (top..bottom).step_by(step as usize).collect();
    let columns: Vec<u32> = (0..w).step_by(step as usize).collect();
    let share = |x: u32, test: fn([u8; 3]) -> bool| {
        let hits = rows.iter().filter(|&&y| test(img.get_pixel(x, y).0)).count();
        hits as f32 / rows.len() as f32
    };
    let post: Vec<bool> = columns
        .iter()
        .map(|&x| share(x, is_post_pixel) > POST_SHARE)
        .collect();
    let centre = columns.len() / 2;
    let left = (0..=centre).rev().find(|&i| post[i])?;
    let right = (centre..columns.len()).find(|&i| post[i])?;
    if right <= left + 1 {
        return None;
    }
    let inside = &columns[left + 1..right];
    let bright = inside.iter().filter(|&&x| share(x, is_wall_pixel) > 0.5).count();
    if (bright as f32) < BRIGHT_SHARE * inside.len() as f32 {
        return None;
    }
    // Inner edges: the panel starts one sampled column inside each post.
    Some(BackPanel {
        left: (columns[left] + step) as f32,
        right: columns[right] as f32,
    })
}

/// Dark and neutral: a post, not a green stem or leaf.
fn is_post_pixel([r, g, b]: [u8; 3]) -> bool {
    let (hi, lo) = (r.max(g).max(b), r.min(g).min(b));
    hi < 90 && hi - lo < 30
}

/// Bright in every channel: the backlit wall.
fn is_wall_pixel([r, g, b]: [u8; 3]) -> bool {
    r.min(g).min(b) > 170
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    /// A 1227x1028 frame: white wall, dark posts with inner edges at
    /// `left`/`right`, a green stem and leaf crossing the middle.
    fn frame(left: u32, right: u32) -> RgbImage {
        let mut img = RgbImage::from_pixel(1227, 1028, Rgb([235, 232, 228]));
        for y in 0..1028 {
            for x in left.saturating_sub(16)..left {
                img.put_pixel(x, y, Rgb([30, 30, 32]));
            }
            for x in right..(right + 16).min(1227) {
                img.put_pixel(x, y, Rgb([30, 30, 32]));
            }
            // A dark green stem the whole height, just right of centre.
            for x in 650..656 {
                img.put_pixel(x, y, Rgb([40, 70, 35]));
            }
        }
        img
    }

    #[test]
    fn the_unzoomed_panel_keeps_the_contract_scale() {
        let c = Contract::embedded();
        let img = frame(410, 898);
        let s = choose(c, &img, None, CameraZoom::default());
        assert_eq!(s.source, ScaleSource::BackPanel);
        assert_eq!(s.camera_zoom, 1.0);
        assert_eq!(s.scale, scale_for(c, 1227, 1028));
        let panel = s.panel.expect("panel found");
        assert!((panel.width() - 488.0).abs() <= 4.0, "{panel:?}");
    }

    #[test]
    fn a_panel_twice_as_wide_halves_the_scale() {
        let c = Contract::embedded();
        let img = frame(178, 1142);
        let s = choose(c, &img, None, CameraZoom::default());
        assert_eq!(s.source, ScaleSource::BackPanel);
        assert!((s.camera_zoom - 1.98).abs() < 0.03, "{s:?}");
        assert!((s.scale * s.camera_zoom - scale_for(c, 1227, 1028)).abs() < 1e-6);
    }

    #[test]
    fn without_posts_the_contract_rule_holds_and_says_so() {
        let c = Contract::embedded();
        let img = RgbImage::from_pixel(1227, 1028, Rgb([235, 232, 228]));
        let s = choose(c, &img, None, CameraZoom::default());
        assert_eq!(s.source, ScaleSource::Contract);
        assert_eq!(s.camera_zoom, 1.0);
        assert!(s.note.as_deref().unwrap_or("").contains("no back panel"), "{s:?}");
    }

    #[test]
    fn pinned_and_given_scales_win_over_the_measurement() {
        let c = Contract::embedded();
        let img = frame(178, 1142);
        let pinned = choose(c, &img, None, CameraZoom::Fixed(1.5));
        assert_eq!(pinned.source, ScaleSource::Pinned);
        assert!((pinned.scale - scale_for(c, 1227, 1028) / 1.5).abs() < 1e-6);
        let given = choose(c, &img, Some(0.3), CameraZoom::default());
        assert_eq!((given.source, given.scale), (ScaleSource::Given, 0.3));
        let contract = choose(c, &img, None, CameraZoom::Rule(ZoomRule::Contract));
        assert_eq!(contract.source, ScaleSource::Contract);
    }

    #[test]
    fn crops_are_not_measured() {
        let c = Contract::embedded();
        let img = RgbImage::from_pixel(400, 600, Rgb([235, 232, 228]));
        let s = choose(c, &img, None, CameraZoom::default());
        assert_eq!((s.source, s.note.is_none()), (ScaleSource::Contract, true));
        assert_eq!(s.scale, c.input.crop_scale);
    }

    #[test]
    fn zoom_settings_parse_and_refuse_nonsense() {
        assert_eq!("measure".parse::<CameraZoom>(), Ok(CameraZoom::default()));
        assert_eq!("2".parse::<CameraZoom>(), Ok(CameraZoom::Fixed(2.0)));
        assert!("0.1".parse::<CameraZoom>().unwrap_err().contains("0.5..=4"));
        assert!("big".parse::<CameraZoom>().unwrap_err().contains("\"big\""));
        let toml: CameraZoom = serde_json::from_str("\"contract\"").unwrap();
        assert_eq!(toml, CameraZoom::Rule(ZoomRule::Contract));
        let fixed: CameraZoom = serde_json::from_str("2.0").unwrap();
        assert_eq!(fixed, CameraZoom::Fixed(2.0));
    }
}
