//! Where a new leaf emerged: the leaf instance, in the images of the session
//! that first counted it, that is the new leaf.
//!
//! The paper dated each new leaf but could not say which leaf it was. A leaf
//! just out of the whorl shows only its tip, so it is taken to be the
//! smallest leaf instance of a side view. Which view: the turntable turns the
//! plant but keeps heights, so where views see the same new tip their
//! smallest instances sit at about the same height; the view whose smallest
//! instance agrees in height (within [`AGREE_SHARE`] of the plant's height)
//! with the most other views is taken; ties go to the view whose count rose
//! most since the session before, then the one seeing more leaves, then the
//! lowest angle. Several leaves new in one session get that view's smallest
//! instances, the newest leaf the smallest. Measured on rendered sequences
//! with the model in the loop (`scripts/leaf-site-accuracy.sh`,
//! docs/daemon.md "Where each new leaf emerged").

use serde::Deserialize;

/// One leaf instance as the daemon stores it (`observations.instances`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Leaf {
    /// Predicted centre `[x, y]`, image pixels.
    pub centre: [f32; 2],
    /// Bounding box `[x0, y0, x1, y1]`, image pixels.
    pub bbox: [u32; 4],
    /// Area in image pixels.
    pub area: u64,
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
                .filter_map(|v| Stored::deserialize(v).ok())
                .filter(|s| s.class == phyllo_contract::LEAF)
                .map(|s| s.leaf)
                .collect()
        })
        .unwrap_or_default()
}

/// Views whose smallest leaf instances lie within this share of the
/// plant's height of each other are taken to see the same new leaf.
pub const AGREE_SHARE: f32 = 0.05;

/// Sites of the `n` leaves new in `after` against `before`, newest leaf
/// first; empty when no side view of `after` has leaf instances.
pub fn locate(before: &[ViewLeaves], after: &[ViewLeaves], n: usize) -> Vec<Site> {
    let mut views: Vec<&ViewLeaves> = after
        .iter()
        .filter(|v| v.view.starts_with("SV") && !v.leaves.is_empty())
        .collect();
    // Angle order, so the same images give the same site whatever order they came in.
    views.sort_by_key(|v| {
        let angle = v.view.get(3..).and_then(|a| a.parse::<u32>().ok());
        (angle.unwrap_or(u32::MAX), v.view.clone())
    });
    let smallest = |v: &ViewLeaves| {
        *v.leaves
            .iter()
            .min_by_key(|l| l.area)
            .expect("a view with leaves")
    };
    let agree = |v: &ViewLeaves| {
        let top = v.leaves.iter().map(|l| l.bbox[1]).min().unwrap_or(0);
        let bottom = v.leaves.iter().map(|l| l.bbox[3]).max().unwrap_or(0);
        let reach = AGREE_SHARE * bottom.saturating_sub(top) as f32;
        let y = smallest(v).centre[1];
        views
            .iter()
            .filter(|w| w.view != v.view && (smallest(w).centre[1] - y).abs() <= reach)
            .count()
    };
    let key = |v: &ViewLeaves| {
        let prev = before
            .iter()
            .find(|b| b.view == v.view)
            .map_or(0, |b| b.leaves.len());
        (agree(v), v.leaves.len() as i64 - prev as i64, v.leaves.len())
    };
    let mut best: Option<&ViewLeaves> = None;
    for &v in &views {
        // Strictly greater: a tie keeps the lower angle.
        if best.is_none_or(|b| key(v) > key(b)) {
            best = Some(v);
        }
    }
    let Some(view) = best else {
        return Vec::new();
    };
    let mut leaves: Vec<&Leaf> = view.leaves.iter().collect();
    leaves.sort_by_key(|l| l.area);
    leaves
        .into_iter()
        .take(n.max(1))
        .map(|l| Site {
            view: view.view.clone(),
            image: view.image.clone(),
            leaf: *l,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(x: f32, y: f32, area: u64) -> Leaf {
        Leaf {
            centre: [x, y],
            bbox: [x as u32 - 10, y as u32 - 10, x as u32 + 10, y as u32 + 10],
            area,
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
    fn the_new_leaf_is_the_smallest_in_the_view_whose_count_rose_most() {
        let old = vec![leaf(100.0, 400.0, 900), leaf(200.0, 380.0, 700)];
        let tip = leaf(160.0, 300.0, 40);
        let mut grown = old.clone();
        grown.push(tip);
        let before = [
            view("SV_0", old.clone()),
            view("SV_72", old.clone()),
            view("TV_90", vec![]),
        ];
        let after = [
            view("SV_0", old.clone()),
            view("SV_72", grown),
            // A top view is never used, however its count moved.
            view(
                "TV_90",
                vec![leaf(50.0, 50.0, 5), leaf(60.0, 60.0, 5), leaf(70.0, 70.0, 5)],
            ),
        ];
        let sites = locate(&before, &after, 1);
        assert_eq!(sites.len(), 1);
        assert_eq!(
            (sites[0].view.as_str(), sites[0].image.as_str(), sites[0].leaf),
            ("SV_72", "SV_72.png", tip)
        );
    }

    #[test]
    fn views_that_agree_on_the_new_tips_height_outvote_one_whose_count_rose() {
        let base = [leaf(100.0, 400.0, 900), leaf(200.0, 300.0, 700)];
        let with = |extra: Leaf| {
            let mut v = base.to_vec();
            v.push(extra);
            v
        };
        // SV_36 and SV_108 see a tip at the same height; SV_0 splits an old
        // leaf into one more, smaller piece low down.
        let after = [
            view(
                "SV_0",
                with(leaf(90.0, 420.0, 20))
                    .into_iter()
                    .chain([leaf(95.0, 430.0, 25)])
                    .collect(),
            ),
            view("SV_36", with(leaf(150.0, 250.0, 40))),
            view("SV_108", with(leaf(170.0, 252.0, 45))),
        ];
        let before: Vec<ViewLeaves> = after.iter().map(|v| view(&v.view, base.to_vec())).collect();
        let sites = locate(&before, &after, 1);
        assert_eq!(
            (sites[0].view.as_str(), sites[0].leaf.centre),
            ("SV_36", [150.0, 250.0])
        );
        // The same images in another order: the same site.
        let reversed: Vec<ViewLeaves> = after.iter().rev().cloned().collect();
        assert_eq!(locate(&before, &reversed, 1), sites);
    }

    #[test]
    fn two_new_leaves_come_smallest_first_and_ties_keep_the_first_view() {
        let old = vec![leaf(100.0, 400.0, 900)];
        let (younger, older) = (leaf(150.0, 200.0, 30), leaf(300.0, 300.0, 120));
        let now = vec![old[0], older, younger];
        let sites = locate(
            &[view("SV_0", old.clone()), view("SV_36", old.clone())],
            &[view("SV_0", now.clone()), view("SV_36", now)],
            2,
        );
        assert_eq!(
            sites.iter().map(|s| s.leaf).collect::<Vec<_>>(),
            vec![younger, older]
        );
        assert!(sites.iter().all(|s| s.view == "SV_0"));
        assert!(locate(&[], &[view("SV_0", vec![])], 1).is_empty());
    }

    /// Issue 41: a chamber whose camera zooms in mid-season: the views of
    /// one session share the zoom and the rule compares heights within a
    /// view as shares of the plant's height, so the site is the same leaf.
    #[test]
    fn a_camera_zoomed_since_the_session_before_finds_the_same_site() {
        let old = vec![leaf(100.0, 400.0, 900), leaf(200.0, 300.0, 700)];
        let tip = leaf(160.0, 250.0, 40);
        let mut grown = old.clone();
        grown.push(tip);
        let before = [view("SV_0", old.clone()), view("SV_72", old.clone())];
        let zoom = |leaves: &[Leaf]| -> Vec<Leaf> {
            leaves
                .iter()
                .map(|l| Leaf {
                    centre: [2.0 * l.centre[0], 2.0 * l.centre[1]],
                    bbox: l.bbox.map(|v| 2 * v),
                    area: 4 * l.area,
                })
                .collect()
        };
        let plain = locate(
            &before,
            &[view("SV_0", old.clone()), view("SV_72", grown.clone())],
            1,
        );
        let zoomed = locate(
            &before,
            &[view("SV_0", zoom(&old)), view("SV_72", zoom(&grown))],
            1,
        );
        assert_eq!((plain[0].view.as_str(), plain[0].leaf), ("SV_72", tip));
        assert_eq!(
            (zoomed[0].view.as_str(), zoomed[0].leaf),
            ("SV_72", zoom(&[tip])[0])
        );
    }

    #[test]
    fn views_named_without_an_angle_are_ranked_last_not_a_panic() {
        let l = vec![leaf(100.0, 100.0, 50)];
        let after = [
            view("SV", l.clone()),
            view("SV_x", l.clone()),
            view("SV_144", l.clone()),
        ];
        assert_eq!(locate(&[], &after, 1)[0].view, "SV_144");
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
                bbox: [1, 2, 3, 4],
                area: 90
            }]
        );
        assert!(leaves_of(&serde_json::json!([])).is_empty());
        assert!(leaves_of(&serde_json::Value::Null).is_empty());
    }
}
