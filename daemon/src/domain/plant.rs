//! The plant and session rows the domain computes on and the store keeps:
//! one plant's timeline as `phyllo timeline` shows it.

use std::collections::BTreeMap;

use serde::Serialize;

/// Everything `phyllo timeline` shows for one plant.
#[derive(Debug, Clone, Serialize)]
pub struct PlantTimeline {
    /// Plant id.
    pub plant: String,
    /// Days per leaf.
    pub phyllochron_days: Option<f64>,
    /// Degree-days per leaf above `[timeline] base_temp_c`, with a temperature
    /// log covering its leaves ([`crate::domain::thermal`]).
    pub phyllochron_cd: Option<f64>,
    /// The zone whose temperature log times it ([`crate::domain::climate_zone`]);
    /// `""` for the facility's.
    pub climate_zone: String,
    /// The leaf that comes next and when it should appear ([`crate::domain::forecast`]).
    pub next_leaf: Option<NextLeafRow>,
    /// Sessions: start, per-view counts, fused, leaves emerged, living.
    pub sessions: Vec<SessionRow>,
    /// Emergence events: leaf, estimated time, first seen.
    pub events: Vec<(u32, String, String)>,
    /// Where the leaves of `events` emerged, for those located ([`crate::domain::leaf_site`]).
    pub sites: Vec<LeafSiteRow>,
}

/// Where one new leaf emerged, as stored with its event.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeafSiteRow {
    /// Leaf number.
    pub leaf: u32,
    /// The view it was found in.
    pub view: String,
    /// The image, relative to the drop directory.
    pub image: String,
    /// The leaf instance's predicted centre, image pixels.
    pub centre: [f64; 2],
    /// Its bounding box `[x0, y0, x1, y1]`.
    pub bbox: [u32; 4],
    /// Its area, image pixels.
    pub area: i64,
}

/// A plant's next leaf as stored ([`crate::domain::forecast`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NextLeafRow {
    /// Its number.
    pub leaf: u32,
    /// When it should appear (facility local time, ISO 8601).
    pub expected: String,
}

/// One session row of a plant timeline.
#[derive(Debug, Clone, Serialize)]
pub struct SessionRow {
    /// First image of the session.
    pub start: String,
    /// Count per view.
    pub views: BTreeMap<String, f64>,
    /// Fused count.
    pub fused: f64,
    /// Leaves emerged (non-decreasing fit).
    pub leaves_emerged: f64,
    /// Living leaves, smoothed.
    pub living: f64,
    /// Leaves read as dead by this session.
    pub leaves_lost: f64,
}
