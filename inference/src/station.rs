//! Settings a facility pins per station, chosen by the image's file name.
//!
//! A facility that knows which chamber zooms its side camera says so with a
//! file-name pattern (`81-*`, `*_SV_*`), so frames whose back panel cannot be
//! measured, and crops, which carry none, are counted at the right scale.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::camera_scale::CameraZoom;

/// The camera zoom of the images whose file name matches a pattern.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraZoomRule {
    /// Pattern on the file name (not its folders): `*` any run of
    /// characters, `?` any one character, everything else itself.
    pub files: String,
    /// The zoom of those images: a number, `measure` or `contract`.
    pub camera_zoom: CameraZoom,
}

/// The zoom for `path`: the first rule whose pattern matches its file name,
/// else `default`.
pub fn camera_zoom_for(path: &Path, rules: &[CameraZoomRule], default: CameraZoom) -> CameraZoom {
    let name = path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    rules
        .iter()
        .find(|r| glob_match(&r.files, &name))
        .map_or(default, |r| r.camera_zoom)
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
        let d = CameraZoom::default();
        assert_eq!(
            camera_zoom_for(Path::new("/x/81-265.jpg"), &rules, d),
            CameraZoom::Fixed(2.0)
        );
        assert_eq!(
            camera_zoom_for(Path::new("/x/81-061.jpg"), &rules, d),
            CameraZoom::Fixed(1.5)
        );
        assert_eq!(camera_zoom_for(Path::new("/81-2/402-1.jpg"), &rules, d), d);
    }
}
