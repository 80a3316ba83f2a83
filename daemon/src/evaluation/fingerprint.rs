//! A digest of exactly what an evaluation read, so that two numbers can be
//! said to come from the same data.
//!
//! The withheld and calibration sets are regenerated from a seed on each
//! machine, and any change to the generator's look changes them: a number in
//! the model card is only comparable with a rerun when the fingerprints agree.

use sha2::{Digest, Sha256};

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
