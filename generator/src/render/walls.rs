//! Where the chamber's walls stand, and the rectangle that every wall,
//! panel and fitting is made of. [`super::chamber`] assembles the chamber
//! from these and [`super::fittings`] lines its side walls with them; both
//! take them from here so that neither depends on the other.

use glam::Vec3;

/// Floor height (below the soil surface).
pub const FLOOR_Y: f32 = -0.2;
/// Chamber ceiling height.
pub const CEILING_Y: f32 = 1.28;
/// Back wall z.
pub const BACK_Z: f32 = -0.9;
/// Half width of the chamber (side panels at x = ±this).
pub const HALF_WIDTH: f32 = 0.47;
/// Front end of the side panels (toward the camera).
pub const FRONT_Z: f32 = 3.4;

/// What a chamber surface looks like.
#[derive(Debug, Clone, Copy)]
pub enum Finish {
    /// Emits this radiance (an area light).
    Emitter([f32; 3]),
    /// Diffuse with this albedo, lit by the chamber's ambient radiance.
    Matte([f32; 3]),
}

/// An axis-aligned rectangle.
#[derive(Debug, Clone, Copy)]
pub struct Rect {
    /// Axis of the normal (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Plane coordinate along `axis`.
    pub at: f32,
    /// Bounds along the other two axes, in increasing axis order.
    pub lo: [f32; 2],
    /// Upper bounds matching `lo`.
    pub hi: [f32; 2],
    /// Sign of the side that faces into the chamber (+1 or -1).
    pub facing: f32,
    /// Surface finish.
    pub finish: Finish,
}

impl Rect {
    fn others(&self) -> (usize, usize) {
        match self.axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        }
    }

    /// Unit normal facing into the chamber.
    pub fn normal(&self) -> Vec3 {
        let mut n = Vec3::ZERO;
        n[self.axis] = self.facing;
        n
    }

    /// Area.
    pub fn area(&self) -> f32 {
        (self.hi[0] - self.lo[0]) * (self.hi[1] - self.lo[1])
    }

    /// Distance to the rectangle along a unit ray, hitting its front side only.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3) -> Option<f32> {
        let dn = d[self.axis];
        if dn * self.facing >= 0.0 {
            return None;
        }
        let t = (self.at - o[self.axis]) / dn;
        if t <= 1e-4 {
            return None;
        }
        let (a, b) = self.others();
        let pa = o[a] + t * d[a];
        let pb = o[b] + t * d[b];
        (pa >= self.lo[0] && pa <= self.hi[0] && pb >= self.lo[1] && pb <= self.hi[1]).then_some(t)
    }

    /// Point at fractions `(u, v)` of the rectangle.
    pub fn point(&self, u: f32, v: f32) -> Vec3 {
        let (a, b) = self.others();
        let mut p = Vec3::ZERO;
        p[self.axis] = self.at;
        p[a] = self.lo[0] + u * (self.hi[0] - self.lo[0]);
        p[b] = self.lo[1] + v * (self.hi[1] - self.lo[1]);
        p
    }
}
