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
    /// Blade tip (end of the midrib) of each living leaf in plant space:
    /// entry `k` belongs to leaf instance `k + 1`.
    pub leaf_tips: Vec<Vec3>,
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
        for leaf in &state.remnants {
            // Dead sheaths dry whatever colour they had alive.
            leaf::sheath(
                &mut mesh,
                leaf,
                leaf::SheathShape {
                    stem_radius: state.stem_radius,
                    // Inside the living sheaths, so overlapping tubes never coincide.
                    layer: -0.5,
                    flare: traits.sheath_flare,
                },
                materials::LEAF,
            );
            leaf::blade(
                &mut mesh,
                &traits.leaves[leaf.rank],
                leaf,
                state.stem_radius,
                leaf::BladeLabel::STEM,
                materials::LEAF,
            );
        }
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
        let mut leaf_tips = Vec::with_capacity(state.leaves.len());
        for (k, leaf) in state.leaves.iter().enumerate() {
            // Instances number the living leaves bottom to top, so a leaf keeps
            // its mask colour in every view of the same plant.
            let instance = (k + 1) as u16;
            mesh.begin_group(format!("leaf_{instance:02}"));
            leaf_tips.push(leaf::blade(
                &mut mesh,
                &traits.leaves[leaf.rank],
                leaf,
                state.stem_radius,
                leaf::BladeLabel::leaf(instance),
                materials::LEAF,
            ));
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
            leaf_tips,
        }
    }

    /// Plant-space blade tip of leaf instance `instance` (1 = lowest living leaf).
    pub fn leaf_tip(&self, instance: u16) -> Option<Vec3> {
        usize::from(instance)
            .checked_sub(1)
            .and_then(|k| self.leaf_tips.get(k))
            .copied()
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
            // Spindle: widest below the middle, with lumpy branches. In f32,
            // sin(PI) is a hair below zero, and its 0.6th power is NaN: the
            // clamp keeps the tip a point (a NaN vertex panics the BVH build).
            let r = radius * (PI * f).sin().max(0.0).powf(0.6) * (1.0 + 0.15 * (f * 23.0).sin());
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

#[cfg(test)]
mod tests {
    use super::*;
    use preset::Preset;

    #[test]
    fn each_recorded_leaf_tip_is_the_last_mesh_row_of_its_blade() {
        for (name, seed, age) in [("btx623", 1, 35.0), ("sc301", 4, 20.0), ("maize", 2, 45.0)] {
            let preset = Preset::load(name).unwrap();
            let plant = Plant::build(&PlantTraits::sample(&preset, seed), age);
            assert!(plant.leaf_count() >= 3, "{name}: {} leaves", plant.leaf_count());
            assert_eq!(plant.leaf_tips.len(), plant.leaf_count());
            for (k, &tip) in plant.leaf_tips.iter().enumerate() {
                let instance = (k + 1) as u16;
                assert_eq!(plant.leaf_tip(instance), Some(tip));
                let g = plant
                    .mesh
                    .groups
                    .iter()
                    .find(|g| g.name == format!("leaf_{instance:02}"))
                    .unwrap();
                let verts: Vec<usize> = plant.mesh.tris[g.start..g.end]
                    .iter()
                    .flatten()
                    .map(|&v| v as usize)
                    .collect();
                let (first, last) = (*verts.iter().min().unwrap(), *verts.iter().max().unwrap());
                // Rows of 7 vertices, 129 rows: the highest vertex used closes
                // the last row, and that whole row is the tip.
                assert_eq!(last + 1 - first, 7 * (leaf::BLADE_SEGMENTS + 1));
                for v in last - 6..=last {
                    let d = (plant.mesh.positions[v] - tip).length();
                    assert!(d < 1e-6, "{name} leaf {instance}: vertex {v} is {d} from the tip");
                }
                // The tip lies a leaf's length away from the blade base.
                let base = plant.mesh.positions[first + 3];
                let length = plant.state.leaves[k].length;
                let chord = (tip - base).length();
                assert!(
                    chord > 0.2 * length && chord <= 1.05 * length + 1e-3,
                    "{name} leaf {instance}: tip {chord} from base, length {length}"
                );
            }
            assert_eq!(plant.leaf_tip(0), None);
            assert_eq!(plant.leaf_tip(plant.leaf_count() as u16 + 1), None);
        }
    }

    #[test]
    fn flowering_plants_have_finite_vertices() {
        // Panicles emerge from day 62, past the dataset's default ages; older
        // plants (dataset --max-age, long sequences) must still build.
        for seed in 0..4 {
            let preset = Preset::load("btx623").unwrap();
            let plant = Plant::build(&PlantTraits::sample(&preset, seed), 80.0);
            assert!(plant.state.panicle.is_some(), "seed {seed}: no panicle at day 80");
            let bad = plant.mesh.positions.iter().filter(|p| !p.is_finite()).count();
            assert_eq!(bad, 0, "seed {seed}: {bad} non-finite vertices");
        }
    }

    #[test]
    fn dead_leaf_remnants_add_dry_stem_and_leave_the_living_leaves_alone() {
        let mut preset = Preset::load("maize").unwrap();
        let plain_traits = PlantTraits::sample(&preset, 3);
        assert!(
            !plain_traits.dead_remnants,
            "the built-in presets keep remnants off"
        );
        preset.growth.dead_remnant_chance = 1.0;
        let traits = PlantTraits::sample(&preset, 3);
        assert!(traits.dead_remnants);
        // Its own random stream: every other trait is drawn as before.
        assert_eq!(
            format!("{:?}", traits.leaves),
            format!("{:?}", plain_traits.leaves)
        );
        let (plain, kept) = (Plant::build(&plain_traits, 70.0), Plant::build(&traits, 70.0));
        let dead = kept.state.emerged - kept.leaf_count();
        assert!(dead >= 3, "{dead} dead leaves at 70 days");
        assert_eq!(kept.state.remnants.len(), dead);
        assert!(plain.state.remnants.is_empty());
        assert_eq!(kept.leaf_count(), plain.leaf_count());
        assert_eq!(kept.leaf_tips, plain.leaf_tips);
        let count = |p: &Plant, class: u8| p.mesh.info.iter().filter(|i| i.class == class).count();
        assert_eq!(
            count(&kept, phyllo_contract::LEAF),
            count(&plain, phyllo_contract::LEAF)
        );
        // What the remnants add is stem, none of it a leaf instance, and drying.
        let added = kept.mesh.tris.len() - plain.mesh.tris.len();
        assert!(added > 0);
        assert_eq!(
            count(&kept, phyllo_contract::STEM) - count(&plain, phyllo_contract::STEM),
            added
        );
        let max_instance = |p: &Plant| p.mesh.info.iter().map(|i| i.instance).max();
        assert_eq!(max_instance(&kept), max_instance(&plain));
        let dry = kept
            .mesh
            .info
            .iter()
            .filter(|i| i.class == phyllo_contract::STEM && i.senescence > 0.5);
        assert!(dry.count() > added / 4);
        // Stubs are short: a remnant is at most a fifth of its leaf.
        for r in &kept.state.remnants {
            assert!(r.length <= 0.2 * traits.leaves[r.rank].length + 1e-6);
        }
        // A seedling has no dead leaves and so no remnants.
        assert!(Plant::build(&traits, 15.0).state.remnants.is_empty());
    }
}
