//! Ray–plant intersection: an obvhs compressed-wide BVH (CWBVH) over the
//! plant and its pot. Triangles are stored in BVH leaf order (each slot is
//! `primitive_indices[slot]` of the input), so a hit's `primitive_id` maps
//! straight to its triangle and semantics.
//!
//! obvhs 0.4's `Triangle::intersect_embree` returns wrong hits; this module
//! only uses `Triangle::intersect`.

use crate::mesh::{Mesh, TriInfo};
use glam::{Vec3, Vec3A};
use obvhs::{
    cwbvh::{builder::build_cwbvh_from_tris, CwBvh},
    ray::{Ray, RayHit},
    triangle::Triangle,
    BvhBuildParams,
};
use std::time::Duration;

/// A closest hit.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Geometric normal (unit, not flipped toward the ray).
    pub normal: Vec3,
    /// Semantics of the triangle hit.
    pub info: TriInfo,
}

/// BVH over a mesh, with triangles and semantics in BVH order.
pub struct Accel {
    bvh: Option<CwBvh>,
    tris: Vec<Triangle>,
    normals: Vec<Vec3>,
    info: Vec<TriInfo>,
}

impl Accel {
    /// Builds the BVH. An empty mesh gives an accelerator that never hits.
    pub fn build(mesh: &Mesh) -> Self {
        let tris: Vec<Triangle> = mesh
            .tris
            .iter()
            .map(|t| Triangle {
                v0: Vec3A::from(mesh.positions[t[0] as usize]),
                v1: Vec3A::from(mesh.positions[t[1] as usize]),
                v2: Vec3A::from(mesh.positions[t[2] as usize]),
            })
            .collect();
        if tris.is_empty() {
            return Accel {
                bvh: None,
                tris,
                normals: Vec::new(),
                info: Vec::new(),
            };
        }
        let bvh = build_cwbvh_from_tris(&tris, BvhBuildParams::fast_build(), &mut Duration::default());
        let order: Vec<usize> = bvh.primitive_indices.iter().map(|&i| i as usize).collect();
        let tris: Vec<Triangle> = order.iter().map(|&i| tris[i]).collect();
        let normals = tris.iter().map(|t| Vec3::from(t.compute_normal())).collect();
        let info = order.iter().map(|&i| mesh.info[i]).collect();
        Accel {
            bvh: Some(bvh),
            tris,
            normals,
            info,
        }
    }

    /// Number of triangles (after any splitting).
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether there is nothing to hit.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Closest hit along `dir` (unit) within `(0, tmax)`.
    #[inline]
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let ray = Ray::new(origin.into(), dir.into(), 0.0, tmax);
        let mut hit = RayHit::none();
        if bvh.ray_traverse(ray, &mut hit, |r, slot| self.tris[slot].intersect(r)) {
            let slot = hit.primitive_id as usize;
            Some(Hit {
                t: hit.t,
                normal: self.normals[slot],
                info: self.info[slot],
            })
        } else {
            None
        }
    }

    /// Whether anything blocks the segment from `origin` along `dir` up to `tmax`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let ray = Ray::new(origin.into(), dir.into(), 0.0, tmax);
        !bvh.ray_traverse_miss(ray, |r, slot| self.tris[slot].intersect(r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriInfo;

    #[test]
    fn hits_the_right_triangle() {
        let mut m = Mesh::default();
        for (k, z) in [0.0f32, -1.0, 1.0].iter().enumerate() {
            let a = m.vertex(Vec3::new(-1.0, -1.0, *z));
            let b = m.vertex(Vec3::new(1.0, -1.0, *z));
            let c = m.vertex(Vec3::new(0.0, 1.0, *z));
            m.tri(
                a,
                b,
                c,
                TriInfo {
                    class: 1,
                    instance: k as u16 + 1,
                    material: 0,
                    senescence: 0.0,
                },
            );
        }
        let acc = Accel::build(&m);
        let h = acc
            .closest(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, f32::INFINITY)
            .unwrap();
        assert_eq!(h.info.instance, 3);
        assert!((h.t - 4.0).abs() < 1e-4);
        let h = acc
            .closest(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, f32::INFINITY)
            .unwrap();
        assert_eq!(h.info.instance, 2);
        assert!(acc.occluded(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 10.0));
        assert!(!acc.occluded(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 3.0));
    }
}
