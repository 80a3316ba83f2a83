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
