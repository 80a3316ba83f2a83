//! Days to check: the plant sessions whose reading is most in doubt, ranked
//! for a person to count by hand and bring back with `phyllo import`.
//!
//! No one recounts a thousand plant-days, but a few dozen a week is within
//! reach. The fit (leaves emerged, never falling, less the leaves read as
//! lost) is what the timeline believes the plant had; a session whose fused
//! count sits off that fit is one the fit overruled, where either that day's
//! count or the fit around it is wrong. Sessions where most side views
//! differ from the fused count follow. On the rendered sequences of
//! `scripts/timeline-accuracy.sh` both kinds are wrong far more often than
//! the rest (docs/daemon.md, "Days to check"). Ties are broken by how many
//! side views differ, then by recency.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::domain::names::View;
use crate::domain::plant::PlantTimeline;

/// How many days to check a nightly export lists.
pub const NIGHTLY: usize = 20;

/// One plant session in doubt.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Doubt {
    /// Plant id.
    pub plant: String,
    /// The session's first image (facility local time, ISO 8601).
    pub start: String,
    /// The plant's next session, if any: the session's images lie before it.
    pub until: Option<String>,
    /// Count per view.
    pub views: BTreeMap<String, f64>,
    /// The fused count of the session.
    pub fused: f64,
    /// What the fit holds for that session: leaves emerged less leaves lost.
    pub fit: f64,
    /// |fused − fit|.
    pub off_fit: f64,
    /// Side views whose count differs from the fused count.
    pub views_differing: usize,
    /// Side views in the session.
    pub side_views: usize,
}

impl Doubt {
    /// Why the session is in doubt, in words.
    pub fn why(&self) -> String {
        let mut parts = Vec::new();
        if self.off_fit > 0.0 {
            // In whole leaves, as the exports and `tail` give them: nobody
            // counts half a leaf.
            parts.push(format!(
                "count {} where the timeline has {}",
                trim(self.fused),
                crate::domain::timeline::whole_leaves(self.fit)
            ));
        }
        if self.views_differing > 0 {
            parts.push(format!(
                "{} of {} side views differ",
                self.views_differing, self.side_views
            ));
        }
        parts.join("; ")
    }
}

/// A count without a trailing `.0`; fits may be fractional.
fn trim(x: f64) -> String {
    if x.fract() == 0.0 {
        format!("{x:.0}")
    } else {
        format!("{x:.2}")
    }
}

/// The sessions in doubt, most doubtful first: those whose fused count is
/// off the fit, or where most side views differ from the fused count.
/// Sessions a person has counted are left out; `since` (an ISO date or
/// date-time) keeps the sessions from then on.
pub fn rank(plants: &[PlantTimeline], since: Option<&str>) -> Vec<Doubt> {
    let mut out = Vec::new();
    for p in plants {
        for (i, s) in p.sessions.iter().enumerate() {
            if since.is_some_and(|t| s.start.as_str() < t) {
                continue;
            }
            let views: Vec<View> = s.views.keys().map(|k| View::parse(k)).collect();
            if views.iter().any(View::is_person) {
                continue;
            }
            let side: Vec<f64> = s
                .views
                .iter()
                .zip(&views)
                .filter(|(_, v)| matches!(v, View::Side(_)))
                .map(|((_, &c), _)| c)
                .collect();
            let fit = s.leaves_emerged - s.leaves_lost;
            let off_fit = (s.fused - fit).abs();
            // Counts are whole; anything under a hundredth is rounding in the fit.
            let off_fit = if off_fit < 0.01 { 0.0 } else { off_fit };
            let views_differing = side.iter().filter(|&&c| (c - s.fused).abs() >= 0.5).count();
            if off_fit == 0.0 && 2 * views_differing <= side.len() {
                continue;
            }
            out.push(Doubt {
                plant: p.plant.clone(),
                start: s.start.clone(),
                until: p.sessions.get(i + 1).map(|n| n.start.clone()),
                views: s.views.clone(),
                fused: s.fused,
                fit,
                off_fit,
                views_differing,
                side_views: side.len(),
            });
        }
    }
    out.sort_by(|a, b| {
        b.off_fit
            .total_cmp(&a.off_fit)
            .then(b.views_differing.cmp(&a.views_differing))
            .then(b.start.cmp(&a.start))
            .then(a.plant.cmp(&b.plant))
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::plant::SessionRow;

    fn session(start: &str, views: &[(&str, f64)], fused: f64, emerged: f64, lost: f64) -> SessionRow {
        SessionRow {
            start: start.into(),
            views: views.iter().map(|(k, c)| (k.to_string(), *c)).collect(),
            fused,
            leaves_emerged: emerged,
            living: fused,
            leaves_lost: lost,
        }
    }

    fn plant(name: &str, sessions: Vec<SessionRow>) -> PlantTimeline {
        PlantTimeline {
            plant: name.into(),
            phyllochron_days: None,
            phyllochron_cd: None,
            climate_zone: String::new(),
            next_leaf: None,
            sessions,
            events: Vec::new(),
            sites: Vec::new(),
        }
    }

    #[test]
    fn sessions_off_their_fit_come_first_and_checked_ones_not_at_all() {
        let five = |c: [f64; 5]| -> Vec<(&'static str, f64)> {
            ["SV_0", "SV_36", "SV_72", "SV_108", "SV_144"]
                .into_iter()
                .zip(c)
                .collect()
        };
        let plants = [
            plant(
                "A",
                vec![
                    session("2026-11-01T08:00:00", &five([6.; 5]), 6., 6., 0.),
                    // The fit overruled a count of 8 (a fused 8, the fit 7).
                    session("2026-11-02T08:00:00", &five([8., 8., 7., 7., 8.]), 8., 7., 0.),
                    // One view of five differs: not in doubt; three of five: in doubt.
                    session("2026-11-03T08:00:00", &five([7., 7., 7., 6., 7.]), 7., 7., 0.),
                    session("2026-11-04T08:00:00", &five([7., 7., 6., 6., 8.]), 7., 7., 0.),
                ],
            ),
            plant(
                "B",
                vec![
                    // Off by two, but a person has counted it.
                    session("2026-11-02T08:00:00", &[("SV_0", 9.), ("human", 7.)], 7., 9., 0.),
                    // A leaf read as lost: the fit is 9 − 1 = 8, as counted.
                    session("2026-11-03T08:00:00", &five([8.; 5]), 8., 9., 1.),
                    session("2026-11-04T08:00:00", &five([9., 8., 8., 8., 8.]), 8., 9., 0.),
                    // The top view's disagreement does not count.
                    session("2026-11-05T08:00:00", &[("SV_0", 9.), ("TV_90", 6.)], 9., 9., 0.),
                ],
            ),
        ];
        let got = rank(&plants, None);
        let keys: Vec<(&str, &str, f64, usize)> = got
            .iter()
            .map(|d| (d.plant.as_str(), &d.start[..10], d.off_fit, d.views_differing))
            .collect();
        assert_eq!(
            keys,
            [
                ("A", "2026-11-02", 1.0, 2),
                ("B", "2026-11-04", 1.0, 1),
                ("A", "2026-11-04", 0.0, 3)
            ]
        );
        assert_eq!(
            got[0].why(),
            "count 8 where the timeline has 7; 2 of 5 side views differ"
        );
        assert_eq!(got[2].why(), "3 of 5 side views differ");
        let recent = rank(&plants, Some("2026-11-04"));
        assert_eq!(recent.len(), 2);
        assert!(recent.iter().all(|d| d.start.as_str() >= "2026-11-03"));
    }
}
