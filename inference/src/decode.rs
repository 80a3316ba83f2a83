//! Decoding image files into RGB, with limits against hostile input.

use std::io::Cursor;
use std::path::Path;

use image::metadata::Orientation;
use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, RgbImage};
use serde::{Deserialize, Serialize};

use crate::error::InferenceError;

/// Bounds on what the decoder accepts. A LemnaTec frame is 2454x2056; the
/// defaults leave room for larger cameras while refusing decompression bombs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DecodeLimits {
    /// Largest accepted width or height, in pixels.
    pub max_side: u32,
    /// Largest accepted width x height, in pixels.
    pub max_pixels: u64,
    /// Smallest accepted width or height, in pixels.
    pub min_side: u32,
    /// Most memory the decoder may allocate, in bytes.
    pub max_alloc_bytes: u64,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        Self {
            max_side: 12_000,
            max_pixels: 40_000_000,
            min_side: 16,
            max_alloc_bytes: 512 << 20,
        }
    }
}

/// Decodes `bytes` (the content of `name`) into 8-bit RGB.
///
/// The format is recognised from the content, not the extension, so a JPEG
/// saved as `.png` still decodes and a text file named `.jpg` is refused as
/// such. 16-bit, grey, grey+alpha and RGBA images are converted to RGB8
/// (alpha is dropped: the chamber has no transparency).
pub fn decode_rgb(name: &Path, bytes: &[u8], limits: &DecodeLimits) -> Result<RgbImage, InferenceError> {
    if bytes.is_empty() {
        return Err(InferenceError::image(name, "file is empty (0 bytes)"));
    }
    let reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| InferenceError::image(name, format!("cannot read: {e}")))?;
    let format = reader
        .format()
        .ok_or_else(|| InferenceError::image(name, "not a PNG, JPEG or TIFF image (unrecognised content)"))?;
    if !matches!(format, ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::Tiff) {
        return Err(InferenceError::image(
            name,
            format!("{format:?} images are not supported (PNG, JPEG, TIFF)"),
        ));
    }
    if format == ImageFormat::Jpeg && !has_jpeg_end(bytes) {
        return Err(InferenceError::image(
            name,
            "corrupt or truncated Jpeg: no end-of-image marker (file still being written?)",
        ));
    }
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| InferenceError::image(name, format!("cannot read {format:?} header: {e}")))?;
    check_dimensions(name, w, h, limits)?;
    if format == ImageFormat::Jpeg
        && (bytes.len() as u64) < u64::from(w) * u64::from(h) / MIN_JPEG_PIXELS_PER_BYTE
    {
        return Err(InferenceError::image(
            name,
            format!(
                "corrupt Jpeg: its header claims {w}x{h}, which {} bytes cannot hold (a camera frame that size \
                 takes at least {} bytes)",
                bytes.len(),
                u64::from(w) * u64::from(h) / MIN_JPEG_PIXELS_PER_BYTE
            ),
        ));
    }

    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    let mut lim = image::Limits::default();
    lim.max_image_width = Some(limits.max_side);
    lim.max_image_height = Some(limits.max_side);
    lim.max_alloc = Some(limits.max_alloc_bytes);
    reader.limits(lim.clone());
    let corrupt =
        |e: image::ImageError| InferenceError::image(name, format!("corrupt or truncated {format:?}: {e}"));
    let mut decoder = reader.into_decoder().map_err(corrupt)?;
    // The output buffer against the allocation limit, as ImageReader::decode does.
    lim.reserve(decoder.total_bytes()).map_err(corrupt)?;
    // A camera or a photo tool may store the frame on its side with an EXIF
    // orientation tag; the plant must stand upright before it is counted.
    let orientation = decoder.orientation().unwrap_or(Orientation::NoTransforms);
    let img = DynamicImage::from_decoder(decoder).map_err(corrupt)?;
    let rgb = img.into_rgb8();
    if format == ImageFormat::Jpeg {
        check_jpeg_fill(name, &rgb)?;
    }
    let mut img = DynamicImage::ImageRgb8(rgb);
    img.apply_orientation(orientation);
    Ok(img.into_rgb8())
}

/// A JPEG of a camera frame holds at least one byte per this many pixels:
/// the chamber's frames hold one per 19 or fewer (the real dev sets), a
/// flat grey frame about one per 250. Fewer bytes than this for the size
/// the header claims is a corrupt header or a file cut short.
const MIN_JPEG_PIXELS_PER_BYTE: u64 = 100;

/// Refuses a JPEG whose data end before its frame does. A decoder that
/// runs out of scan data ("premature end of data") fills the rest of the
/// frame with copies of its last block and reports success; that fill
/// repeats exactly every 16 rows and every 16 columns. A camera frame never
/// repeats itself exactly (sensor noise): none of the real dev sets' frames
/// has a single bottom row equal to the one 16 above. A flat band (a frame
/// with the lights off, a drawn test image) is left alone: it repeats too,
/// but so does each row the one just above it.
fn check_jpeg_fill(name: &Path, img: &RgbImage) -> Result<(), InferenceError> {
    const MCU: u32 = 16;
    let (w, h) = img.dimensions();
    let row_bytes = w as usize * 3;
    let row = |y: u32| &img.as_raw()[y as usize * row_bytes..(y as usize + 1) * row_bytes];
    let repeats = |period: u32| {
        (period..h)
            .rev()
            .take_while(|&y| row(y) == row(y - period))
            .count() as u32
    };
    let filled = repeats(MCU);
    if filled >= (h / 8).max(64) && repeats(1) < filled {
        return Err(InferenceError::image(
            name,
            format!(
                "corrupt or truncated Jpeg: its last {filled} of {h} rows repeat one block, the fill a decoder \
                 leaves where the data end early (premature end of data)"
            ),
        ));
    }
    Ok(())
}

/// Reads and decodes an image file as [`decode_rgb`] does, with default limits.
pub fn read_rgb(path: &Path) -> Result<RgbImage, InferenceError> {
    let bytes = std::fs::read(path).map_err(|e| InferenceError::image(path, format!("cannot read: {e}")))?;
    decode_rgb(path, &bytes, &DecodeLimits::default())
}

/// Whether a JPEG ends with its end-of-image marker (FF D9). Decoders fill a
/// truncated JPEG with grey and report success, so a half-written file would
/// otherwise be counted as data. Some cameras pad after the marker, so a
/// short tail of padding is allowed.
fn has_jpeg_end(bytes: &[u8]) -> bool {
    let tail = &bytes[bytes.len().saturating_sub(4096)..];
    let trimmed = tail
        .iter()
        .rposition(|&b| b != 0x00)
        .map_or(&tail[..0], |i| &tail[..=i]);
    trimmed.windows(2).rev().take(64).any(|w| w == [0xFF, 0xD9])
}

/// Refuses images that are too small to hold a plant or too large to be a camera frame.
pub fn check_dimensions(name: &Path, w: u32, h: u32, limits: &DecodeLimits) -> Result<(), InferenceError> {
    if w < limits.min_side || h < limits.min_side {
        return Err(InferenceError::image(
            name,
            format!(
                "{w}x{h} is too small (each side must be at least {} px)",
                limits.min_side
            ),
        ));
    }
    if w > limits.max_side || h > limits.max_side || u64::from(w) * u64::from(h) > limits.max_pixels {
        return Err(InferenceError::image(
            name,
            format!(
                "{w}x{h} exceeds the limits ({} px per side, {} pixels): refusing a possible decompression bomb",
                limits.max_side, limits.max_pixels
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png_bytes(img: image::DynamicImage) -> Vec<u8> {
        let mut out = Vec::new();
        img.write_to(&mut Cursor::new(&mut out), ImageFormat::Png)
            .unwrap();
        out
    }

    #[test]
    fn decodes_grey16_and_rgba_to_rgb8() {
        let lim = DecodeLimits::default();
        let g16 =
            image::DynamicImage::ImageLuma16(image::ImageBuffer::from_pixel(32, 20, image::Luma([65535u16])));
        let rgb = decode_rgb(Path::new("a.png"), &png_bytes(g16), &lim).unwrap();
        assert_eq!(rgb.dimensions(), (32, 20));
        assert_eq!(rgb.get_pixel(3, 3).0, [255, 255, 255]);
        let rgba = image::DynamicImage::ImageRgba8(image::ImageBuffer::from_pixel(
            20,
            20,
            image::Rgba([10, 200, 30, 0]),
        ));
        let rgb = decode_rgb(Path::new("b.png"), &png_bytes(rgba), &lim).unwrap();
        assert_eq!(rgb.get_pixel(0, 0).0, [10, 200, 30]);
    }

    #[test]
    fn refuses_empty_garbage_truncated_and_bombs_with_the_name() {
        let lim = DecodeLimits::default();
        let e = decode_rgb(Path::new("empty.png"), &[], &lim)
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty.png") && e.contains("empty"), "{e}");
        let e = decode_rgb(Path::new("t.jpg"), b"hello, I am text", &lim)
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.jpg") && e.contains("not a PNG"), "{e}");
        let full = png_bytes(image::DynamicImage::new_rgb8(64, 64));
        let e = decode_rgb(Path::new("cut.png"), &full[..full.len() / 2], &lim)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cut.png") && e.contains("corrupt or truncated"), "{e}");
        let mut jpeg = Vec::new();
        image::DynamicImage::new_rgb8(64, 64)
            .write_to(&mut Cursor::new(&mut jpeg), ImageFormat::Jpeg)
            .unwrap();
        assert!(decode_rgb(Path::new("ok.jpg"), &jpeg, &lim).is_ok());
        let e = decode_rgb(Path::new("half.jpg"), &jpeg[..jpeg.len() - 40], &lim)
            .unwrap_err()
            .to_string();
        assert!(e.contains("half.jpg") && e.contains("truncated"), "{e}");
        let e = check_dimensions(Path::new("bomb.png"), 100_000, 100_000, &lim)
            .unwrap_err()
            .to_string();
        assert!(e.contains("decompression bomb"), "{e}");
        let e = check_dimensions(Path::new("dot.png"), 1, 1, &lim)
            .unwrap_err()
            .to_string();
        assert!(e.contains("too small"), "{e}");
    }

    /// A JPEG cut short with its end marker kept, and one whose header claims
    /// a frame far larger than its data, decode "successfully" into a flat
    /// fill: both are refused, not counted as an empty chamber (issue 57
    /// item 2). A frame flat from edge to edge is still a frame.
    #[test]
    fn a_jpeg_whose_data_end_early_or_whose_header_lies_is_refused() {
        let lim = DecodeLimits::default();
        let noise = image::RgbImage::from_fn(256, 192, |x, y| {
            let v = (x.wrapping_mul(7919) ^ y.wrapping_mul(104_729)).wrapping_mul(2_654_435_761) >> 24;
            image::Rgb([v as u8, (v >> 1) as u8, 255 - v as u8])
        });
        let mut jpeg = Vec::new();
        image::DynamicImage::ImageRgb8(noise)
            .write_to(&mut Cursor::new(&mut jpeg), ImageFormat::Jpeg)
            .unwrap();
        assert!(decode_rgb(Path::new("whole.jpg"), &jpeg, &lim).is_ok());
        let mut cut = jpeg[..jpeg.len() / 2].to_vec();
        cut.extend_from_slice(&[0xFF, 0xD9]);
        let Err(e) = decode_rgb(Path::new("cut.jpg"), &cut, &lim) else {
            panic!("cut.jpg was counted");
        };
        let e = e.to_string();
        assert!(
            e.contains("cut.jpg") && e.contains("premature end of data"),
            "{e}"
        );
        let sof = jpeg
            .windows(2)
            .position(|w| w == [0xFF, 0xC0])
            .expect("a baseline frame header");
        let mut big = jpeg.clone();
        big[sof + 5..sof + 9].copy_from_slice(&[0x18, 0xB0, 0x18, 0xB0]); // 6320 x 6320
        let Err(e) = decode_rgb(Path::new("big.jpg"), &big, &lim) else {
            panic!("big.jpg was counted");
        };
        let e = e.to_string();
        assert!(e.contains("big.jpg") && e.contains("claims 6320x6320"), "{e}");
        let mut flat = Vec::new();
        image::DynamicImage::new_rgb8(64, 64)
            .write_to(&mut Cursor::new(&mut flat), ImageFormat::Jpeg)
            .unwrap();
        assert!(decode_rgb(Path::new("dark.jpg"), &flat, &lim).is_ok());
    }

    /// A little-endian TIFF header with one IFD entry: Orientation = `value`.
    fn exif_orientation(value: u8) -> Vec<u8> {
        let mut b = b"II*\0\x08\0\0\0\x01\0".to_vec();
        b.extend_from_slice(&[0x12, 0x01, 0x03, 0x00, 0x01, 0, 0, 0, value, 0, 0, 0]);
        b.extend_from_slice(&[0, 0, 0, 0]);
        b
    }

    #[test]
    fn exif_orientation_stands_the_image_upright() {
        use image::{codecs::jpeg::JpegEncoder, ImageEncoder, Rgb};
        // Stored on its side: 60 wide, 30 high, the top rows red (the picture's left
        // side once turned 90° clockwise, as orientation 6 asks).
        let stored = RgbImage::from_fn(60, 30, |_, y| {
            if y < 10 {
                Rgb([220, 20, 20])
            } else {
                Rgb([20, 200, 20])
            }
        });
        let mut jpeg = Vec::new();
        let mut enc = JpegEncoder::new_with_quality(&mut jpeg, 95);
        enc.set_exif_metadata(exif_orientation(6)).unwrap();
        enc.write_image(stored.as_raw(), 60, 30, image::ExtendedColorType::Rgb8)
            .unwrap();
        let img = decode_rgb(Path::new("side.jpg"), &jpeg, &DecodeLimits::default()).unwrap();
        assert_eq!(img.dimensions(), (30, 60), "turned upright");
        // Orientation 6 turns the stored image 90° clockwise: its top rows become the right columns.
        assert!(img.get_pixel(27, 30)[0] > 150, "{:?}", img.get_pixel(27, 30));
        assert!(img.get_pixel(5, 30)[1] > 150, "{:?}", img.get_pixel(5, 30));
    }
}
