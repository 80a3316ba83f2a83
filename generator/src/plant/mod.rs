//! The procedural plant: genotype presets, development over time, and the
//! mesh of stem, sheaths, leaf blades and panicle.

pub mod growth;
pub mod leaf;
pub mod preset;
pub mod spline;

use crate::mesh::{Mesh, TriInfo};
use glam::Vec3;
use growth::{PlantState, PlantTraits};
use std::f32::consts::PI;

/// Material slots every plant mesh uses (the renderer fills in the colours).
pub mod materials {
    /// Leaf tissue (colour by per-triangle senescence).
    pub const LEAF: u16 = 0;
    /// Stem and sheaths.
    pub const STEM: u16 = 1;
    /// Panicle.
    pub const PANICLE: u16 = 2;
}

/// A plant on one day, meshed.
#[derive(Debug, Clone)]
pub struct Plant {
    /// The plant's fixed traits.
    pub traits: PlantTraits,
    /// Its state on the day.
    pub state: PlantState,
    /// The mesh, leaves as groups `leaf_NN` with instance = NN.
    pub mesh: Mesh,
}

impl Plant {
    /// Grows the plant to `age_days` and meshes it.
    pub fn build(traits: &PlantTraits, age_days: f32) -> Plant {
        let state = traits.at(age_days);
        let mut mesh = Mesh::default();
        mesh.begin_group("stem");
        stem(&mut mesh, state.stem_height, state.stem_radius);
        let sheath_material = if traits.green_sheaths {
            materials::LEAF
        } else {
            materials::STEM
        };
        for (k, leaf) in state.leaves.iter().enumerate() {
            leaf::sheath(
                &mut mesh,
                leaf,
                leaf::SheathShape {
                    stem_radius: state.stem_radius,
                    layer: k as f32 / state.leaves.len().max(1) as f32,
                    flare: traits.sheath_flare,
                },
                sheath_material,
            );
        }
        for (k, leaf) in state.leaves.iter().enumerate() {
            // Instances number the living leaves bottom to top, so a leaf keeps
            // its mask colour in every view of the same plant.
            let instance = (k + 1) as u16;
            mesh.begin_group(format!("leaf_{instance:02}"));
            leaf::blade(
                &mut mesh,
                &traits.leaves[leaf.rank],
                leaf,
                state.stem_radius,
                instance,
                materials::LEAF,
            );
        }
        if let Some((len, rad)) = state.panicle {
            mesh.begin_group("panicle");
            panicle(&mut mesh, state.stem_height, len, rad);
        }
        mesh.end_group();
        Plant {
            traits: traits.clone(),
            state,
            mesh,
        }
    }

    /// Living leaves on the plant.
    pub fn leaf_count(&self) -> usize {
        self.state.leaves.len()
    }
}

/// A closed ring of `sides + 1` vertices (first = last, so grids close) of
/// radius `r` around the plant axis at height `y`: one row of a tube.
fn ring(r: f32, y: f32, sides: usize) -> Vec<Vec3> {
    (0..=sides)
        .map(|j| {
            let a = 2.0 * PI * j as f32 / sides as f32;
            Vec3::new(r * a.cos(), y, r * a.sin())
        })
        .collect()
}

fn stem(mesh: &mut Mesh, height: f32, radius: f32) {
    let sides = 12;
    let rings = 8;
    let rows: Vec<Vec<Vec3>> = (0..=rings)
        .map(|k| {
            let f = k as f32 / rings as f32;
            let y = -0.01 + (height + 0.01) * f;
            let r = radius * (1.0 - 0.35 * f);
            ring(r, y, sides)
        })
        .collect();
    mesh.grid(&rows, |_| TriInfo {
        class: phyllo_contract::STEM,
        instance: 0,
        material: materials::STEM,
        senescence: 0.0,
    });
}

fn panicle(mesh: &mut Mesh, base: f32, length: f32, radius: f32) {
    let sides = 10;
    let rings = 16;
    let rows: Vec<Vec<Vec3>> = (0..=rings)
        .map(|k| {
            let f = k as f32 / rings as f32;
            let y = base + length * f;
            // Spindle: widest below the middle, with lumpy branches.
            let r = radius * (PI * f).sin().powf(0.6) * (1.0 + 0.15 * (f * 23.0).sin());
            (0..=sides)
                .map(|j| {
                    let a = 2.0 * PI * j as f32 / sides as f32;
                    let bump = 1.0 + 0.2 * (a * 3.0 + f * 11.0).sin();
                    Vec3::new(r * bump * a.cos(), y, r * bump * a.sin())
                })
                .collect()
        })
        .collect();
    mesh.grid(&rows, |_| TriInfo {
        class: phyllo_contract::PANICLE,
        instance: 1,
        material: materials::PANICLE,
        senescence: 0.0,
    });
}
