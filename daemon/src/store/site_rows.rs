//! From a plant's stored observations to each emergence event's site
//! ([`crate::domain::leaf_site`]): the sessions around the one that first counted a
//! leaf, their images' leaf instances, one site per new leaf.

use chrono::NaiveDateTime;

use crate::domain::leaf_site::{self, Site, ViewLeaves};
use crate::domain::timeline::Timeline;

/// One counted image of the plant, its instances as stored (JSON text).
#[derive(Debug, Clone)]
pub(super) struct SeenRow {
    pub taken_at: NaiveDateTime,
    pub view: String,
    pub image: String,
    pub instances: String,
}

/// A site for each of `tl.events` (in order), `None` where the session that
/// first counted the leaf, or the one before it, has no image-backed counts
/// (imported counts carry no instances).
pub(super) fn event_sites(tl: &Timeline, seen: &[SeenRow]) -> Vec<Option<Site>> {
    let starts: Vec<NaiveDateTime> = tl.sessions.iter().map(|s| s.start).collect();
    let mut out: Vec<Option<Site>> = vec![None; tl.events.len()];
    let mut i = 0;
    while i < tl.events.len() {
        // Leaves first counted in the same session share its images.
        let seen_at = tl.events[i].seen_at;
        let j = i + tl.events[i..].iter().take_while(|e| e.seen_at == seen_at).count();
        if let Some(k) = starts.iter().position(|&s| s == seen_at).filter(|&k| k > 0) {
            let before = views_between(seen, starts[k - 1], Some(starts[k]));
            let after = views_between(seen, starts[k], starts.get(k + 1).copied());
            let sites = leaf_site::locate(&before, &after, j - i);
            // The highest new instance to the newest leaf.
            for (slot, site) in out[i..j].iter_mut().rev().zip(sites) {
                *slot = Some(site);
            }
        }
        i = j;
    }
    out
}

/// Each view's latest image taken in `[from, until)`, with its leaves.
fn views_between(seen: &[SeenRow], from: NaiveDateTime, until: Option<NaiveDateTime>) -> Vec<ViewLeaves> {
    let mut rows: Vec<&SeenRow> = seen
        .iter()
        .filter(|r| r.taken_at >= from && until.is_none_or(|u| r.taken_at < u))
        .collect();
    rows.sort_by_key(|r| r.taken_at);
    let mut views: Vec<ViewLeaves> = Vec::new();
    for r in rows {
        let leaves = leaf_site::leaves_of(&serde_json::from_str(&r.instances).unwrap_or_default());
        let v = ViewLeaves {
            view: r.view.clone(),
            image: r.image.clone(),
            leaves,
        };
        match views.iter_mut().find(|x| x.view == r.view) {
            Some(slot) => *slot = v,
            None => views.push(v),
        }
    }
    views
}
