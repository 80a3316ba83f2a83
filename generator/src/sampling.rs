//! Choosing what to render: which preset and age each plant gets, its look,
//! its split, and which crop of the camera frame becomes the training image.

use crate::plant::growth::PlantTraits;
use crate::plant::preset::Preset;
use crate::render::{camera::Camera, Scene, View, Window};
use crate::rng::{self, Draw};

/// Youngest plant age, days (1 week).
pub const MIN_AGE: f32 = 7.0;
/// Oldest plant age, days (8 weeks).
pub const MAX_AGE: f32 = 56.0;
/// Fewest living leaves of a dataset plant.
pub const MIN_LEAVES: usize = 4;
/// Most living leaves of a dataset plant.
pub const MAX_LEAVES: usize = 13;

/// The ages a dataset plant is drawn from, and the living-leaf counts it
/// must have there. The default is the paper's (1–8 weeks, 4–13 leaves);
/// the facility's late maize reaches 14–15 leaves, which needs older plants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgeRange {
    /// Youngest age, days.
    pub min_age: f32,
    /// Oldest age, days.
    pub max_age: f32,
    /// Fewest living leaves.
    pub min_leaves: usize,
    /// Most living leaves.
    pub max_leaves: usize,
}

impl Default for AgeRange {
    fn default() -> Self {
        Self {
            min_age: MIN_AGE,
            max_age: MAX_AGE,
            min_leaves: MIN_LEAVES,
            max_leaves: MAX_LEAVES,
        }
    }
}

/// The side camera's optical zoom a dataset plant is drawn with: the
/// facility zooms some chambers' side camera in about 2× (the pot's rim
/// ~170 px wide in a 1227×1028 frame instead of ~85), so a `share` of the
/// plants get a zoom drawn uniformly from `min..=max`, the rest 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZoomRange {
    /// Smallest zoom of a zoomed plant.
    pub min: f32,
    /// Largest zoom of a zoomed plant.
    pub max: f32,
    /// Share of plants drawn from the range; the others keep zoom 1.
    pub share: f32,
}

impl ZoomRange {
    /// `phyllo-gen dataset`'s default `--zoom`: a quarter of the plants
    /// zoomed in by 1–2.2×, around the facility's 2×.
    pub const DEFAULT_SPEC: &'static str = "1-2.2:0.25";

    /// Every plant at the calibrated zoom (the paper's protocol).
    pub const NONE: ZoomRange = ZoomRange {
        min: 1.0,
        max: 1.0,
        share: 0.0,
    };

    /// Parses `Z` (every plant at Z), `MIN-MAX` (every plant drawn from the
    /// range) or `MIN-MAX:SHARE`.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let bad = || {
            format!(
                "--zoom {spec:?}: expected Z, MIN-MAX or MIN-MAX:SHARE, zooms in 0.25..=4, share in 0..=1"
            )
        };
        let (range, share) = match spec.split_once(':') {
            Some((r, s)) => (r, s.trim().parse::<f32>().map_err(|_| bad())?),
            None => (spec, 1.0),
        };
        let (min, max) = match range.split_once('-') {
            Some((a, b)) => (
                a.trim().parse::<f32>().map_err(|_| bad())?,
                b.trim().parse::<f32>().map_err(|_| bad())?,
            ),
            None => {
                let z = range.trim().parse::<f32>().map_err(|_| bad())?;
                (z, z)
            }
        };
        let zoom_ok = |z: f32| (0.25..=4.0).contains(&z);
        if !(zoom_ok(min) && zoom_ok(max) && min <= max && (0.0..=1.0).contains(&share)) {
            return Err(bad());
        }
        Ok(ZoomRange { min, max, share })
    }

    /// The zoom of plant `index`. Drawn from its own streams, so the plant,
    /// its age and its look are the same at any zoom setting.
    pub fn pick(&self, seed: u64, index: u64) -> f32 {
        if self.share <= 0.0 || rng::unit_from_bits(rng::derive(seed, "zoom", index)) >= self.share {
            return 1.0;
        }
        let u = rng::unit_from_bits(rng::derive(seed, "zoom-factor", index));
        self.min + (self.max - self.min) * u
    }
}

impl Default for ZoomRange {
    fn default() -> Self {
        Self::parse(Self::DEFAULT_SPEC).expect("the default zoom spec parses")
    }
}

/// Picks a preset for plant `index`, weighted by the presets' weights.
pub fn pick_preset(presets: &[Preset], seed: u64, index: u64) -> &Preset {
    if presets.len() == 1 {
        return &presets[0];
    }
    let total: f32 = presets.iter().map(|p| p.weight).sum();
    let mut u = rng::unit_from_bits(rng::derive(seed, "preset", index)) * total;
    for p in presets {
        if u < p.weight {
            return p;
        }
        u -= p.weight;
    }
    presets
        .iter()
        .rev()
        .find(|p| p.weight > 0.0)
        .unwrap_or(&presets[0])
}

/// Draws an age in `range` at which the plant has the range's number of
/// living leaves (by default 4–13 in 1–8 weeks, the paper's ranges). Falls
/// back to the closest age found.
pub fn pick_age(traits: &PlantTraits, seed: u64, index: u64, range: &AgeRange) -> f32 {
    let mut r = rng::stream(seed, "age", index);
    let mut best = (usize::MAX, range.min_age);
    for _ in 0..64 {
        let age = (r.uniform(range.min_age, range.max_age) * 4.0).round() / 4.0;
        let n = traits.living_on(age);
        if (range.min_leaves..=range.max_leaves).contains(&n) {
            return age;
        }
        let miss = if n < range.min_leaves {
            range.min_leaves - n
        } else {
            n - range.max_leaves
        };
        if miss < best.0 {
            best = (miss, age);
        }
    }
    best.1
}

/// Whether plant `index` is held out for validation (all its views together).
pub fn is_val(seed: u64, index: u64, val_fraction: f32) -> bool {
    rng::unit_from_bits(rng::derive(seed, "split", index)) < val_fraction
}

/// The `size x size` training crop of the camera frame: centred on the pot
/// axis horizontally; vertically the frame itself when it is about the crop's
/// size, otherwise around the plant's top and centre. Outside the frame the
/// crop shows more chamber (padding), never a rescaled plant.
pub fn crop_window(scene: &Scene, camera: &Camera, view: View, size: u32) -> Window {
    let s = size as i32;
    let fh = camera.height as i32;
    match view {
        View::Top => Window {
            x0: camera.cx.round() as i32 - s / 2,
            y0: camera.cy.round() as i32 - s / 2,
            width: size,
            height: size,
        },
        View::Side(_) => {
            let axis = camera.project(glam::Vec3::ZERO).map(|p| p.0).unwrap_or(camera.cx);
            let x0 = axis.round() as i32 - s / 2;
            let y0 = if s >= fh {
                -(s - fh) / 2
            } else {
                let rows: Vec<f32> = scene
                    .plant_corners()
                    .iter()
                    .filter_map(|p| camera.project(*p).map(|q| q.1))
                    .collect();
                let top = rows.iter().cloned().fold(f32::MAX, f32::min);
                let bottom = camera
                    .project(glam::Vec3::new(0.0, -0.2, 0.0))
                    .map(|p| p.1)
                    .unwrap_or(fh as f32);
                let centre = 0.5 * (top.max(0.0) + bottom);
                let want = (centre - s as f32 / 2.0).min(top - 8.0);
                (want.round() as i32).clamp(0, fh - s)
            };
            Window {
                x0,
                y0,
                width: size,
                height: size,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn living_counts(range: &AgeRange) -> Vec<usize> {
        let maize = Preset::load("maize-late").unwrap();
        (0..200)
            .map(|i| {
                let traits = PlantTraits::sample(&maize, rng::derive(9, "plant", i));
                traits.living_on(pick_age(&traits, 9, i, range))
            })
            .collect()
    }

    #[test]
    fn zoom_specs_parse_and_draw_within_their_range() {
        assert_eq!(
            ZoomRange::parse("1").unwrap(),
            ZoomRange {
                min: 1.0,
                max: 1.0,
                share: 1.0
            }
        );
        let r = ZoomRange::parse("1-2.2:0.25").unwrap();
        assert_eq!(r, ZoomRange::default());
        for bad in ["", "0", "2-1", "1-2:1.5", "x", "1-9"] {
            assert!(ZoomRange::parse(bad).is_err(), "{bad:?} parsed");
        }
        let zooms: Vec<f32> = (0..400).map(|i| r.pick(5, i)).collect();
        let zoomed = zooms.iter().filter(|&&z| z != 1.0).count();
        assert!((60..=140).contains(&zoomed), "{zoomed} of 400 zoomed");
        assert!(zooms.iter().all(|z| (1.0..=2.2).contains(z)));
        assert!((0..50).all(|i| ZoomRange::NONE.pick(5, i) == 1.0));
    }

    #[test]
    fn default_ages_keep_the_papers_leaf_range_and_a_wider_range_reaches_late_maize() {
        let paper = living_counts(&AgeRange::default());
        assert!(paper.iter().all(|n| (MIN_LEAVES..=MAX_LEAVES).contains(n)));
        let late = AgeRange {
            max_age: 84.0,
            max_leaves: 16,
            ..Default::default()
        };
        let counts = living_counts(&late);
        assert!(counts.iter().all(|n| (MIN_LEAVES..=16).contains(n)));
        // The facility's late maize shows 14–15 leaves; the default ages never do.
        let late_maize = counts.iter().filter(|&&n| n >= 14).count();
        assert!(
            late_maize >= 10,
            "only {late_maize} of 200 maize plants reach 14 leaves"
        );
    }
}
