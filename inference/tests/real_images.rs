//! The decoder's refusals (a JPEG cut short, a header that lies) must never
//! refuse a real camera frame: every real development image decodes.
//! Skipped, and said so, without `../shared/data/unl-maize-dev` (or
//! `PHYLLO_DEV_DATA`).

use std::path::PathBuf;

use phyllo_inference::decode::{decode_rgb, DecodeLimits};

#[test]
fn every_real_development_image_decodes() {
    let root = std::env::var_os("PHYLLO_DEV_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/unl-maize-dev"));
    let samples = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs/samples");
    let mut dirs = vec![samples];
    if root.join("images").is_dir() {
        dirs.extend([root.join("images"), root.join("crops")]);
    } else {
        eprintln!("SKIPPED the development images: no {}", root.display());
    }
    let mut decoded = 0;
    for dir in dirs {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if !path.extension().is_some_and(|x| x == "jpg" || x == "png") {
                continue;
            }
            let bytes = std::fs::read(&path).unwrap();
            if let Err(e) = decode_rgb(&path, &bytes, &DecodeLimits::default()) {
                panic!("a real image is refused: {e}");
            }
            decoded += 1;
        }
    }
    eprintln!("{decoded} real images decoded");
    assert!(decoded >= 3);
}
