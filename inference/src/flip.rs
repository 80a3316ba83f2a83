//! Test-time flip: each tile is also run mirrored left to right, and the two
//! outputs are averaged, so that a centre or an offset the model gets wrong
//! on one side of a leaf is outvoted by its mirror image.

use ndarray::{s, Array4, Axis};

use crate::stitch::TileOutputs;

/// The batch mirrored along its width.
pub fn mirrored(batch: &Array4<f32>) -> Array4<f32> {
    // Copied into standard layout: ONNX Runtime takes contiguous tensors only.
    let mut out = Array4::zeros(batch.raw_dim());
    out.assign(&batch.slice(s![.., .., .., ..;-1]));
    out
}

/// Averages `out` with `mirror`, the outputs for the mirrored batch, after
/// mirroring those back (their x offsets change sign).
pub fn average_with_mirror(out: &mut TileOutputs, mirror: &TileOutputs) {
    let back = mirrored;
    out.semantic = (&out.semantic + &back(&mirror.semantic)) * 0.5;
    out.center = (&out.center + &back(&mirror.center)) * 0.5;
    let mut off = back(&mirror.offset);
    off.index_axis_mut(Axis(1), 1).mapv_inplace(|dx| -dx);
    out.offset = (&out.offset + &off) * 0.5;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mirror_symmetric_prediction_survives_averaging() {
        // A model that sees the mirrored tile and answers with the mirrored
        // truth: averaging must give the truth back exactly.
        let mut truth = TileOutputs {
            semantic: Array4::from_shape_fn((1, 4, 2, 3), |(_, c, y, x)| (c * 10 + y * 3 + x) as f32),
            center: Array4::from_shape_fn((1, 1, 2, 3), |(_, _, y, x)| (y * 3 + x) as f32),
            offset: Array4::from_shape_fn((1, 2, 2, 3), |(_, c, y, x)| (c as f32 + 1.0) * (y + x) as f32),
        };
        let expect = truth.clone();
        let mut mirror = TileOutputs {
            semantic: mirrored(&truth.semantic),
            center: mirrored(&truth.center),
            offset: mirrored(&truth.offset),
        };
        mirror.offset.index_axis_mut(Axis(1), 1).mapv_inplace(|dx| -dx);
        average_with_mirror(&mut truth, &mirror);
        assert_eq!(truth.semantic, expect.semantic);
        assert_eq!(truth.center, expect.center);
        assert_eq!(truth.offset, expect.offset);
    }
}
