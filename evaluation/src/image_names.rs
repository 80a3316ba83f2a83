//! What the images of evaluation data and loose files are, read from their
//! file names: phyllo-gen's (`p000012_top.png`, `p000012_108.png`) and
//! LemnaTec's (`..._Vis_TV_90.png`, `..._Vis_SV_108.jpg`).
//!
//! The inference crate reads no file names, and the daemon's `[names]`
//! patterns need a plant, a date and a time that these files may lack. So
//! `phyllo eval`, `phyllo bench` and `phyllo count` classify their images
//! here, once per image, by the rule the top-view model shipped with: a name
//! holding `_TV_` or `_top.` is a top view. No station pins a zoom here: the
//! counter's `camera_zoom` applies. Their overlays are named after the
//! image here too ([`overlay_path`]).

use std::path::{Path, PathBuf};

use phyllo_inference::{ImageFacts, View};

/// The facts of the image at `path`, by its file name (not its folders).
pub fn facts_for(path: &Path) -> ImageFacts {
    let name = path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    ImageFacts::of_view(view_of(&name))
}

/// The view a file name says: top for LemnaTec's `*_TV_*` and phyllo-gen's
/// `*_top.*`, else a side view at the angle the name gives, if any.
pub fn view_of(name: &str) -> View {
    if name.contains("_TV_") || name.contains("_top.") {
        return View::Top;
    }
    View::Side {
        angle: side_angle(name),
    }
}

/// The angle of LemnaTec's `..._SV_108.jpg` or phyllo-gen's `p000012_108.png`.
fn side_angle(name: &str) -> Option<u16> {
    let digits = |s: &str| -> Option<u16> {
        let d: String = s.chars().take_while(char::is_ascii_digit).collect();
        d.parse().ok()
    };
    if let Some(at) = name.rfind("_SV_") {
        return digits(&name[at + 4..]);
    }
    let stem = name.split('.').next().unwrap_or_default();
    let last = stem.rsplit('_').next()?;
    (stem.contains('_') && last.chars().all(|c| c.is_ascii_digit()))
        .then(|| digits(last))
        .flatten()
}

/// Where an overlay of `image` is written: `DIR/<image stem>.<kind>.png`.
pub fn overlay_path(dir: &Path, image: &Path, kind: &str) -> PathBuf {
    let stem = image
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".into());
    dir.join(format!("{stem}.{kind}.png"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moved from `phyllo_inference::overlay::output_path`.
    #[test]
    fn an_overlay_is_named_after_its_image_and_kind() {
        let dir = Path::new("out");
        assert_eq!(
            overlay_path(dir, Path::new("in/plant_SV_108.jpg"), "tips"),
            dir.join("plant_SV_108.tips.png")
        );
        assert_eq!(
            overlay_path(dir, Path::new(""), "overlay"),
            dir.join("image.overlay.png")
        );
    }

    fn is_top_view(path: &Path) -> bool {
        facts_for(path).view == View::Top
    }

    /// Moved from `phyllo_inference::top_view`, where names were read before.
    #[test]
    fn facility_and_generator_top_views_are_told_by_name() {
        assert!(is_top_view(Path::new(
            "/drop/P1_2018-04-20_10-02-00_Vis_TV_90.png"
        )));
        assert!(is_top_view(Path::new("data/images/p000012_top.png")));
        assert!(!is_top_view(Path::new(
            "/drop/P1_2018-04-20_10-02-00_Vis_SV_90.png"
        )));
        assert!(!is_top_view(Path::new("data/images/p000012_108.png")));
        // Only the file name counts, not the folders it lies in.
        assert!(!is_top_view(Path::new("/x_TV_1/p000012_36.png")));
    }

    #[test]
    fn side_views_carry_the_angle_their_name_gives() {
        let angle = |n: &str| match view_of(n) {
            View::Side { angle } => angle,
            View::Top => panic!("{n} is no top view"),
        };
        assert_eq!(
            angle("81-133-Tzi25_2018-08-20_04-44-32_Vis_SV_0.Crp.jpg"),
            Some(0)
        );
        assert_eq!(angle("P1_2019-05-10_09-18-07_Vis_SV_108.png"), Some(108));
        assert_eq!(angle("p000012_36.png"), Some(36));
        assert_eq!(angle("frame.png"), None);
    }
}
