//! Stitching per-tile model outputs into one canvas.
//!
//! Tiles overlap; each output pixel is taken from the tile in which it lies
//! farthest from a tile border that is interior to the canvas (where a model
//! sees least context). Offsets are relative (pixel → centre), so they need no
//! shifting, and post-processing then runs once over the whole canvas: a leaf
//! that crosses tile borders is one instance because its pixels all point at
//! one centre, not because tile instances were matched up afterwards.

use ndarray::{s, Array4};

use crate::postprocess::RawOutputs;

/// Model outputs for a batch of tiles, as returned by ONNX Runtime.
#[derive(Debug, Clone)]
pub struct TileOutputs {
    /// `[n, classes, t, t]` semantic logits.
    pub semantic: Array4<f32>,
    /// `[n, 1, t, t]` centre heatmap.
    pub center: Array4<f32>,
    /// `[n, 2, t, t]` offsets.
    pub offset: Array4<f32>,
}

impl TileOutputs {
    /// Appends another batch's outputs.
    pub fn append(&mut self, other: TileOutputs) {
        self.semantic
            .append(ndarray::Axis(0), other.semantic.view())
            .expect("same tile shape");
        self.center
            .append(ndarray::Axis(0), other.center.view())
            .expect("same tile shape");
        self.offset
            .append(ndarray::Axis(0), other.offset.view())
            .expect("same tile shape");
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.center.dim().0
    }

    /// Whether there are no tiles.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Stitches `outputs` of tiles whose top-left corners are `tiles` (canvas
/// pixels) into a canvas of `canvas_w` x `canvas_h` canvas pixels.
pub fn stitch(
    outputs: &TileOutputs,
    tiles: &[[u32; 2]],
    canvas_w: u32,
    canvas_h: u32,
    stride: u32,
) -> RawOutputs {
    let (n, classes, t, t2) = outputs.semantic.dim();
    assert_eq!(n, tiles.len(), "one output per tile");
    assert_eq!(t, t2, "square tiles");
    let (w, h) = ((canvas_w / stride) as usize, (canvas_h / stride) as usize);
    let mut out = RawOutputs::zeros(h, w);
    debug_assert_eq!(classes, out.semantic.dim().0);
    let mut best = vec![-1i64; h * w];
    // Which tile owns each canvas pixel: the one where it is farthest from an
    // interior tile border.
    let mut owner = vec![(u32::MAX, 0u32, 0u32); h * w];
    for (k, &[tx, ty]) in tiles.iter().enumerate() {
        let (ox, oy) = ((tx / stride) as usize, (ty / stride) as usize);
        let far = i64::MAX;
        for i in 0..t.min(h - oy) {
            let top = if oy > 0 { i as i64 } else { far };
            let bottom = if oy + t < h { (t - 1 - i) as i64 } else { far };
            for j in 0..t.min(w - ox) {
                let left = if ox > 0 { j as i64 } else { far };
                let right = if ox + t < w { (t - 1 - j) as i64 } else { far };
                let margin = top.min(bottom).min(left).min(right);
                let g = (oy + i) * w + ox + j;
                if margin > best[g] {
                    best[g] = margin;
                    owner[g] = (k as u32, i as u32, j as u32);
                }
            }
        }
    }
    // Copy plane by plane over contiguous slices: indexing four ndarray
    // dimensions per pixel costs more than the post-processing itself.
    for c in 0..classes {
        let mut plane = out.semantic.index_axis_mut(ndarray::Axis(0), c);
        copy_plane(
            &outputs.semantic,
            c,
            &owner,
            plane.as_slice_mut().expect("fresh array is contiguous"),
        );
    }
    copy_plane(
        &outputs.center,
        0,
        &owner,
        out.center.as_slice_mut().expect("fresh array is contiguous"),
    );
    for c in 0..2 {
        let mut plane = out.offset.index_axis_mut(ndarray::Axis(0), c);
        copy_plane(
            &outputs.offset,
            c,
            &owner,
            plane.as_slice_mut().expect("fresh array is contiguous"),
        );
    }
    out
}

/// Copies channel `c` of the owning tile into each canvas pixel of `dst`.
fn copy_plane(src: &Array4<f32>, c: usize, owner: &[(u32, u32, u32)], dst: &mut [f32]) {
    let (_, channels, t, _) = src.dim();
    let std = src.as_standard_layout();
    let data = std.as_slice().expect("standard layout");
    for (d, &(k, i, j)) in dst.iter_mut().zip(owner) {
        if k != u32::MAX {
            *d = data[((k as usize * channels + c) * t + i as usize) * t + j as usize];
        }
    }
}

/// Cuts the tile at `[tx, ty]` (canvas pixels) out of canvas-wide outputs:
/// what a perfect model would have produced for that tile. Used by the oracle
/// tests and the benchmark's post-processing stage.
pub fn cut_tile(full: &RawOutputs, tx: u32, ty: u32, stride: u32, t: usize) -> TileOutputs {
    let (ox, oy) = ((tx / stride) as usize, (ty / stride) as usize);
    let sem = full.semantic.slice(s![.., oy..oy + t, ox..ox + t]).to_owned();
    let cen = full.center.slice(s![oy..oy + t, ox..ox + t]).to_owned();
    let off = full.offset.slice(s![.., oy..oy + t, ox..ox + t]).to_owned();
    TileOutputs {
        semantic: sem.insert_axis(ndarray::Axis(0)),
        center: cen.insert_axis(ndarray::Axis(0)).insert_axis(ndarray::Axis(0)),
        offset: off.insert_axis(ndarray::Axis(0)),
    }
}
