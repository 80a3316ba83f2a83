//! Where a new leaf emerged: the leaf instance in the images of the session
//! that first counted it that was not there the session before.
//!
//! The paper dated each new leaf but could not say which leaf it was. The
//! camera and the turntable angles repeat from day to day and a plant moves
//! little overnight, so each side view's leaf instances are matched to the
//! same view's instances of the session before, nearest predicted centres
//! first; what stays unmatched is new. A grass leaf emerges from the whorl
//! at the top of the plant, so among the new instances the highest is taken,
//! in the view whose count rose most. Several leaves new in one session get
//! the highest new instances, the newest leaf the highest. Fallback, when
//! every instance found a partner: the view's highest instance.

use serde::Deserialize;

/// One leaf instance as the daemon stores it (`observations.instances`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Leaf {
    /// Predicted centre `[x, y]`, image pixels.
    pub centre: [f32; 2],
    /// Bounding box `[x0, y0, x1, y1]`, image pixels.
    pub bbox: [u32; 4],
}

/// One view of a session: its name, the image, and its leaf instances.
#[derive(Debug, Clone)]
pub struct ViewLeaves {
    /// View name (`SV_108`).
    pub view: String,
    /// The image, relative to the drop directory.
    pub image: String,
    /// Leaf instances.
    pub leaves: Vec<Leaf>,
}

/// Where a new leaf was found.
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// View it was found in.
    pub view: String,
    /// The image, relative to the drop directory.
    pub image: String,
    /// The leaf instance.
    pub leaf: Leaf,
    /// False when every instance of the view had a partner the session
    /// before and the highest was taken instead.
    pub unmatched: bool,
}

/// Reads the leaf instances (class 1) out of a stored `instances` JSON array;
/// empty when it holds none or is not one (imported counts).
pub fn leaves_of(instances: &serde_json::Value) -> Vec<Leaf> {
    #[derive(Deserialize)]
    struct Stored {
        class: u8,
        #[serde(flatten)]
        leaf: Leaf,
    }
    instances
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|v| serde_json::from_value::<Stored>(v.clone()).ok())
                .filter(|s| s.class == phyllo_contract::LEAF)
                .map(|s| s.leaf)
                .collect()
        })
        .unwrap_or_default()
}

/// Sites of the `n` leaves new in `after` against `before`, newest leaf
/// first; empty when no side view of `after` has leaf instances.
pub fn locate(before: &[ViewLeaves], after: &[ViewLeaves], n: usize) -> Vec<Site> {
    let side = |v: &ViewLeaves| v.view.starts_with("SV");
    // The view whose count rose most shows the new leaves most plainly; ties
    // go to the one with more leaves seen.
    let best = after
        .iter()
        .filter(|v| side(v) && !v.leaves.is_empty())
        .max_by_key(|v| {
            let prev = before
                .iter()
                .find(|b| b.view == v.view)
                .map_or(0, |b| b.leaves.len());
            (v.leaves.len() as i64 - prev as i64, v.leaves.len())
        });
    let Some(view) = best else {
        return Vec::new();
    };
    let prev: &[Leaf] = before
        .iter()
        .find(|b| b.view == view.view)
        .map_or(&[], |b| b.leaves.as_slice());
    let partnered = match_nearest(prev, &view.leaves);
    let mut new: Vec<&Leaf> = view
        .leaves
        .iter()
        .zip(&partnered)
        .filter(|(_, p)| !**p)
        .map(|(l, _)| l)
        .collect();
    let unmatched = !new.is_empty();
    if !unmatched {
        new = view.leaves.iter().collect();
    }
    // Highest first: the smallest top edge, then the highest centre.
    new.sort_by(|a, b| {
        (a.bbox[1], a.centre[1])
            .partial_cmp(&(b.bbox[1], b.centre[1]))
            .expect("finite")
    });
    new.into_iter()
        .take(n.max(1))
        .map(|l| Site {
            view: view.view.clone(),
            image: view.image.clone(),
            leaf: *l,
            unmatched,
        })
        .collect()
}

/// For each leaf of `after`, whether it has a partner in `before`: pairs
/// taken nearest centres first, each leaf at most once, no farther apart
/// than a quarter of the plant's height in `after`.
fn match_nearest(before: &[Leaf], after: &[Leaf]) -> Vec<bool> {
    let top = after.iter().map(|l| l.bbox[1]).min().unwrap_or(0);
    let bottom = after.iter().map(|l| l.bbox[3]).max().unwrap_or(0);
    let reach = (0.25 * f64::from(bottom.saturating_sub(top))).max(8.0);
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, b) in before.iter().enumerate() {
        for (j, a) in after.iter().enumerate() {
            let d = f64::from(b.centre[0] - a.centre[0]).hypot(f64::from(b.centre[1] - a.centre[1]));
            if d <= reach {
                pairs.push((d, i, j));
            }
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (mut used_b, mut used_a) = (vec![false; before.len()], vec![false; after.len()]);
    for (_, i, j) in pairs {
        if !used_b[i] && !used_a[j] {
            used_b[i] = true;
            used_a[j] = true;
        }
    }
    used_a
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(x: f32, y: f32, top: u32, bottom: u32) -> Leaf {
        Leaf {
            centre: [x, y],
            bbox: [x as u32 - 10, top, x as u32 + 10, bottom],
        }
    }

    fn view(name: &str, leaves: Vec<Leaf>) -> ViewLeaves {
        ViewLeaves {
            view: name.into(),
            image: format!("{name}.png"),
            leaves,
        }
    }

    #[test]
    fn the_new_leaf_is_the_one_without_a_partner() {
        let old = vec![
            leaf(100.0, 400.0, 350, 450),
            leaf(200.0, 380.0, 300, 420),
            leaf(150.0, 250.0, 200, 300),
        ];
        // Overnight every leaf moved a little; a new one came out beside the whorl,
        // lower than the old top leaf's tip.
        let mut now: Vec<Leaf> = old
            .iter()
            .map(|l| leaf(l.centre[0] + 4.0, l.centre[1] - 3.0, l.bbox[1] - 3, l.bbox[3] - 3))
            .collect();
        let fresh = leaf(160.0, 230.0, 215, 245);
        now.push(fresh);
        let sites = locate(&[view("SV_0", old)], &[view("SV_0", now)], 1);
        assert_eq!(sites.len(), 1);
        assert_eq!(sites[0].leaf, fresh);
        assert!(sites[0].unmatched);
        assert_eq!(sites[0].image, "SV_0.png");
    }

    #[test]
    fn the_view_whose_count_rose_most_is_used_and_top_views_never() {
        let a = vec![leaf(100.0, 400.0, 350, 450)];
        let b = vec![leaf(100.0, 400.0, 350, 450), leaf(300.0, 100.0, 80, 120)];
        let before = [
            view("SV_0", a.clone()),
            view("SV_72", a.clone()),
            view("TV_90", vec![]),
        ];
        let after = [
            view("SV_0", a.clone()),
            view("SV_72", b.clone()),
            view("TV_90", vec![leaf(50.0, 50.0, 0, 100), leaf(60.0, 60.0, 0, 100)]),
        ];
        let sites = locate(&before, &after, 1);
        assert_eq!(sites[0].view, "SV_72");
        assert_eq!(sites[0].leaf, b[1]);
    }

    #[test]
    fn two_new_leaves_come_highest_first_and_a_full_match_falls_back_to_the_top() {
        let old = vec![leaf(100.0, 400.0, 350, 450)];
        let low_new = leaf(300.0, 300.0, 280, 320);
        let high_new = leaf(200.0, 150.0, 120, 180);
        let now = vec![old[0], low_new, high_new];
        let sites = locate(&[view("SV_0", old.clone())], &[view("SV_0", now)], 2);
        assert_eq!(
            sites.iter().map(|s| s.leaf).collect::<Vec<_>>(),
            vec![high_new, low_new]
        );
        let same = locate(&[view("SV_0", old.clone())], &[view("SV_0", old.clone())], 1);
        assert_eq!(same[0].leaf, old[0]);
        assert!(!same[0].unmatched);
        assert!(locate(&[], &[view("SV_0", vec![])], 1).is_empty());
    }

    #[test]
    fn stored_instances_give_their_leaves_only() {
        let v = serde_json::json!([
            {"id": 1, "class": 1, "class_name": "leaf", "area": 90, "bbox": [1, 2, 3, 4], "centre": [2.0, 3.0], "score": 0.8},
            {"id": 2, "class": 3, "class_name": "panicle", "area": 50, "bbox": [5, 6, 7, 8], "centre": [6.0, 7.0], "score": 0.5}
        ]);
        assert_eq!(
            leaves_of(&v),
            vec![Leaf {
                centre: [2.0, 3.0],
                bbox: [1, 2, 3, 4]
            }]
        );
        assert!(leaves_of(&serde_json::json!([])).is_empty());
        assert!(leaves_of(&serde_json::Value::Null).is_empty());
    }
}
