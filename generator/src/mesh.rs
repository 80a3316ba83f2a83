//! Triangle meshes with per-triangle semantics (label class/instance and
//! material), grouped by part for OBJ export.

use glam::Vec3;
use std::io::Write;

/// What a triangle is: its panoptic label and how it is shaded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriInfo {
    /// Semantic class (contract ids: 0 background, 1 leaf, 2 stem, 3 panicle).
    pub class: u8,
    /// Instance number within the plant (leaves 1.., 0 for stuff).
    pub instance: u16,
    /// Index into the scene's material table.
    pub material: u16,
    /// Local senescence 0 (green) .. 1 (dry), for leaf shading.
    pub senescence: f32,
}

/// A named range of triangles (one leaf, the stem, the pot...).
#[derive(Debug, Clone)]
pub struct Group {
    /// Group name written to OBJ (`leaf_03`, `stem`, ...).
    pub name: String,
    /// First triangle index.
    pub start: usize,
    /// One past the last triangle index.
    pub end: usize,
}

/// An indexed triangle mesh.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices.
    pub tris: Vec<[u32; 3]>,
    /// Per-triangle semantics, parallel to `tris`.
    pub info: Vec<TriInfo>,
    /// Named triangle ranges.
    pub groups: Vec<Group>,
}

impl Mesh {
    /// Starts a named group; triangles added until the next call belong to it.
    pub fn begin_group(&mut self, name: impl Into<String>) {
        let start = self.tris.len();
        if let Some(g) = self.groups.last_mut() {
            g.end = start;
        }
        self.groups.push(Group {
            name: name.into(),
            start,
            end: start,
        });
    }

    /// Closes the current group.
    pub fn end_group(&mut self) {
        let end = self.tris.len();
        if let Some(g) = self.groups.last_mut() {
            g.end = end;
        }
    }

    /// Adds a vertex and returns its index.
    pub fn vertex(&mut self, p: Vec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Adds a triangle, skipping degenerate ones (zero area).
    pub fn tri(&mut self, a: u32, b: u32, c: u32, info: TriInfo) {
        let (pa, pb, pc) = (
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        );
        if (pb - pa).cross(pc - pa).length_squared() <= 1e-16 {
            return;
        }
        self.tris.push([a, b, c]);
        self.info.push(info);
    }

    /// Adds a grid of `rows x cols` vertices (row-major) as quads.
    pub fn grid(&mut self, rows: &[Vec<Vec3>], info: impl Fn(usize) -> TriInfo) {
        if rows.len() < 2 {
            return;
        }
        let cols = rows[0].len();
        let base = self.positions.len() as u32;
        for row in rows {
            debug_assert_eq!(row.len(), cols);
            self.positions.extend_from_slice(row);
        }
        for r in 0..rows.len() - 1 {
            let ti = info(r);
            for c in 0..cols - 1 {
                let i00 = base + (r * cols + c) as u32;
                let i01 = i00 + 1;
                let i10 = i00 + cols as u32;
                let i11 = i10 + 1;
                self.tri(i00, i10, i11, ti);
                self.tri(i00, i11, i01, ti);
            }
        }
    }

    /// Appends another mesh (its groups keep their names).
    pub fn append(&mut self, other: &Mesh) {
        let vbase = self.positions.len() as u32;
        let tbase = self.tris.len();
        self.positions.extend_from_slice(&other.positions);
        self.tris.extend(other.tris.iter().map(|t| t.map(|i| i + vbase)));
        self.info.extend_from_slice(&other.info);
        self.groups.extend(other.groups.iter().map(|g| Group {
            name: g.name.clone(),
            start: g.start + tbase,
            end: g.end + tbase,
        }));
    }

    /// Axis-aligned bounds (min, max); zero box for an empty mesh.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        if self.positions.is_empty() {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        self.positions
            .iter()
            .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            })
    }

    /// Writes Wavefront OBJ, one `g` group per part.
    pub fn write_obj(&self, mut w: impl Write) -> std::io::Result<()> {
        writeln!(
            w,
            "# phyllo-gen plant mesh: {} vertices, {} triangles",
            self.positions.len(),
            self.tris.len()
        )?;
        for p in &self.positions {
            writeln!(w, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z)?;
        }
        for g in &self.groups {
            writeln!(w, "g {}", g.name)?;
            for t in &self.tris[g.start..g.end] {
                writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
            }
        }
        Ok(())
    }
}
