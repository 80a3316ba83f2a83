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

/// Draws an age in 1–8 weeks at which the plant has 4–13 living leaves
/// (the paper's ranges). Falls back to the closest age found.
pub fn pick_age(traits: &PlantTraits, seed: u64, index: u64) -> f32 {
    let mut r = rng::stream(seed, "age", index);
    let mut best = (usize::MAX, MIN_AGE);
    for _ in 0..64 {
        let age = (r.uniform(MIN_AGE, MAX_AGE) * 4.0).round() / 4.0;
        let n = traits.living_on(age);
        if (MIN_LEAVES..=MAX_LEAVES).contains(&n) {
            return age;
        }
        let miss = if n < MIN_LEAVES {
            MIN_LEAVES - n
        } else {
            n - MAX_LEAVES
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
