//! Counting the stored images again with the current model and settings.
//!
//! A new model or post-processing stage changes counts; without a recount a
//! site's timelines would mix old and new counts and show a step on the day
//! of the upgrade. Each counted image is read again from the drop directory;
//! one whose content no longer matches its recorded hash is left alone (the
//! daemon counts it as a new version), and so is one that is gone.

use std::path::Path;

use crate::counting::LeafCounter;
use crate::files::sha256_hex;
use crate::store::{CountedImage, Store};

/// What a recount did.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct RecountSummary {
    /// Images counted again.
    pub recounted: usize,
    /// Of those, images whose leaf count changed.
    pub changed: usize,
    /// Sum of the count changes (new minus old).
    pub net_leaves: i64,
    /// Images no longer in the drop directory.
    pub missing: Vec<String>,
    /// Images whose content changed since they were counted.
    pub modified: Vec<String>,
    /// Images the counter failed on, with its message.
    pub failed: Vec<(String, String)>,
    /// Plants whose timelines were refitted.
    pub plants_refitted: usize,
}

/// Counts every counted image of `plant` (or of all plants) again with
/// `counter` and, unless `dry_run`, stores the new counts and refits the
/// timelines. `progress` hears about each image as it is done.
pub fn recount(
    store: &mut Store,
    counter: &dyn LeafCounter,
    drop_dir: &Path,
    plant: Option<&str>,
    dry_run: bool,
    mut progress: impl FnMut(&CountedImage, Option<u32>),
) -> anyhow::Result<RecountSummary> {
    let mut summary = RecountSummary::default();
    for img in store.counted_images(plant)? {
        let path = drop_dir.join(crate::domain::rel_path::decode(&img.path));
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                summary.missing.push(img.path.clone());
                progress(&img, None);
                continue;
            }
            Err(e) => {
                summary
                    .failed
                    .push((img.path.clone(), format!("{}: {e}", path.display())));
                progress(&img, None);
                continue;
            }
        };
        if sha256_hex(&bytes) != img.sha256 {
            summary.modified.push(img.path.clone());
            progress(&img, None);
            continue;
        }
        // Counted as the view its name was read as when it was stored: the
        // name is not parsed again.
        let view = crate::domain::names::View::parse(&img.view);
        let count = match counter.count(&path, &view, &bytes) {
            Ok(c) => c,
            Err(e) => {
                summary.failed.push((img.path.clone(), e.message));
                progress(&img, None);
                continue;
            }
        };
        summary.recounted += 1;
        let delta = i64::from(count.leaf_count) - i64::from(img.leaf_count);
        if delta != 0 {
            summary.changed += 1;
            summary.net_leaves += delta;
        }
        if !dry_run {
            store.replace_count(img.image_id, &count)?;
        }
        progress(&img, Some(count.leaf_count));
    }
    if !dry_run && summary.recounted > 0 {
        summary.plants_refitted = store.recompute_all()?;
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::counting::CountError;
    use crate::domain::names::{ParsedName, View};
    use crate::domain::timeline::TimelineParams;
    use crate::store::{CountRecord, FileFacts, Outcome};

    /// Counts the bytes' length, plus `extra`: a stand-in for a new model.
    struct LengthCounter {
        extra: u32,
    }

    impl LeafCounter for LengthCounter {
        fn count(&self, _name: &Path, _: &View, bytes: &[u8]) -> Result<CountRecord, CountError> {
            if bytes.starts_with(b"bad") {
                return Err(CountError {
                    message: "not an image".into(),
                    retry: false,
                });
            }
            Ok(CountRecord {
                leaf_count: bytes.len() as u32 + self.extra,
                instances: serde_json::json!([]),
                timing: serde_json::json!({}),
                ms_total: 1.0,
                model_id: format!("length+{}", self.extra),
                settings: serde_json::json!({"extra": self.extra}),
            })
        }

        fn model_id(&self) -> String {
            format!("length+{}", self.extra)
        }
    }

    fn store_with(dir: &tempfile::TempDir, files: &[(&str, &str, i64)]) -> Store {
        let mut store = Store::open(&dir.path().join("db.sqlite"), &TimelineParams::default(), 3).unwrap();
        let old = LengthCounter { extra: 0 };
        for (rel, content, day) in files {
            std::fs::write(dir.path().join(rel), content).unwrap();
            let facts = FileFacts {
                rel: rel.to_string(),
                size: content.len() as u64,
                mtime: None,
                sha256: sha256_hex(content.as_bytes()),
            };
            let name = ParsedName {
                plant: "P1".into(),
                taken_at: chrono::NaiveDate::from_ymd_opt(2026, 5, 1)
                    .unwrap()
                    .and_hms_opt(10, 0, 0)
                    .unwrap()
                    + chrono::Duration::days(*day),
                view: View::Side(0),
                pattern: "test".into(),
            };
            let count = old.count(Path::new(rel), &name.view, content.as_bytes()).unwrap();
            store.record(&facts, Outcome::Counted(&name, &count)).unwrap();
        }
        store
    }

    #[test]
    fn new_counts_replace_the_old_and_the_timeline_follows() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = store_with(
            &dir,
            &[
                ("a.png", "aaaa", 0),
                ("b.png", "bbbbb", 1),
                ("c.png", "cccccc", 2),
            ],
        );
        // One image is gone, one was rewritten since it was counted.
        std::fs::remove_file(dir.path().join("b.png")).unwrap();
        std::fs::write(dir.path().join("c.png"), "different").unwrap();
        let new = LengthCounter { extra: 2 };
        let dry = recount(&mut store, &new, dir.path(), None, true, |_, _| {}).unwrap();
        assert_eq!((dry.recounted, dry.changed, dry.net_leaves), (1, 1, 2));
        assert_eq!(
            store.counted_images(None).unwrap()[0].leaf_count,
            4,
            "a dry run writes nothing"
        );
        let mut seen = Vec::new();
        let s = recount(&mut store, &new, dir.path(), Some("P1"), false, |img, n| {
            seen.push((img.path.clone(), n))
        })
        .unwrap();
        assert_eq!(s.missing, vec!["b.png".to_string()]);
        assert_eq!(s.modified, vec!["c.png".to_string()]);
        assert_eq!(
            (s.recounted, s.changed, s.net_leaves, s.plants_refitted),
            (1, 1, 2, 1)
        );
        assert_eq!(seen.len(), 3);
        let imgs = store.counted_images(None).unwrap();
        assert_eq!(imgs[0].leaf_count, 6);
        assert_eq!(imgs[0].settings.as_deref(), Some(r#"{"extra":2}"#));
        assert_eq!(imgs[1].leaf_count, 5, "the missing image keeps its count");
        let first = &store.plant_timeline("P1").unwrap().unwrap().sessions[0];
        assert_eq!(first.fused, 6.0, "the timeline is refitted from the new count");
        // The change is in the feed `phyllo tail` follows, named by file.
        let recounts = |store: &Store| {
            store
                .feed_after(0, None, 1000)
                .unwrap()
                .into_iter()
                .filter(|r| r.kind == "recount")
                .collect::<Vec<_>>()
        };
        let feed = recounts(&store);
        assert_eq!(feed.len(), 1, "{feed:?}");
        assert_eq!(feed[0].path.as_deref(), Some("a.png"));
        assert_eq!(feed[0].leaf_count, Some(6));
        assert_eq!(feed[0].message.as_deref(), Some("a.png: count 4 -> 6 (length+2)"));
        // Counting again with the same counter changes nothing, and says nothing.
        let again = recount(&mut store, &new, dir.path(), None, false, |_, _| {}).unwrap();
        assert_eq!((again.recounted, again.changed), (1, 0));
        assert_eq!(recounts(&store).len(), 1);
    }

    #[test]
    fn a_failed_recount_keeps_the_old_count() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = store_with(&dir, &[("a.png", "aaaa", 0)]);
        // The same bytes, but this counter refuses them.
        struct Refuses;
        impl LeafCounter for Refuses {
            fn count(&self, name: &Path, _: &View, _: &[u8]) -> Result<CountRecord, CountError> {
                Err(CountError {
                    message: format!("{}: refused", name.display()),
                    retry: false,
                })
            }
            fn model_id(&self) -> String {
                "refuses".into()
            }
        }
        let s = recount(&mut store, &Refuses, dir.path(), None, false, |_, _| {}).unwrap();
        assert_eq!(s.failed.len(), 1);
        assert!(s.failed[0].1.contains("a.png: refused"), "{:?}", s.failed);
        assert_eq!(store.counted_images(None).unwrap()[0].leaf_count, 4);
    }
}
