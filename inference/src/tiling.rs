//! Bringing an image to the contract's scale and cutting it into model tiles.
//!
//! The model was trained on plants seen at one pixels-per-metre; this module
//! resizes every input to that scale (the contract's scale rule), crops the
//! plant's region, and lays out overlapping tiles over that crop (the
//! "canvas"). Tile origins are multiples of the output stride so that every
//! tile's output grid lines up with the canvas's.

use fast_image_resize as fr;
use image::RgbImage;
use ndarray::Array4;
use phyllo_contract::Contract;

use crate::region::{median_colour, plant_bbox, RegionMode};

/// Scale factor (model pixels per original pixel) for an image of `w` x `h`.
///
/// Camera frames, recognised by their aspect ratio and a height of at least
/// the contract's frame height (some crops happen to have the frame's
/// aspect), are resized to the contract's frame height, whatever the
/// camera's resolution; anything else
/// is taken as a facility crop (cut from a half-size frame) and resized by the
/// contract's crop factor, so a plant is as large as it is in frames.
pub fn scale_for(contract: &Contract, w: u32, h: u32) -> f32 {
    let spec = &contract.input;
    if is_frame(contract, w, h) {
        spec.frame_height as f32 / h as f32
    } else {
        spec.crop_scale
    }
}

/// Whether an image of `w` x `h` is a whole camera frame (the frame's aspect
/// ratio, at least the contract's frame height) rather than a crop.
pub fn is_frame(contract: &Contract, w: u32, h: u32) -> bool {
    let spec = &contract.input;
    let aspect = w as f32 / h as f32;
    (aspect / spec.frame_aspect - 1.0).abs() <= spec.frame_aspect_tolerance && h >= spec.frame_height
}

/// Resizes `img` by `scale` with a bilinear filter (SIMD, via fast_image_resize).
pub fn resize(img: &RgbImage, scale: f32) -> RgbImage {
    let (w, h) = img.dimensions();
    let nw = ((w as f32 * scale).round() as u32).max(1);
    let nh = ((h as f32 * scale).round() as u32).max(1);
    if (nw, nh) == (w, h) {
        return img.clone();
    }
    let src = fr::images::ImageRef::new(w, h, img.as_raw(), fr::PixelType::U8x3)
        .expect("an RgbImage buffer is w*h*3 bytes");
    let mut dst = fr::images::Image::new(nw, nh, fr::PixelType::U8x3);
    let options = fr::ResizeOptions::new().resize_alg(fr::ResizeAlg::Convolution(fr::FilterType::Bilinear));
    fr::Resizer::new()
        .resize(&src, &mut dst, &options)
        .expect("pixel types match");
    RgbImage::from_raw(nw, nh, dst.into_vec()).expect("resizer output is nw*nh*3 bytes")
}

/// The canvas the tiles are cut from, and how to map it back.
#[derive(Debug, Clone)]
pub struct Canvas {
    /// Pixels at model scale, padded to at least one tile per side and to a
    /// multiple of the output stride.
    pub image: RgbImage,
    /// Model pixels per original pixel.
    pub scale: f32,
    /// Position of the canvas's top-left pixel in the scaled image (negative
    /// where the canvas is padded beyond the image).
    pub origin: [i64; 2],
    /// Plant region in original-image pixels `[x0, y0, x1, y1]`.
    pub region: [u32; 4],
    /// Plant region in canvas pixels `[x0, y0, x1, y1]` when it is known (a
    /// plant was found by colour, or a fixed region was given); instances
    /// centred outside it are chamber, not plant.
    pub plant: Option<[i64; 4]>,
    /// Top-left corners of the tiles, in canvas pixels.
    pub tiles: Vec<[u32; 2]>,
}

impl Canvas {
    /// Maps a canvas position (model pixels) to original-image pixels.
    pub fn to_original(&self, x: f32, y: f32) -> [f32; 2] {
        [
            (x + self.origin[0] as f32) / self.scale,
            (y + self.origin[1] as f32) / self.scale,
        ]
    }
}

/// Scales `img` (by `scale`, or by the contract's rule when `None`), chooses
/// the region to look at and lays out the tiles.
pub fn prepare(contract: &Contract, img: &RgbImage, mode: RegionMode, scale: Option<f32>) -> Canvas {
    let tile = contract.input.tile;
    let stride = contract.outputs.stride;
    let scale = scale.unwrap_or_else(|| scale_for(contract, img.width(), img.height()));
    let scaled = resize(img, scale);
    let (sw, sh) = scaled.dimensions();

    // The region in scaled pixels, and whether it really bounds the plant.
    let whole = [0, 0, sw, sh];
    let (known, [rx0, ry0, rx1, ry1]) = match mode {
        RegionMode::Full => (false, whole),
        RegionMode::Fixed { x0, y0, x1, y1 } => {
            let s = |v: u32, max: u32| ((v as f32 * scale).round() as u32).min(max);
            let (a, b, c, d) = (s(x0, sw), s(y0, sh), s(x1, sw), s(y1, sh));
            if c > a && d > b {
                (true, [a, b, c, d])
            } else {
                (false, whole)
            }
        }
        RegionMode::Auto => match plant_bbox(&scaled, 0.02, 12, 40) {
            Some(b) => (true, b),
            None => (false, whole),
        },
    };

    // Grow the region to at least one tile per side, centred on the plant,
    // then round up to the stride; beyond the image the canvas is padded.
    let span = |lo: u32, hi: u32, len: u32| -> (i64, u32) {
        let want = (hi - lo).max(tile);
        let want = want.div_ceil(stride) * stride;
        let centre = (i64::from(lo) + i64::from(hi)) / 2;
        let mut start = centre - i64::from(want) / 2;
        // Prefer real pixels over padding where the image is big enough.
        if i64::from(len) >= i64::from(want) {
            start = start.clamp(0, i64::from(len - want));
        } else {
            start = -(i64::from(want - len) / 2);
        }
        (start, want)
    };
    let (ox, cw) = span(rx0, rx1, sw);
    let (oy, ch) = span(ry0, ry1, sh);
    // Padding shows the chamber wall, as around every training plant. The
    // image border is no stand-in: the facility's crops are cut at the
    // chamber's dark side profiles, and on 22 of the 60 dev crops the
    // border's median was a dark brown frame around a white box.
    let fill = image::Rgb(median_colour(&scaled));
    let mut canvas = RgbImage::from_pixel(cw, ch, fill);
    for y in 0..ch {
        let sy = i64::from(y) + oy;
        if sy < 0 || sy >= i64::from(sh) {
            continue;
        }
        for x in 0..cw {
            let sx = i64::from(x) + ox;
            if sx >= 0 && sx < i64::from(sw) {
                canvas.put_pixel(x, y, *scaled.get_pixel(sx as u32, sy as u32));
            }
        }
    }
    let xs = tile_starts(cw, tile, contract.input.tile_overlap, stride);
    let ys = tile_starts(ch, tile, contract.input.tile_overlap, stride);
    let tiles = ys.iter().flat_map(|&y| xs.iter().map(move |&x| [x, y])).collect();
    let to_orig = |v: u32, len: u32| ((v as f32 / scale).round() as u32).min(len);
    let region = [
        to_orig(rx0, img.width()),
        to_orig(ry0, img.height()),
        to_orig(rx1, img.width()),
        to_orig(ry1, img.height()),
    ];
    let plant = known.then(|| {
        [
            i64::from(rx0) - ox,
            i64::from(ry0) - oy,
            i64::from(rx1) - ox,
            i64::from(ry1) - oy,
        ]
    });
    Canvas {
        image: canvas,
        scale,
        origin: [ox, oy],
        region,
        plant,
        tiles,
    }
}

/// Evenly spaced tile starts covering `len` with at least `overlap` between
/// neighbours, each a multiple of `stride`.
pub fn tile_starts(len: u32, tile: u32, overlap: u32, stride: u32) -> Vec<u32> {
    if len <= tile {
        return vec![0];
    }
    let step = tile - overlap;
    let n = (len - tile).div_ceil(step) + 1;
    let last = len - tile;
    (0..n)
        .map(|i| {
            let s = (u64::from(last) * u64::from(i) / u64::from(n - 1)) as u32;
            (s / stride * stride).min(last / stride * stride)
        })
        .collect()
}

/// Fills an NCHW batch with the given tiles, normalised per the contract.
pub fn batch_tensor(contract: &Contract, canvas: &RgbImage, tiles: &[[u32; 2]]) -> Array4<f32> {
    let t = contract.input.tile as usize;
    let spec = &contract.input;
    let lo = spec.value_range[0];
    let span = spec.value_range[1] - spec.value_range[0];
    // A lookup table per channel: 768 floats instead of 3 divisions per pixel.
    let lut: Vec<[f32; 256]> = (0..3)
        .map(|c| {
            let mut l = [0f32; 256];
            for (v, out) in l.iter_mut().enumerate() {
                *out = (lo + span * v as f32 / 255.0 - spec.mean[c]) / spec.std[c];
            }
            l
        })
        .collect();
    let mut batch = Array4::<f32>::zeros((tiles.len(), 3, t, t));
    let cw = canvas.width() as usize;
    let raw = canvas.as_raw();
    for (n, &[tx, ty]) in tiles.iter().enumerate() {
        for c in 0..3 {
            let mut plane = batch.slice_mut(ndarray::s![n, c, .., ..]);
            let plane = plane.as_slice_mut().expect("fresh array is contiguous");
            for y in 0..t {
                let row = ((ty as usize + y) * cw + tx as usize) * 3;
                let src = &raw[row..row + t * 3];
                let dst = &mut plane[y * t..(y + 1) * t];
                for (x, d) in dst.iter_mut().enumerate() {
                    *d = lut[c][src[x * 3 + c] as usize];
                }
            }
        }
    }
    batch
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_starts_cover_with_overlap_on_stride() {
        assert_eq!(tile_starts(512, 512, 128, 2), vec![0]);
        assert_eq!(tile_starts(300, 512, 128, 2), vec![0]);
        let s = tile_starts(1300, 512, 128, 2);
        assert_eq!(*s.first().unwrap(), 0);
        assert_eq!(*s.last().unwrap() + 512, 1300);
        for w in s.windows(2) {
            assert!(w[0] + 512 >= w[1] + 128, "{s:?}");
        }
        assert!(s.iter().all(|v| v % 2 == 0));
    }

    #[test]
    fn frames_and_crops_get_the_contract_scale() {
        let c = Contract::embedded();
        assert!((scale_for(c, 2454, 2056) - 0.25).abs() < 1e-6);
        assert!((scale_for(c, 1227, 1028) - 0.5).abs() < 1e-6);
        assert_eq!(scale_for(c, 614, 514), 1.0);
        assert_eq!(scale_for(c, 225, 198), 0.5);
        // A crop that happens to have the frame's aspect is still a crop.
        assert_eq!(scale_for(c, 473, 401), 0.5);
    }

    #[test]
    fn canvas_maps_back_to_original_pixels() {
        let c = Contract::embedded();
        let mut img = RgbImage::from_pixel(2454, 2056, image::Rgb([235, 232, 230]));
        for y in 800..1600 {
            for x in 1000..1200 {
                img.put_pixel(x, y, image::Rgb([50, 120, 40]));
            }
        }
        let canvas = prepare(c, &img, RegionMode::Auto, None);
        assert_eq!(canvas.image.width() % 2, 0);
        assert!(canvas.image.width() >= 512 && canvas.image.height() >= 512);
        let [x0, y0, x1, y1] = canvas.region;
        assert!(
            x0 <= 1000 && x1 >= 1200 && y0 <= 800 && y1 >= 1600,
            "{:?}",
            canvas.region
        );
        let [ox, oy] = canvas.to_original(0.0, 0.0);
        assert!(ox >= 0.0 && oy >= 0.0);
        let batch = batch_tensor(c, &canvas.image, &canvas.tiles);
        assert_eq!(batch.shape(), &[canvas.tiles.len(), 3, 512, 512]);
    }

    #[test]
    fn a_crop_cut_at_dark_profiles_is_padded_with_the_wall() {
        // The facility's crops often keep a few columns of the chamber's dark
        // side profiles at both edges: more than half of the border is dark.
        let c = Contract::embedded();
        let wall = image::Rgb([236, 233, 222]);
        let mut img = RgbImage::from_pixel(490, 560, wall);
        for y in 0..560 {
            for x in (0..6).chain(484..490) {
                img.put_pixel(x, y, image::Rgb([35, 28, 20]));
            }
        }
        for y in 150..500 {
            for x in 240..250 {
                img.put_pixel(x, y, image::Rgb([60, 110, 40]));
            }
        }
        let canvas = prepare(c, &img, RegionMode::Auto, None);
        assert!(
            canvas.origin[0] < 0 && canvas.origin[1] < 0,
            "the half-size crop is padded"
        );
        let corner = canvas.image.get_pixel(0, 0).0;
        assert!(
            corner.iter().zip(wall.0).all(|(a, b)| a.abs_diff(b) <= 2),
            "padding {corner:?}, wall {wall:?}"
        );
    }
}
