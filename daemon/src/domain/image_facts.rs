//! What the model is told about each image, decided once, where the daemon
//! reads the image's name: the view the `[names]` patterns parsed, and the
//! camera zoom its station pins by file-name pattern
//! (`[[inference.camera_zoom_rules]]`).
//!
//! The inference crate reads no file names; it gets these facts as a
//! [`phyllo_inference::ImageFacts`]. `[inference.top_views] files`, the older
//! file-name rule for top views, is still read: set to anything but its
//! default it decides instead of `[names]`, with a warning at load
//! ([`TopViewsConfig::legacy_files`]).

use std::path::Path;

use phyllo_inference::camera_scale::CameraZoom;
use phyllo_inference::top_view::{TopModel, TopViewConfig};
use phyllo_inference::{ImageFacts, View as ModelView};
use serde::{Deserialize, Serialize};

use super::names::View;

/// `[[inference.camera_zoom_rules]]`: the camera zoom of the images whose
/// file name matches a pattern.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraZoomRule {
    /// Pattern on the file name (not its folders): `*` any run of
    /// characters, `?` any one character, everything else itself.
    pub files: String,
    /// The zoom of those images: a number, `measure` or `contract`.
    pub camera_zoom: CameraZoom,
}

/// The top-view file-name patterns `[inference.top_views] files` had by
/// default (LemnaTec's and phyllo-gen's), before `[names]` told top views.
pub const LEGACY_TOP_VIEW_FILES: [&str; 2] = ["*_TV_*", "*_top.*"];

/// `[inference.top_views]`: the model that counts top views and its
/// post-processing, and the deprecated `files` patterns. Serialised as it
/// always was: the stored counting settings show it whole.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TopViewsConfig {
    /// The model that counts them: `default`, `none` or a file.
    pub model: TopModel,
    /// Deprecated: file-name patterns of top views (`*` and `?`, on the name
    /// without its folders). `[names]` tells top views now; a value other
    /// than the default still decides, with a warning.
    pub files: Vec<String>,
    /// The top-view model's centre threshold; `None`: the shipped model's.
    pub center_threshold: Option<f32>,
    /// The top-view model's NMS window (odd, output pixels); `None`: the
    /// shipped model's.
    pub nms_kernel: Option<u32>,
}

impl Default for TopViewsConfig {
    fn default() -> Self {
        Self {
            model: TopModel::Default,
            files: LEGACY_TOP_VIEW_FILES.map(String::from).to_vec(),
            center_threshold: None,
            nms_kernel: None,
        }
    }
}

impl TopViewsConfig {
    /// The inference core's part: which model counts top views, and how.
    pub fn counting(&self) -> TopViewConfig {
        TopViewConfig {
            model: self.model.clone(),
            center_threshold: self.center_threshold,
            nms_kernel: self.nms_kernel,
        }
    }

    /// The deprecated `files` patterns when a site set them to anything but
    /// the default: they then decide which images are top views, as they did
    /// before `[names]` did, so that such a site's counts do not change.
    pub fn legacy_files(&self) -> Option<&[String]> {
        (self.files != LEGACY_TOP_VIEW_FILES).then_some(self.files.as_slice())
    }
}

/// The rules that turn a parsed name into the model's [`ImageFacts`].
#[derive(Debug, Clone, Copy)]
pub struct ImageRules<'a> {
    camera_zoom_rules: &'a [CameraZoomRule],
    legacy_top_files: Option<&'a [String]>,
}

impl<'a> ImageRules<'a> {
    /// The rules of `[[inference.camera_zoom_rules]]` and `[inference.top_views]`.
    pub fn new(camera_zoom_rules: &'a [CameraZoomRule], top_views: &'a TopViewsConfig) -> Self {
        Self {
            camera_zoom_rules,
            legacy_top_files: top_views.legacy_files(),
        }
    }

    /// What the model is told about the image at `path` (its file name is
    /// what the rules match, not its folders), whose name `[names]` read as
    /// `view`.
    pub fn facts(&self, path: &Path, view: &View) -> ImageFacts {
        let name = path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
        let top = match self.legacy_top_files {
            Some(files) => files.iter().any(|p| glob_match(p, &name)),
            None => view.is_top(),
        };
        let view = match view {
            _ if top => ModelView::Top,
            View::Side(a) => ModelView::Side { angle: Some(*a) },
            View::Top(_) | View::Other(_) => ModelView::Side { angle: None },
        };
        let camera_zoom = self
            .camera_zoom_rules
            .iter()
            .find(|r| glob_match(&r.files, &name))
            .map(|r| r.camera_zoom);
        ImageFacts { view, camera_zoom }
    }
}

/// Whether `name` matches the whole of `pattern` (`*` and `?` wildcards).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let n: Vec<char> = name.chars().collect();
    // Iterative matcher with one backtrack point: the last `*` seen.
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || p[i] == n[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::names::{NamePatterns, NamesConfig};

    fn zoom_of(rules: &[CameraZoomRule], path: &str) -> Option<CameraZoom> {
        let top = TopViewsConfig::default();
        ImageRules::new(rules, &top)
            .facts(Path::new(path), &View::Side(0))
            .camera_zoom
    }

    #[test]
    fn patterns_match_whole_names() {
        assert!(glob_match(
            "81-*",
            "81-265-CML332_2018-08-21_12-52-45_Vis_SV_108.jpg"
        ));
        assert!(!glob_match("81-*", "402-081-N9_2019-05-10_Vis_SV_108.jpg"));
        assert!(glob_match("*_SV_???.jpg", "a_SV_108.jpg"));
        assert!(!glob_match("*_SV_???.jpg", "a_SV_36.jpg"));
        assert!(glob_match("*", ""));
        assert!(glob_match("a*b*c", "aXbYbZc"));
        assert!(!glob_match("a*b*c", "aXbYbZ"));
    }

    #[test]
    fn the_first_matching_rule_wins_and_folders_do_not_count() {
        let rules = vec![
            CameraZoomRule {
                files: "81-2*".into(),
                camera_zoom: CameraZoom::Fixed(2.0),
            },
            CameraZoomRule {
                files: "81-*".into(),
                camera_zoom: CameraZoom::Fixed(1.5),
            },
        ];
        // `None`: the counter's configured zoom, as `default` was before.
        assert_eq!(zoom_of(&rules, "/x/81-265.jpg"), Some(CameraZoom::Fixed(2.0)));
        assert_eq!(zoom_of(&rules, "/x/81-061.jpg"), Some(CameraZoom::Fixed(1.5)));
        assert_eq!(zoom_of(&rules, "/81-2/402-1.jpg"), None);
    }

    /// `[names]` tells top views; the facility's flat names read as they did
    /// by the old `*_TV_*` rule, and so do the snapshot layouts' top views,
    /// which that rule missed.
    #[test]
    fn names_tell_top_views() {
        let names = NamePatterns::from_config(&NamesConfig::default()).unwrap();
        let top = TopViewsConfig::default();
        let rules = ImageRules::new(&[], &top);
        let facts = |rel: &str| rules.facts(Path::new(rel), &names.parse(Path::new(rel)).unwrap().view);
        assert_eq!(facts("P1_2018-04-20_10-02-00_Vis_TV_90.png").view, ModelView::Top);
        assert_eq!(
            facts("P1_2018-04-20_10-02-00_Vis_SV_90.png").view,
            ModelView::Side { angle: Some(90) }
        );
        assert_eq!(
            facts("2019-05-10_E1_P1_2019-05-10_09-18-07_1/Vis_TV_90/0_0_0.png").view,
            ModelView::Top
        );
        assert_eq!(
            facts("2019-05-10_E1_P1_2019-05-10_09-18-07_1/top_0_90_0.png").view,
            ModelView::Top
        );
    }

    /// A site that set its own `files` keeps them deciding (with a warning
    /// at load), whatever `[names]` says.
    #[test]
    fn legacy_top_view_files_still_decide_when_set() {
        let top = TopViewsConfig {
            files: vec!["*_TOP_*".into()],
            ..TopViewsConfig::default()
        };
        assert!(TopViewsConfig::default().legacy_files().is_none());
        let rules = ImageRules::new(&[], &top);
        let view = |rel: &str, parsed: View| rules.facts(Path::new(rel), &parsed).view;
        assert_eq!(view("/d/P1_x_TOP_1.png", View::Side(0)), ModelView::Top);
        assert_eq!(
            view("/d/P1_Vis_TV_90.png", View::Top(90)),
            ModelView::Side { angle: None }
        );
    }
}
