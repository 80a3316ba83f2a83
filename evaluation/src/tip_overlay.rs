//! Overlays for real frames with marked tips: the model's leaves as `phyllo
//! count --overlay` draws them, every marked tip ringed by its fate (white:
//! a leaf of its own, yellow: sharing a leaf, red: reached by no leaf) and a
//! red cross on the centre of every extra leaf (one reaching no tip).

use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_hollow_circle_mut, draw_line_segment_mut};
use phyllo_inference::Instance;

use super::tip_errors::{TipFate, TipMatch};

const OWN: Rgb<u8> = Rgb([255, 255, 255]);
const SHARING: Rgb<u8> = Rgb([255, 220, 0]);
const MISSED: Rgb<u8> = Rgb([255, 0, 0]);

/// Draws `m`'s tips (`tips[i]` has fate `m.fates[i]`) and extra leaves
/// (centres from `instances`) onto `img`, an overlay of the same image.
pub fn draw(img: &mut RgbImage, tips: &[[f32; 2]], m: &TipMatch, instances: &[Instance]) {
    // Rings a little wider than a leaf at frame scale, thick enough to see
    // on a halved screenshot.
    let r = (img.width().max(img.height()) / 100).max(6) as i32;
    for (tip, fate) in tips.iter().zip(&m.fates) {
        let colour = match fate {
            TipFate::OwnLeaf(_) => OWN,
            TipFate::Sharing(_) => SHARING,
            TipFate::Unreached => MISSED,
        };
        let centre = (tip[0].round() as i32, tip[1].round() as i32);
        for k in 0..3 {
            draw_hollow_circle_mut(img, centre, r + k, colour);
        }
    }
    for (id, _) in &m.extras {
        let Some(leaf) = instances.iter().find(|i| i.id == *id) else {
            continue;
        };
        let [x, y] = leaf.centre;
        let a = r as f32;
        for d in [-1.0, 0.0, 1.0] {
            draw_line_segment_mut(img, (x - a + d, y - a), (x + a + d, y + a), MISSED);
            draw_line_segment_mut(img, (x - a + d, y + a), (x + a + d, y - a), MISSED);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segmentation::PixelMap;
    use phyllo_contract::LEAF;

    #[test]
    fn rings_tips_by_fate_and_crosses_extra_leaves() {
        // Leaf 1 on the left reaches the tip; leaf 2 on the right reaches none.
        let (w, h) = (60usize, 40usize);
        let mut pred = PixelMap {
            width: w,
            height: h,
            class: vec![0; w * h],
            instance: vec![0; w * h],
        };
        for y in 10..30 {
            for x in (5..15).chain(40..50) {
                pred.class[y * w + x] = LEAF;
                pred.instance[y * w + x] = if x < 20 { 1 } else { 2 };
            }
        }
        let tips = [[10.0, 20.0], [30.0, 5.0]];
        let m = TipMatch::of(&tips, &pred, 3.0);
        let leaf = |id, cx: f32| Instance {
            id,
            class: LEAF,
            class_name: "leaf".into(),
            area: 200,
            bbox: [0, 0, 1, 1],
            centre: [cx, 20.0],
            score: 1.0,
        };
        let mut img = RgbImage::new(w as u32, h as u32);
        draw(&mut img, &tips, &m, &[leaf(1, 10.0), leaf(2, 45.0)]);
        let r = 6;
        assert_eq!(img.get_pixel(10 + r, 20), &OWN);
        assert_eq!(img.get_pixel(30 + r, 5), &MISSED);
        assert_eq!(m.fates, vec![TipFate::OwnLeaf(1), TipFate::Unreached]);
        // The cross on leaf 2's centre, none on leaf 1's.
        assert_eq!(img.get_pixel(45, 20), &MISSED);
        assert_eq!(img.get_pixel(10, 20), &Rgb([0, 0, 0]));
    }
}
