//! Images and file names to drop into a test's drop directory.

use std::io::Cursor;
use std::path::Path;
use std::time::Duration;

/// Images `range` of a stream: (relative name, bytes), spread over `plants`
/// plants named `<prefix>NN`, several days, five side views, unique content
/// each (seeded from `seed + i`).
pub fn image_stream(
    range: std::ops::Range<usize>,
    plants: usize,
    prefix: &str,
    seed: u64,
) -> Vec<(String, Vec<u8>)> {
    range
        .map(|i| {
            let plant = format!("{prefix}{:02}", i % plants);
            let k = i / plants;
            let (day, view) = (1 + (k / 5) as u32, (k % 5) as u32);
            (
                flat_name(&plant, day, view * 7, view * 36),
                small_png(seed + i as u64, 96),
            )
        })
        .collect()
}

/// A flat-layout file name.
pub fn flat_name(plant: &str, day: u32, second: u32, angle: u32) -> String {
    format!("{plant}_2018-04-{day:02}_10-00-{second:02}_Vis_SV_{angle}.png")
}

/// A small, unique PNG: white background, a green stripe whose position and
/// a corner pixel depend on `seed`, so no two seeds share content.
pub fn small_png(seed: u64, side: u32) -> Vec<u8> {
    let mut img = image::RgbImage::from_pixel(side, side, image::Rgb([235, 235, 230]));
    let x0 = (seed % (side as u64 / 2)) as u32 + side / 4;
    for y in side / 4..side {
        for x in x0.saturating_sub(3)..(x0 + 3).min(side) {
            img.put_pixel(x, y, image::Rgb([40, 120, 30]));
        }
    }
    let b = seed.to_le_bytes();
    img.put_pixel(0, 0, image::Rgb([b[0], b[1], b[2]]));
    img.put_pixel(1, 0, image::Rgb([b[3], b[4], b[5]]));
    encode(image::DynamicImage::ImageRgb8(img), image::ImageFormat::Png)
}

/// Encodes an image.
pub fn encode(img: image::DynamicImage, fmt: image::ImageFormat) -> Vec<u8> {
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), fmt).unwrap();
    out
}

/// A deterministic generator (xorshift64*), so a failing run reproduces from its seed.
pub struct Rng(pub u64);

impl Rng {
    /// Next value.
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `[lo, hi)` milliseconds.
    pub fn ms(&mut self, lo: u64, hi: u64) -> Duration {
        Duration::from_millis(lo + self.next() % (hi - lo).max(1))
    }
}

/// Writes `bytes` to `dst` either directly (close-after-write) or through a
/// hidden temporary renamed into place, as imaging stations do.
pub fn drop_file(dst: &Path, bytes: &[u8], via_rename: bool) {
    if via_rename {
        let tmp = dst.with_file_name(format!(".{}.part", dst.file_name().unwrap().to_string_lossy()));
        std::fs::write(&tmp, bytes).unwrap();
        std::fs::rename(&tmp, dst).unwrap();
    } else {
        std::fs::write(dst, bytes).unwrap();
    }
}
