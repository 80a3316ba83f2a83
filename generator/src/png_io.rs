//! Writing outputs: fast PNG encoding and atomic file replacement (write a
//! temporary file, then rename) so an interrupted run never leaves a
//! half-written file that a resumed run would mistake for a finished one.

use anyhow::Context;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use std::path::Path;

/// Encodes 8-bit RGB or 16-bit grey pixels as PNG bytes.
pub fn encode_png(
    width: u32,
    height: u32,
    bytes: &[u8],
    colour: ExtendedColorType,
) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(bytes, width, height, colour)
        .context("encoding PNG")?;
    Ok(out)
}

/// Encodes an RGB image.
pub fn rgb_png(img: &image::RgbImage) -> anyhow::Result<Vec<u8>> {
    encode_png(img.width(), img.height(), img.as_raw(), ExtendedColorType::Rgb8)
}

/// Encodes a 16-bit grey label. The encoder takes native-endian samples and
/// writes PNG's big-endian itself.
pub fn label_png(label: &crate::label::LabelImage) -> anyhow::Result<Vec<u8>> {
    let bytes: Vec<u8> = label.data.iter().flat_map(|v| v.to_ne_bytes()).collect();
    encode_png(label.width, label.height, &bytes, ExtendedColorType::L16)
}

/// Writes `bytes` to `path` atomically, creating parent folders.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating folder {}", dir.display()))?;
    }
    let tmp = path.with_extension(format!(
        "{}.part",
        path.extension().and_then(|e| e.to_str()).unwrap_or("tmp")
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))?;
    Ok(())
}
