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
    match (out.tip.as_mut(), &mirror.tip) {
        (Some(tip), Some(m)) => *tip = (&*tip + &back(m)) * 0.5,
        (None, None) => {}
        _ => panic!("both runs of one model either have a tip output or neither does"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model that sees the mirrored tile and answers with the mirrored
    /// truth (x offsets negated).
    fn mirror_of(truth: &TileOutputs) -> TileOutputs {
        let mut mirror = TileOutputs {
            semantic: mirrored(&truth.semantic),
            center: mirrored(&truth.center),
            offset: mirrored(&truth.offset),
            tip: truth.tip.as_ref().map(mirrored),
        };
        mirror.offset.index_axis_mut(Axis(1), 1).mapv_inplace(|dx| -dx);
        mirror
    }

    fn truth(tip: bool) -> TileOutputs {
        TileOutputs {
            semantic: Array4::from_shape_fn((1, 4, 2, 3), |(_, c, y, x)| (c * 10 + y * 3 + x) as f32),
            center: Array4::from_shape_fn((1, 1, 2, 3), |(_, _, y, x)| (y * 3 + x) as f32),
            offset: Array4::from_shape_fn((1, 2, 2, 3), |(_, c, y, x)| (c as f32 + 1.0) * (y + x) as f32),
            tip: tip.then(|| Array4::from_shape_fn((1, 1, 2, 3), |(_, _, y, x)| (y * 7 + x * x) as f32)),
        }
    }

    #[test]
    fn a_mirror_symmetric_prediction_survives_averaging() {
        // Averaging must give the truth back exactly, tip map or not.
        for with_tip in [false, true] {
            let mut out = truth(with_tip);
            let expect = out.clone();
            let mirror = mirror_of(&out);
            average_with_mirror(&mut out, &mirror);
            assert_eq!(out.semantic, expect.semantic);
            assert_eq!(out.center, expect.center);
            assert_eq!(out.offset, expect.offset);
            assert_eq!(out.tip, expect.tip);
        }
    }

    #[test]
    fn the_tip_map_is_averaged_with_its_mirror_image() {
        let mut out = truth(true);
        let mut mirror = mirror_of(&out);
        // The mirrored run sees a tip at its (0, 0): the original's (0, 2).
        mirror.tip = Some(Array4::zeros((1, 1, 2, 3)));
        mirror.tip.as_mut().unwrap()[[0, 0, 0, 0]] = 1.0;
        let before = out.tip.clone().unwrap();
        average_with_mirror(&mut out, &mirror);
        let tip = out.tip.unwrap();
        assert_eq!(tip[[0, 0, 0, 2]], (before[[0, 0, 0, 2]] + 1.0) * 0.5);
        assert_eq!(tip[[0, 0, 0, 0]], before[[0, 0, 0, 0]] * 0.5);
    }
}
