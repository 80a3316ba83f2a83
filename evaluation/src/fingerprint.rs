//! A digest of exactly what an evaluation read, so that two numbers can be
//! said to come from the same data.
//!
//! The withheld and calibration sets are regenerated from a seed on each
//! machine, and any change to the generator's look changes them: a number in
//! the model card is only comparable with a rerun when the fingerprints agree.

use std::path::Path;

use anyhow::Context;
use sha2::{Digest, Sha256};

use super::sources::{self, DatasetItem, HumanCount};

/// Running SHA-256 over each evaluated item's name, files and truth.
#[derive(Debug, Clone, Default)]
pub struct Fingerprint {
    hasher: Sha256,
    items: usize,
}

impl Fingerprint {
    /// Adds one item: its name (path relative to the data set), then each part
    /// (file bytes, a truth written out as text). Parts are length-prefixed, so
    /// moving bytes from one part to the next changes the digest.
    pub fn add(&mut self, name: &str, parts: &[&[u8]]) {
        for part in std::iter::once(name.as_bytes()).chain(parts.iter().copied()) {
            self.hasher.update((part.len() as u64).to_le_bytes());
            self.hasher.update(part);
        }
        self.items += 1;
    }

    /// How many items were added.
    pub fn items(&self) -> usize {
        self.items
    }

    /// The first 16 hex digits of the digest (64 bits: plenty to tell data sets apart).
    pub fn hex(&self) -> String {
        let digest = self.hasher.clone().finalize();
        digest[..8].iter().map(|b| format!("{b:02x}")).collect()
    }

    /// Adds one phyllo-gen pair: its manifest name, image bytes and label bytes.
    pub fn add_pair(&mut self, item: &DatasetItem, image: &[u8], label: &[u8]) {
        self.add(&item.name, &[image, label]);
    }

    /// Adds one human-counted image: its file name, bytes, count and marked tips.
    pub fn add_human_count(&mut self, hc: &HumanCount, image: &[u8]) {
        let name = hc.image.file_name().map(|f| f.to_string_lossy().into_owned());
        let truth = format!("{} {:?}", hc.count, hc.tips);
        self.add(&name.unwrap_or_default(), &[image, truth.as_bytes()]);
    }

    /// The fingerprint of a phyllo-gen split read without a model, and the
    /// items whose files could not be read (left out, as `phyllo eval` leaves
    /// out items it fails on).
    pub fn of_dataset(dir: &Path, split: Option<&str>) -> anyhow::Result<(Self, Vec<String>)> {
        let mut f = Self::default();
        let mut failed = Vec::new();
        let read = |p: &Path| std::fs::read(p).with_context(|| format!("cannot read {}", p.display()));
        for item in sources::read_manifest(dir, split)? {
            match read(&item.image).and_then(|i| Ok((i, read(&item.label)?))) {
                Ok((image, label)) => f.add_pair(&item, &image, &label),
                Err(e) => failed.push(format!("{e:#}")),
            }
        }
        Ok((f, failed))
    }

    /// The fingerprint of a human-count CSV and its images, read without a model.
    pub fn of_counts(csv: &Path, images: &Path) -> anyhow::Result<(Self, Vec<String>)> {
        let mut f = Self::default();
        let mut failed = Vec::new();
        for hc in sources::read_counts(csv, images)? {
            match std::fs::read(&hc.image) {
                Ok(bytes) => f.add_human_count(&hc, &bytes),
                Err(e) => failed.push(format!("cannot read {}: {e}", hc.image.display())),
            }
        }
        Ok((f, failed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn digest(items: &[(&str, &[u8], &[u8])]) -> String {
        let mut f = Fingerprint::default();
        for (name, image, label) in items {
            f.add(name, &[image, label]);
        }
        assert_eq!(f.items(), items.len());
        f.hex()
    }

    #[test]
    fn same_items_same_digest_and_any_change_shows() {
        let (a, b) = ("images/p0_0.png", "images/p0_36.png");
        let base = digest(&[(a, b"img0", b"lab0"), (b, b"img1", b"lab1")]);
        assert_eq!(base.len(), 16);
        assert_eq!(base, digest(&[(a, b"img0", b"lab0"), (b, b"img1", b"lab1")]));
        let changed = [
            // one byte of one label
            digest(&[(a, b"img0", b"lab0"), (b, b"img1", b"lab2")]),
            // the same bytes split differently between image and label
            digest(&[(a, b"img0l", b"ab0"), (b, b"img1", b"lab1")]),
            // order
            digest(&[(b, b"img1", b"lab1"), (a, b"img0", b"lab0")]),
        ];
        for c in changed {
            assert_ne!(base, c);
        }
    }
}
