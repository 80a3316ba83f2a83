//! Stitching per-tile model outputs into one canvas.
//!
//! Tiles overlap; each output pixel is taken from the tile in which it lies
//! farthest from a tile border that is interior to the canvas (where a model
//! sees least context). Offsets are relative (pixel → centre), so they need no
//! shifting, and post-processing then runs once over the whole canvas: a leaf
//! that crosses tile borders is one instance because its pixels all point at
//! one centre, not because tile instances were matched up afterwards.

use ndarray::{s, Array2, Array4};

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
    /// `[n, 1, t, t]` leaf-tip heatmap, for models with a tip output.
    pub tip: Option<Array4<f32>>,
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
        match (&mut self.tip, other.tip) {
            (Some(tip), Some(other)) => tip
                .append(ndarray::Axis(0), other.view())
                .expect("same tile shape"),
            (None, None) => {}
            _ => panic!("batches of one model either all have a tip output or none does"),
        }
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
    if outputs.tip.is_some() {
        out.tip = Some(Array2::zeros((h, w)));
    }
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
    // Tips follow the same ownership as the centre heatmap: a tip near a tile
    // border is taken from the tile that saw it with most context.
    if let (Some(src), Some(dst)) = (&outputs.tip, out.tip.as_mut()) {
        copy_plane(
            src,
            0,
            &owner,
            dst.as_slice_mut().expect("fresh array is contiguous"),
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
    let tip = full.tip.as_ref().map(|tip| {
        tip.slice(s![oy..oy + t, ox..ox + t])
            .to_owned()
            .insert_axis(ndarray::Axis(0))
            .insert_axis(ndarray::Axis(0))
    });
    TileOutputs {
        semantic: sem.insert_axis(ndarray::Axis(0)),
        center: cen.insert_axis(ndarray::Axis(0)).insert_axis(ndarray::Axis(0)),
        offset: off.insert_axis(ndarray::Axis(0)),
        tip,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Array3, Axis};

    /// A 20x12 canvas at stride 2 (10x6 output pixels) cut into 8x8 tiles
    /// (4x4 output pixels) that overlap.
    const TILES: [[u32; 2]; 6] = [[0, 0], [6, 0], [12, 0], [0, 4], [6, 4], [12, 4]];

    fn full(with_tip: bool) -> RawOutputs {
        let (h, w) = (6, 10);
        let mut out = RawOutputs::zeros(h, w);
        out.semantic =
            Array3::from_shape_fn(out.semantic.raw_dim(), |(c, y, x)| (c * 100 + y * w + x) as f32);
        out.center = Array2::from_shape_fn((h, w), |(y, x)| (y * w + x) as f32 / 100.0);
        out.offset = Array3::from_shape_fn((2, h, w), |(c, y, x)| c as f32 - (y + x) as f32);
        out.tip =
            with_tip.then(|| Array2::from_shape_fn((h, w), |(y, x)| ((y * 3 + x * 7) % 11) as f32 / 10.0));
        out
    }

    fn cut_all(full: &RawOutputs) -> TileOutputs {
        let mut outs = cut_tile(full, TILES[0][0], TILES[0][1], 2, 4);
        for &[tx, ty] in &TILES[1..] {
            outs.append(cut_tile(full, tx, ty, 2, 4));
        }
        outs
    }

    #[test]
    fn consistent_tiles_stitch_back_to_the_canvas_with_or_without_tips() {
        for with_tip in [false, true] {
            let full = full(with_tip);
            let outs = cut_all(&full);
            assert_eq!(outs.len(), TILES.len());
            assert_eq!(
                outs.tip.as_ref().map(|t| t.dim()),
                with_tip.then_some((6, 1, 4, 4))
            );
            let back = stitch(&outs, &TILES, 20, 12, 2);
            assert_eq!(back.semantic, full.semantic);
            assert_eq!(back.center, full.center);
            assert_eq!(back.offset, full.offset);
            assert_eq!(back.tip, full.tip);
        }
    }

    #[test]
    fn the_tip_map_takes_each_pixel_from_the_centre_heatmaps_tile() {
        // Tiles that disagree: every plane of tile k holds k. The stitched tip
        // map must name the same owner as the stitched centre heatmap.
        let mut outs = cut_all(&full(true));
        for (k, mut c) in outs.center.axis_iter_mut(Axis(0)).enumerate() {
            c.fill(k as f32);
        }
        for (k, mut c) in outs.tip.as_mut().unwrap().axis_iter_mut(Axis(0)).enumerate() {
            c.fill(k as f32);
        }
        let back = stitch(&outs, &TILES, 20, 12, 2);
        let owners = &back.center;
        assert!(owners.iter().any(|&k| k > 0.0), "several tiles own pixels");
        assert_eq!(back.tip.as_ref(), Some(owners));
    }
}
