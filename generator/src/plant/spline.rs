//! Cubic (Catmull–Rom) spline through control points: the leaf skeleton.

use glam::Vec3;

/// A uniform Catmull–Rom spline passing through every control point.
#[derive(Debug, Clone)]
pub struct CatmullRom {
    points: Vec<Vec3>,
}

impl CatmullRom {
    /// Spline through `points` (at least two).
    pub fn new(points: Vec<Vec3>) -> Self {
        assert!(points.len() >= 2, "a spline needs two control points");
        Self { points }
    }

    /// Point at global parameter `t` in `[0, 1]` (0 = first control point).
    pub fn eval(&self, t: f32) -> Vec3 {
        let spans = self.points.len() - 1;
        let x = t.clamp(0.0, 1.0) * spans as f32;
        let i = (x.floor() as usize).min(spans - 1);
        let u = x - i as f32;
        let p = |k: isize| -> Vec3 {
            let n = self.points.len() as isize;
            let k = k.clamp(0, n - 1) as usize;
            self.points[k]
        };
        let i = i as isize;
        // End tangents: mirror the neighbour so the curve starts along its first chord.
        let p0 = if i == 0 { 2.0 * p(0) - p(1) } else { p(i - 1) };
        let p1 = p(i);
        let p2 = p(i + 1);
        let p3 = if i + 2 >= self.points.len() as isize {
            2.0 * p2 - p1
        } else {
            p(i + 2)
        };
        let u2 = u * u;
        let u3 = u2 * u;
        0.5 * ((2.0 * p1)
            + (p2 - p0) * u
            + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * u2
            + (3.0 * p1 - p0 - 3.0 * p2 + p3) * u3)
    }

    /// `n + 1` points evenly spaced in parameter (n segments).
    pub fn sample(&self, n: usize) -> Vec<Vec3> {
        (0..=n).map(|k| self.eval(k as f32 / n as f32)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_through_control_points() {
        let pts = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(3.0, 0.0, 1.0),
        ];
        let s = CatmullRom::new(pts.clone());
        for (k, p) in pts.iter().enumerate() {
            assert!((s.eval(k as f32 / 3.0) - *p).length() < 1e-5);
        }
    }
}
