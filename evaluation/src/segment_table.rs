//! One row per predicted leaf of a labelled dataset: what it is against the
//! truth (found, a split-off piece, ...) beside what the post-processing
//! could see of it (area, score, contact with neighbouring leaves), so that
//! a rule for dropping or merging instances can be scored offline on the
//! rows (`python -m phyllo_train.experiments.segment_rules`) without running the model
//! again.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use phyllo_contract::LEAF;
use phyllo_inference::postprocess::Panoptic;
use serde::Serialize;

use super::leaf_errors::classify_predicted;
use super::segmentation::Overlaps;

/// One predicted leaf instance.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SegmentRow {
    /// Image name in the dataset.
    pub image: String,
    /// The image's true count.
    pub truth: u32,
    /// The image's predicted count.
    pub predicted: u32,
    /// Instance id in the panoptic output.
    pub segment: u32,
    /// `found`, `partner`, `split`, `on_stem`, `on_background` or `unseen`
    /// (no pixel left at image resolution).
    pub kind: &'static str,
    /// Area in model output pixels.
    pub area: u32,
    /// Instance score (centre peak times mean class probability).
    pub score: f32,
    /// Longest border shared with one other leaf instance, in output pixel edges.
    pub max_contact: u32,
    /// Border shared with all other leaf instances.
    pub total_contact: u32,
    /// Area of the leaf instance sharing the longest border (0: none).
    pub neighbour_area: u32,
}

/// Rows of one image's leaf instances.
pub fn rows(image: &str, truth: u32, predicted: u32, overlaps: &Overlaps, pan: &Panoptic) -> Vec<SegmentRow> {
    let kinds = classify_predicted(overlaps);
    let contact = leaf_contacts(pan);
    pan.segments
        .iter()
        .filter(|s| s.class == LEAF)
        .map(|s| {
            let mine = contact.range((s.id, 0)..=(s.id, u32::MAX));
            let (mut best, mut max_contact, mut total_contact) = (0, 0, 0);
            for (&(_, other), &n) in mine {
                total_contact += n;
                if n > max_contact {
                    (best, max_contact) = (other, n);
                }
            }
            SegmentRow {
                image: image.to_string(),
                truth,
                predicted,
                segment: s.id,
                kind: kinds.get(&s.id).map_or("unseen", |k| k.name()),
                area: s.area,
                score: s.score,
                max_contact,
                total_contact,
                neighbour_area: if best > 0 {
                    pan.segments[best as usize - 1].area
                } else {
                    0
                },
            }
        })
        .collect()
}

/// Shared border lengths between leaf instances, keyed both ways `(a, b)`.
fn leaf_contacts(pan: &Panoptic) -> BTreeMap<(u32, u32), u32> {
    let (w, h) = (pan.width, pan.height);
    let leaf_at = |i: usize| {
        let id = pan.instance[i];
        (id > 0 && pan.segments[id as usize - 1].class == LEAF).then_some(id)
    };
    let mut contact = BTreeMap::new();
    for y in 0..h {
        for x in 0..w {
            let Some(a) = leaf_at(y * w + x) else { continue };
            let right = (x + 1 < w).then(|| y * w + x + 1);
            let below = (y + 1 < h).then(|| (y + 1) * w + x);
            for b in [right, below].into_iter().flatten().filter_map(leaf_at) {
                if b != a {
                    *contact.entry((a, b)).or_default() += 1;
                    *contact.entry((b, a)).or_default() += 1;
                }
            }
        }
    }
    contact
}

/// Writes the rows as a tab-separated table with a header.
pub fn write_tsv(path: &Path, rows: &[SegmentRow]) -> anyhow::Result<()> {
    let mut w = csv::WriterBuilder::new()
        .delimiter(b'\t')
        .from_path(path)
        .with_context(|| format!("cannot create {}", path.display()))?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use phyllo_contract::STEM;
    use phyllo_inference::postprocess::Segment;

    fn segment(id: u32, class: u8, area: u32) -> Segment {
        Segment {
            id,
            class,
            area,
            bbox: [0, 0, 1, 1],
            centre: [0.0, 0.0],
            score: 0.5,
        }
    }

    #[test]
    fn contact_counts_shared_edges_between_leaves_only() {
        // 1 1 2
        // 1 1 2
        // 3 3 .   (3 is stem: its border with 1 does not count)
        let pan = Panoptic {
            height: 3,
            width: 3,
            semantic: vec![0; 9],
            instance: vec![1, 1, 2, 1, 1, 2, 3, 3, 0],
            segments: vec![segment(1, LEAF, 4), segment(2, LEAF, 2), segment(3, STEM, 2)],
            tips: None,
        };
        let c = leaf_contacts(&pan);
        assert_eq!(c.get(&(1, 2)), Some(&2));
        assert_eq!(c.get(&(2, 1)), Some(&2));
        assert_eq!(c.get(&(1, 3)), None);
        let rows = rows("x", 2, 2, &Overlaps::default(), &pan);
        assert_eq!(rows.len(), 2, "one row per leaf instance");
        assert_eq!((rows[0].max_contact, rows[0].neighbour_area), (2, 2));
        assert_eq!((rows[1].max_contact, rows[1].neighbour_area), (2, 4));
        assert_eq!(rows[0].kind, "unseen");
    }

    #[test]
    fn the_table_reads_back_with_its_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("segments.tsv");
        let row = SegmentRow {
            image: "p1_0".into(),
            truth: 5,
            predicted: 6,
            segment: 3,
            kind: "split",
            area: 40,
            score: 0.25,
            max_contact: 7,
            total_contact: 9,
            neighbour_area: 300,
        };
        write_tsv(&path, &[row]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next(),
            Some("image\ttruth\tpredicted\tsegment\tkind\tarea\tscore\tmax_contact\ttotal_contact\tneighbour_area")
        );
        assert_eq!(lines.next(), Some("p1_0\t5\t6\t3\tsplit\t40\t0.25\t7\t9\t300"));
    }
}
