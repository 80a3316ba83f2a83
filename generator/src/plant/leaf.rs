//! Leaf geometry: a cubic-spline skeleton bent by droop, swept with a V/U
//! cross-section whose width follows the leaf's profile (a generalised
//! cylinder), plus the closed sheath that wraps the stem below the collar.

use super::growth::{LeafState, LeafTraits};
use super::spline::CatmullRom;
use crate::mesh::{Mesh, TriInfo};
use glam::{Quat, Vec3};
use std::f32::consts::PI;

/// Segments along every blade (the paper renders with at least 128).
pub const BLADE_SEGMENTS: usize = 128;
/// Cross-section points per half blade (midrib excluded).
const HALF_POINTS: usize = 3;
/// Segments around the sheath tube.
const SHEATH_SIDES: usize = 12;

/// Blade half-width at relative position `u` along the blade.
fn width_profile(u: f32, peak: f32, base: f32) -> f32 {
    if u < peak {
        base + (1.0 - base) * (0.5 * PI * u / peak).sin()
    } else {
        ((1.0 - u) / (1.0 - peak)).max(0.0).powf(0.75)
    }
}

/// Relative blade length over which a buckle turns the midrib.
const KINK_SPAN: f32 = 0.06;
/// The skeleton never points further than this from vertical, so a buckled
/// tip hangs down and does not curl back up toward the stem.
const MAX_BEND: f32 = 178.0 * PI / 180.0;

/// How a blade's skeleton bends: an even arc from the insertion angle to the
/// tip angle, plus an optional buckle, a sharp extra bend over a short span.
#[derive(Debug, Clone, Copy)]
struct Bend {
    insertion: f32,
    tip: f32,
    kink_position: f32,
    kink: f32,
}

impl Bend {
    /// Angle of the skeleton from vertical at relative position `u`.
    fn angle(&self, u: f32) -> f32 {
        let arc = self.insertion + (self.tip - self.insertion) * u.powf(1.4);
        let x = ((u - self.kink_position) / KINK_SPAN + 0.5).clamp(0.0, 1.0);
        (arc + self.kink * x * x * (3.0 - 2.0 * x)).min(MAX_BEND)
    }
}

/// The skeleton's control points: integrate the bend angle in the leaf's
/// vertical plane, then displace sideways by the leaf's wander.
fn control_points(base: Vec3, out: Vec3, side: Vec3, traits: &LeafTraits, state: &LeafState) -> Vec<Vec3> {
    let length = state.length.max(1e-3);
    let insertion = state.insertion;
    // Longer leaves bend more under their own weight.
    let droop = state.droop * (length / 0.5).clamp(0.3, 1.4);
    let bend = Bend {
        insertion,
        tip: (insertion + droop * 150f32.to_radians()).min(175f32.to_radians()),
        kink_position: traits.kink_position,
        kink: state.kink,
    };
    let steps = 96;
    let ds = length / steps as f32;
    let mut p = base;
    let mut pts = vec![base];
    for k in 0..steps {
        let a = bend.angle((k as f32 + 0.5) / steps as f32);
        p += (out * a.sin() + Vec3::Y * a.cos()) * ds;
        if (k + 1) % (steps / 6) == 0 {
            pts.push(p);
        }
    }
    for (k, q) in pts.iter_mut().enumerate() {
        *q += side * traits.wander[k] * length;
    }
    pts
}

/// The label a blade's triangles carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BladeLabel {
    /// Contract class.
    pub class: u8,
    /// Instance (0 for stem).
    pub instance: u16,
}

impl BladeLabel {
    /// A dead leaf's remnant: part of the stem, not a leaf to count.
    pub const STEM: BladeLabel = BladeLabel {
        class: phyllo_contract::STEM,
        instance: 0,
    };

    /// A living leaf, instance `instance`.
    pub fn leaf(instance: u16) -> Self {
        Self {
            class: phyllo_contract::LEAF,
            instance,
        }
    }
}

/// Appends one leaf blade labelled `label` to `mesh` and returns its tip:
/// the end of the midrib (u = 1), where the width profile is zero, so every
/// vertex of the blade's last mesh row sits there.
pub fn blade(
    mesh: &mut Mesh,
    traits: &LeafTraits,
    state: &LeafState,
    stem_radius: f32,
    label: BladeLabel,
    material: u16,
) -> Vec3 {
    let (s, c) = traits.azimuth.sin_cos();
    let out = Vec3::new(c, 0.0, s);
    let side0 = Vec3::new(-s, 0.0, c);
    let base = Vec3::new(0.0, state.base_height, 0.0) + out * stem_radius * (0.8 + 0.4 * (1.0 - state.furl));
    let spline = CatmullRom::new(control_points(base, out, side0, traits, state));
    let pts = spline.sample(BLADE_SEGMENTS);
    let width = traits.width * state.width_scale;
    let mut rows = Vec::with_capacity(pts.len());
    let mut along_len = 0.0f32;
    for (i, p) in pts.iter().enumerate() {
        let u = i as f32 / BLADE_SEGMENTS as f32;
        if i > 0 {
            along_len += (pts[i] - pts[i - 1]).length();
        }
        let t = if i == 0 {
            pts[1] - pts[0]
        } else if i == pts.len() - 1 {
            pts[i] - pts[i - 1]
        } else {
            pts[i + 1] - pts[i - 1]
        };
        let t = t.normalize_or(Vec3::Y);
        let side = (side0 - t * t.dot(side0)).normalize_or(side0);
        let twist = Quat::from_axis_angle(t, traits.twist * u.powf(1.5));
        let side = twist * side;
        let normal = side.cross(t);
        let hw = 0.5 * width * width_profile(u, traits.width_peak, traits.base_width);
        // The blade base cups around the stem where it leaves the sheath.
        let furl = state.furl.max(0.75 * (1.0 - u / 0.04).max(0.0));
        let v = traits.v_angle * (1.0 - 0.7 * u) * (1.0 - state.furl);
        let wave = traits.waviness * (u * (1.0 - u) * 4.0).min(1.0);
        let mut row = Vec::with_capacity(2 * HALF_POINTS + 1);
        for sign in [-1.0f32, 1.0] {
            let mut q = glam::Vec2::ZERO;
            let mut half = Vec::with_capacity(HALF_POINTS);
            for k in 1..=HALF_POINTS {
                let a = v + furl * 2.6 * (k as f32 - 0.5) / HALF_POINTS as f32;
                q += glam::Vec2::new(a.cos(), a.sin()) * (hw / HALF_POINTS as f32);
                let frac = k as f32 / HALF_POINTS as f32;
                let ripple = wave
                    * hw
                    * frac
                    * frac
                    * (2.0 * PI * along_len / traits.wave_length + traits.wave_phase + sign * 1.3).sin();
                half.push(*p + side * (sign * q.x) + normal * (q.y + ripple));
            }
            if sign < 0.0 {
                half.reverse();
                row.extend(half);
                row.push(*p);
            } else {
                row.extend(half);
            }
        }
        rows.push(row);
    }
    let senescence = state.senescence;
    mesh.grid(&rows, |r| {
        // Senescence starts at the tip and moves down the blade.
        let u = (r as f32 + 0.5) / BLADE_SEGMENTS as f32;
        let local = (senescence * 1.8 - (1.0 - u) * 0.8).clamp(0.0, 1.0);
        TriInfo {
            class: label.class,
            instance: label.instance,
            material,
            senescence: local,
        }
    });
    pts[BLADE_SEGMENTS]
}

/// Where a sheath sits and how it widens.
#[derive(Debug, Clone, Copy)]
pub struct SheathShape {
    /// Radius of the stem it wraps.
    pub stem_radius: f32,
    /// 0 for the lowest leaf's sheath up to 1 for the top one: outer sheaths
    /// are slightly wider so stacked sheaths do not z-fight.
    pub layer: f32,
    /// Radius at the collar relative to the node.
    pub flare: f32,
}

/// Appends the leaf's sheath: a closed tube around the stem from its node up
/// to the collar, widening by `shape.flare` (labelled as stem: it reads as
/// stem in the images).
pub fn sheath(mesh: &mut Mesh, state: &LeafState, shape: SheathShape, material: u16) {
    if state.sheath_length <= 1e-4 {
        return;
    }
    let r0 = shape.stem_radius * (1.08 + 0.04 * shape.layer);
    let rings = 6;
    let rows: Vec<Vec<Vec3>> = (0..=rings)
        .map(|k| {
            let f = k as f32 / rings as f32;
            let y = state.node_height + state.sheath_length * f;
            // Most of the loosening happens near the collar.
            let r = r0 * (1.0 + (shape.flare - 1.0) * f * f);
            super::ring(r, y, SHEATH_SIDES)
        })
        .collect();
    mesh.grid(&rows, |_| TriInfo {
        class: phyllo_contract::STEM,
        instance: 0,
        material,
        senescence: state.senescence * 0.5,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn width_profile_is_zero_at_tip_and_peaks_at_one() {
        assert!(width_profile(1.0, 0.4, 0.4).abs() < 1e-6);
        assert!((width_profile(0.4, 0.4, 0.4) - 1.0).abs() < 1e-5);
        assert!((width_profile(0.0, 0.4, 0.4) - 0.4).abs() < 1e-6);
    }

    #[test]
    fn a_buckle_adds_its_angle_over_a_short_span_and_never_curls_back() {
        let even = Bend {
            insertion: 0.5,
            tip: 1.5,
            kink_position: 0.5,
            kink: 0.0,
        };
        let buckled = Bend { kink: 1.2, ..even };
        // Before the fold the two blades coincide, after it they differ by
        // the whole buckle.
        assert_eq!(buckled.angle(0.4), even.angle(0.4));
        assert!((buckled.angle(0.6) - even.angle(0.6) - 1.2).abs() < 1e-5);
        // Half the buckle is reached at the fold itself.
        assert!((buckled.angle(0.5) - even.angle(0.5) - 0.6).abs() < 1e-5);
        let steep = Bend {
            kink: 2.0,
            tip: 2.8,
            ..even
        };
        assert!(steep.angle(1.0) <= MAX_BEND);
    }
}
