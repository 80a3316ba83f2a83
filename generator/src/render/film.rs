//! From radiance to the camera's 8-bit sRGB pixels: exposure, white balance,
//! sensor noise, clipping, the sRGB transfer curve and optional JPEG
//! artefacts.

use super::look::Look;
use glam::Vec3;
use image::RgbImage;

/// sRGB transfer function of a linear value in `[0, 1]`.
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse sRGB transfer function.
#[inline]
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// Develops one pixel; `noise` are three standard normal draws.
#[inline]
pub fn develop(radiance: Vec3, look: &Look, noise: [f32; 3]) -> [u8; 3] {
    let v = radiance * look.exposure * Vec3::from(look.white_balance);
    let mut out = [0u8; 3];
    for c in 0..3 {
        let s = linear_to_srgb(v[c].clamp(0.0, 1.0)) + noise[c] * look.noise_sd;
        out[c] = (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    }
    out
}

/// Puts the image through a JPEG encode/decode at `quality`, as the real
/// facility's archives are JPEG. Deterministic for given input bytes.
pub fn jpeg_round_trip(img: &RgbImage, quality: u8) -> anyhow::Result<RgbImage> {
    let mut bytes = Vec::new();
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality);
    img.write_with_encoder(enc)?;
    Ok(image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)?.to_rgb8())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips() {
        for x in [0.0f32, 0.002, 0.1, 0.5, 1.0] {
            assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() < 1e-5);
        }
    }
}
