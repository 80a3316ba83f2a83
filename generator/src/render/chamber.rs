//! The virtual LemnaTec imaging chamber, in chamber coordinates (y up, the
//! plant axis at x = z = 0, soil surface at y = 0, side camera on +z).
//!
//! Walls, floor and frames are analytic rectangles: cheap to intersect and
//! never rotated. The back wall, translucent side panels and ceiling are
//! lit from behind in the real chamber, so they are area lights here; other
//! surfaces are shaded by an ambient estimate (they are far from the plant,
//! and the real chamber shows no plant shadows on them). The pot, soil and
//! black carrier turn with the plant, so they are meshed ([`props`]).

use super::look::Look;
use super::walls::{Finish, Rect, BACK_Z, CEILING_Y, FLOOR_Y, FRONT_Z, HALF_WIDTH};
use crate::mesh::{Mesh, TriInfo};
use glam::Vec3;
use std::f32::consts::PI;

/// The chamber: rectangles, with the emitting ones indexed for light sampling.
#[derive(Debug, Clone)]
pub struct Chamber {
    /// All surfaces.
    pub rects: Vec<Rect>,
    /// Indices of emitting rectangles and their cumulative selection weights.
    pub lights: Vec<(usize, f32)>,
    /// Radiance used to shade matte surfaces.
    pub ambient: [f32; 3],
    /// Radiance of rays that leave the chamber.
    pub outside: [f32; 3],
}

fn scale(c: [f32; 3], k: f32) -> [f32; 3] {
    c.map(|x| x * k)
}

fn mul(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

impl Chamber {
    /// Builds the chamber for a look. `with_ceiling` is false for the top
    /// view, whose camera looks in through the ceiling.
    pub fn new(look: &Look, with_ceiling: bool) -> Self {
        let tint = look.light_tint;
        let metal = [0.62, 0.62, 0.6];
        let (y0, y1, w) = (FLOOR_Y, CEILING_Y, HALF_WIDTH);
        let mut rects = vec![
            // Back wall, lit from behind.
            Rect {
                axis: 2,
                at: BACK_Z,
                lo: [-0.42, y0],
                hi: [0.42, y1],
                facing: 1.0,
                finish: Finish::Emitter(scale(tint, look.back_wall)),
            },
            // Floor.
            Rect {
                axis: 1,
                at: y0,
                lo: [-w, BACK_Z],
                hi: [w, FRONT_Z],
                facing: 1.0,
                finish: Finish::Matte(look.floor_albedo),
            },
        ];
        // Side panels (translucent, lit from outside), posts, rails, frames.
        let panel = mul(scale(tint, look.side_panels), [1.0, 1.0, 0.93]);
        rects.extend(super::fittings::build(look.fittings, panel, metal));
        if with_ceiling {
            rects.push(Rect {
                axis: 1,
                at: y1,
                lo: [-w, BACK_Z],
                hi: [w, FRONT_Z],
                facing: -1.0,
                finish: Finish::Emitter(scale(tint, look.ceiling)),
            });
        }
        // Light selection proportional to power, but the far front of the side
        // panels matters little to the plant: weight by area seen from the axis.
        let mut lights = Vec::new();
        let mut total = 0.0;
        for (i, r) in rects.iter().enumerate() {
            if let Finish::Emitter(le) = r.finish {
                let power = (le[0] + le[1] + le[2]) * r.area();
                let c = r.point(0.5, 0.5);
                let dist2 = (c - Vec3::new(0.0, 0.4, 0.0)).length_squared().max(0.25);
                total += power / dist2;
                lights.push((i, total));
            }
        }
        for l in &mut lights {
            l.1 /= total;
        }
        let ambient = scale(tint, 0.8 * look.back_wall.max(look.side_panels));
        Chamber {
            rects,
            lights,
            ambient,
            outside: [0.08, 0.08, 0.08],
        }
    }

    /// Radiance seen along a ray that missed the plant. `emitters` is false
    /// for rays whose light was already counted by next-event estimation.
    #[inline]
    pub fn radiance(&self, o: Vec3, d: Vec3, emitters: bool) -> [f32; 3] {
        let mut best = f32::INFINITY;
        let mut finish = None;
        for r in &self.rects {
            if let Some(t) = r.intersect(o, d) {
                if t < best {
                    best = t;
                    finish = Some(r.finish);
                }
            }
        }
        match finish {
            Some(Finish::Emitter(le)) => {
                if emitters {
                    le
                } else {
                    [0.0; 3]
                }
            }
            Some(Finish::Matte(a)) => mul(a, self.ambient),
            None => self.outside,
        }
    }

    /// Radiance of a prop (pot, soil, carrier) with albedo `albedo` and
    /// normal `n`: ambient light with a soft top-lit gradient. Props are
    /// shaded without sampling so the white pot is as smooth as in real
    /// frames; the plant's faint shadow on it is not modelled.
    #[inline]
    pub fn prop_radiance(&self, albedo: Vec3, n: Vec3) -> Vec3 {
        albedo * Vec3::from(self.ambient) * (1.05 + 0.15 * n.y)
    }

    /// Picks a light with probability `pdf` from a uniform number.
    #[inline]
    pub fn pick_light(&self, u: f32) -> (&Rect, f32) {
        let mut prev = 0.0;
        for &(i, cdf) in &self.lights {
            if u < cdf {
                return (&self.rects[i], cdf - prev);
            }
            prev = cdf;
        }
        let (i, cdf) = *self.lights.last().expect("chamber has lights");
        let before = if self.lights.len() > 1 {
            self.lights[self.lights.len() - 2].1
        } else {
            0.0
        };
        (&self.rects[i], cdf - before)
    }
}

/// Material slots of the props (after the plant's).
pub mod materials {
    /// White pot.
    pub const POT: u16 = 3;
    /// Potting mix.
    pub const SOIL: u16 = 4;
    /// Black metal carrier.
    pub const CARRIER: u16 = 5;
}

/// Pot, soil surface and carrier (labelled background), in plant coordinates.
pub fn props() -> Mesh {
    let mut m = Mesh::default();
    let bg = |material| TriInfo {
        class: 0,
        instance: 0,
        material,
        senescence: 0.0,
    };
    let sides = 32;
    // Pot: a slightly tapered white cylinder with a rolled rim.
    let (r_top, r_bot, y_top, y_bot) = (0.062f32, 0.052f32, 0.012f32, -0.16f32);
    let ring = |r: f32, y: f32| -> Vec<Vec3> {
        (0..=sides)
            .map(|j| {
                let a = 2.0 * PI * j as f32 / sides as f32;
                Vec3::new(r * a.cos(), y, r * a.sin())
            })
            .collect()
    };
    m.begin_group("pot");
    let rows = vec![
        ring(r_bot, y_bot),
        ring(r_top, y_top - 0.012),
        ring(r_top + 0.004, y_top - 0.008),
        ring(r_top + 0.004, y_top),
        ring(r_top - 0.003, y_top),
    ];
    m.grid(&rows, |_| bg(materials::POT));
    m.begin_group("soil");
    let rows = vec![ring(r_top - 0.003, -0.004), ring(0.0, -0.004)];
    m.grid(&rows, |_| bg(materials::SOIL));
    // Carrier: a black square cage around the pot's lower part.
    m.begin_group("carrier");
    let h = 0.078f32;
    let boxes = [
        (Vec3::new(-h, FLOOR_Y, -h), Vec3::new(h, FLOOR_Y + 0.025, h)),
        (
            Vec3::new(-h, FLOOR_Y, -h),
            Vec3::new(-h + 0.008, -0.1, -h + 0.008),
        ),
        (Vec3::new(h - 0.008, FLOOR_Y, -h), Vec3::new(h, -0.1, -h + 0.008)),
        (Vec3::new(-h, FLOOR_Y, h - 0.008), Vec3::new(-h + 0.008, -0.1, h)),
        (Vec3::new(h - 0.008, FLOOR_Y, h - 0.008), Vec3::new(h, -0.1, h)),
        (Vec3::new(-h, -0.11, -h), Vec3::new(h, -0.1, -h + 0.006)),
        (Vec3::new(-h, -0.11, h - 0.006), Vec3::new(h, -0.1, h)),
        (Vec3::new(-h, -0.11, -h), Vec3::new(-h + 0.006, -0.1, h)),
        (Vec3::new(h - 0.006, -0.11, -h), Vec3::new(h, -0.1, h)),
    ];
    for (lo, hi) in boxes {
        cuboid(&mut m, lo, hi, bg(materials::CARRIER));
    }
    m.end_group();
    m
}

fn cuboid(m: &mut Mesh, lo: Vec3, hi: Vec3, info: TriInfo) {
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let v: Vec<u32> = (0..8)
        .map(|i| m.vertex(c(i & 1 != 0, i & 2 != 0, i & 4 != 0)))
        .collect();
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    for f in faces {
        m.tri(v[f[0]], v[f[1]], v[f[2]], info);
        m.tri(v[f[0]], v[f[2]], v[f[3]], info);
    }
}
