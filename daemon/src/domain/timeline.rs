//! Temporal coherence: from per-image counts to a plant's timeline.
//!
//! Pure functions, no I/O: the store feeds them all of a plant's observations
//! and writes back what they return, so a late or out-of-order image simply
//! changes the input of the next recomputation.
//!
//! 1. **Sessions.** A plant's observations are sorted by time and cut wherever
//!    two consecutive images are more than `session_gap_minutes` apart. The
//!    facility images each plant once a day, a few seconds per view.
//! 2. **View fusion.** One count per session, by a [`FusionRule`]. The default,
//!    `second-max-side`, takes the second-largest side-view count (the top view
//!    undercounts and is used only when a session has no side view). For
//!    people counting, the largest view is closest to the truth (occlusion only
//!    hides leaves), but a model also over-counts some views (a leaf cut in
//!    two), and the largest count keeps every such error; the largest count
//!    that two views reach keeps the first and outvotes the second. On 1080
//!    rendered plant-days it counted 85.6 % exactly, the median 79.9 % and the
//!    largest 73.7 % (`scripts/timeline-accuracy.sh`, docs/daemon.md).
//! 3. **Leaves emerged** never decreases: a weighted isotonic regression
//!    ([`isotonic`], pool-adjacent-violators) of the fused counts, each session
//!    weighted by its number of views. Leaf *k* emerged when the fit crosses
//!    *k − ½*; the date is interpolated linearly between the two sessions it
//!    crosses between (the leaf became countable somewhere in that interval).
//!    Leaves already present at the first session have no known date and get
//!    no event. The phyllochron is the least-squares slope of emergence time
//!    (days) against leaf number.
//!    Old leaves die, and the model counts living leaves only, so from the
//!    first death on the fused count lags the leaves emerged. With a
//!    `death_penalty` λ > 0 (default 2.5), [`deaths`] first reads lasting drops
//!    as leaves lost: it fits a whole-leaf living count to every side view's
//!    count, where a rise is free and each leaf lost costs as much as λ
//!    views that disagree with the fit, and ties keep the count (so the views
//!    showing a one-leaf drop must outnumber those that do not by more than
//!    λ, summed over sessions: four of five side views on one day). The isotonic
//!    fit then runs on fused + lost, so leaves after a death keep their numbers.
//!    On two rendered sequences this dated emergences after the first death
//!    with MAE 2.05 and 2.03 d instead of 4.11 and 4.22 d
//!    (`scripts/timeline-accuracy.sh`, docs/daemon.md).
//! 4. **Living leaves** may fall when old leaves senesce: a centred moving
//!    median of the fused counts (window `living_window`), which removes
//!    one-session spikes but keeps lasting drops.

use anyhow::bail;
use chrono::{Duration, NaiveDateTime};
use serde::Deserialize;

use crate::domain::climate_zone::ZoneConfig;
use crate::domain::least_squares;
use crate::domain::names::View;

/// `[timeline]`: view fusion and the fits across sessions.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimelineConfig {
    /// How one session's views become one count: `second-max-side` (the
    /// second-largest side-view count; top view only if there is no side view),
    /// `max-side`, `median-side`, `mean-side`, `max` (all views), or
    /// `view:SV_108` (that view, else `second-max-side`).
    pub fusion: String,
    /// Images of a plant less than this many minutes apart belong to the same
    /// imaging session.
    pub session_gap_minutes: f64,
    /// Window (sessions, odd) of the centred moving median that smooths living
    /// leaves; 1 disables smoothing.
    pub living_window: usize,
    /// Cost of one lost leaf when lasting drops of the side views' counts are
    /// read as leaves that died, so later leaves keep their numbers: the views
    /// showing a one-leaf drop must outnumber those that do not by more than
    /// this, summed over sessions; 0 reads no deaths.
    pub death_penalty: f64,
    /// Base temperature (°C) of the thermal phyllochron, in degree-days per
    /// leaf above it, once `phyllo import` has a temperature log: about 10
    /// for sorghum, 8 to 10 for maize.
    pub base_temp_c: f64,
    /// Greenhouse compartments with temperature logs of their own
    /// (`[[timeline.zones]]`); a plant takes the first whose `plants`
    /// expression matches its id, else the facility's log.
    pub zones: Vec<ZoneConfig>,
}

impl Default for TimelineConfig {
    fn default() -> Self {
        Self {
            fusion: "second-max-side".into(),
            session_gap_minutes: 120.0,
            living_window: 3,
            death_penalty: 2.5,
            base_temp_c: 10.0,
            zones: Vec::new(),
        }
    }
}

/// How the views of one imaging session are fused into one count.
#[derive(Debug, Clone, PartialEq)]
pub enum FusionRule {
    /// Largest side-view count (top view only when there is no side view).
    MaxSide,
    /// Second-largest side-view count: the largest count that two side views
    /// reach, so one view's over-count is outvoted (the only side view when
    /// there is one; the top view only when there is no side view).
    SecondMaxSide,
    /// Largest count over all views, top included.
    Max,
    /// Median of the side-view counts.
    MedianSide,
    /// Mean of the side-view counts.
    MeanSide,
    /// The count of one view (mean if repeated); `second-max-side` when it is missing.
    View(View),
}

impl FusionRule {
    /// Parses `second-max-side`, `max-side`, `max`, `median-side`, `mean-side`
    /// or `view:<VIEW>`.
    pub fn parse(s: &str) -> anyhow::Result<FusionRule> {
        Ok(match s {
            "second-max-side" => FusionRule::SecondMaxSide,
            "max-side" => FusionRule::MaxSide,
            "max" => FusionRule::Max,
            "median-side" => FusionRule::MedianSide,
            "mean-side" => FusionRule::MeanSide,
            _ => match s.strip_prefix("view:") {
                Some(v) if !v.is_empty() => FusionRule::View(View::parse(v)),
                _ => bail!(
                    "timeline.fusion: unknown rule '{s}' (second-max-side, max-side, max, median-side, mean-side, view:SV_108)"
                ),
            },
        })
    }

    /// Fuses one session's `(view, count)` pairs. `None` if there are none.
    /// A person's count (a correction, [`View::is_person`]) overrides every
    /// rule: the session's count is the mean of the people's.
    pub fn fuse(&self, views: &[(View, f64)]) -> Option<f64> {
        if let Some(people) = person_mean(views) {
            return Some(people);
        }
        let all: Vec<f64> = views.iter().map(|(_, c)| *c).collect();
        let pool = &side_counts(views);
        if pool.is_empty() {
            return None;
        }
        let max = |xs: &[f64]| xs.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        Some(match self {
            FusionRule::MaxSide => max(pool),
            FusionRule::SecondMaxSide => second_max(pool),
            FusionRule::Max => max(&all),
            FusionRule::MedianSide => median(pool),
            FusionRule::MeanSide => mean(pool),
            FusionRule::View(want) => {
                let hit: Vec<f64> = views.iter().filter(|(v, _)| v == want).map(|(_, c)| *c).collect();
                if hit.is_empty() {
                    second_max(pool)
                } else {
                    mean(&hit)
                }
            }
        })
    }
}

/// The mean of the people's counts in a session (imported corrections),
/// `None` when no person counted.
fn person_mean(views: &[(View, f64)]) -> Option<f64> {
    let people: Vec<f64> = views
        .iter()
        .filter(|(v, _)| v.is_person())
        .map(|(_, c)| *c)
        .collect();
    (!people.is_empty()).then(|| mean(&people))
}

/// Mean of `xs` (not empty).
fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// How many agreeing views a person's count stands for when [`deaths`]
/// weighs a session: a full day's views, so a correction decides its day.
const PERSON_AS_VIEWS: usize = 5;

/// What a session tells [`deaths`]: its side views' counts, or, where a
/// person counted, that count as a full day's agreeing views.
fn death_evidence(views: &[(View, f64)]) -> Vec<f64> {
    match person_mean(views) {
        Some(people) => vec![people; PERSON_AS_VIEWS],
        None => side_views(views),
    }
}

/// The side views' counts (none when a session has only top views).
fn side_views(views: &[(View, f64)]) -> Vec<f64> {
    views
        .iter()
        .filter(|(v, _)| !v.is_top())
        .map(|(_, c)| *c)
        .collect()
}

/// The side views' counts; every count when a session has only top views.
fn side_counts(views: &[(View, f64)]) -> Vec<f64> {
    let side = side_views(views);
    if side.is_empty() {
        views.iter().map(|(_, c)| *c).collect()
    } else {
        side
    }
}

/// Second-largest value (the only one of a single value); `xs` is not empty.
fn second_max(xs: &[f64]) -> f64 {
    let mut v = xs.to_vec();
    v.sort_by(|a, b| b.total_cmp(a));
    v[1.min(v.len() - 1)]
}

fn median(xs: &[f64]) -> f64 {
    let mut v = xs.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// The largest leaf count accepted (`phyllo import` rejects larger ones): far
/// above any plant's, it bounds the work of [`deaths`].
pub const MAX_COUNT: u32 = 1000;

/// A fitted leaf count in whole leaves, as every output a person reads
/// gives it: the leaves the fit has reached (12.5 is 12). Applied to the
/// non-decreasing fit of leaves emerged, it never decreases either.
pub fn whole_leaves(fit: f64) -> u32 {
    // The epsilon keeps 12.999999999 (a sum of fractions) at 13.
    (fit + 1e-9).floor().max(0.0) as u32
}

/// Parameters of the timeline fit (from `[timeline]`).
#[derive(Debug, Clone)]
pub struct TimelineParams {
    /// View fusion rule.
    pub fusion: FusionRule,
    /// Gap that starts a new imaging session.
    pub session_gap: Duration,
    /// Odd window of the living-leaves moving median.
    pub living_window: usize,
    /// Cost of one lost leaf in [`deaths`]; 0 reads no deaths.
    pub death_penalty: f64,
    /// Base temperature of the thermal phyllochron ([`crate::domain::thermal`]).
    pub base_temp_c: f64,
    /// Which temperature log times each plant ([`crate::domain::climate_zone`]).
    pub zones: crate::domain::climate_zone::ZoneRules,
    /// The section these were compiled from, as written: the store keeps its
    /// text to notice a changed setting and refit.
    pub source: TimelineConfig,
}

impl TimelineParams {
    /// Builds the parameters from the config section (already validated).
    pub fn from_config(cfg: &TimelineConfig) -> anyhow::Result<TimelineParams> {
        Ok(TimelineParams {
            fusion: FusionRule::parse(&cfg.fusion)?,
            session_gap: Duration::milliseconds((cfg.session_gap_minutes * 60_000.0) as i64),
            living_window: cfg.living_window,
            death_penalty: cfg.death_penalty,
            base_temp_c: cfg.base_temp_c,
            zones: crate::domain::climate_zone::ZoneRules::from_config(&cfg.zones)?,
            source: cfg.clone(),
        })
    }
}

impl Default for TimelineParams {
    fn default() -> Self {
        Self::from_config(&TimelineConfig::default()).expect("defaults are valid")
    }
}

/// One per-image (or imported) count.
#[derive(Debug, Clone, PartialEq)]
pub struct Obs {
    /// When the image was taken.
    pub taken_at: NaiveDateTime,
    /// Camera view.
    pub view: View,
    /// Leaf count.
    pub count: f64,
}

/// One imaging session of a plant, fused and fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// Time of the session's first image; also its key.
    pub start: NaiveDateTime,
    /// Every count in the session.
    pub views: Vec<(View, f64)>,
    /// Fused count.
    pub fused: f64,
    /// Weight in the isotonic fit (number of counts; a person's counts as
    /// a full day of views).
    pub weight: f64,
    /// Leaves lost by this session, as [`deaths`] reads them.
    pub lost: f64,
    /// Leaves emerged: the non-decreasing fit.
    pub emerged: f64,
    /// Living leaves, smoothed.
    pub living: f64,
}

impl Session {
    /// A session starting at `start`, before any count joins it or any fit.
    fn open(start: NaiveDateTime) -> Session {
        Session {
            start,
            views: Vec::new(),
            fused: 0.0,
            weight: 0.0,
            lost: 0.0,
            emerged: 0.0,
            living: 0.0,
        }
    }
}

/// A leaf emergence read from the steps of the leaves-emerged fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// Leaf number (1 = first leaf).
    pub leaf: u32,
    /// Estimated emergence time.
    pub at: NaiveDateTime,
    /// Start of the first session at which the leaf was counted.
    pub seen_at: NaiveDateTime,
}

/// A plant's whole timeline.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Timeline {
    /// Sessions in time order.
    pub sessions: Vec<Session>,
    /// Emergence events in leaf order.
    pub events: Vec<Event>,
    /// Days per leaf, when at least two events are known.
    pub phyllochron_days: Option<f64>,
}

/// Weighted isotonic (non-decreasing) least-squares regression by the
/// pool-adjacent-violators algorithm, O(n).
pub fn isotonic(y: &[f64], w: &[f64]) -> Vec<f64> {
    assert_eq!(y.len(), w.len());
    // Blocks of pooled points: (weighted mean, total weight, number of points).
    let mut blocks: Vec<(f64, f64, usize)> = Vec::with_capacity(y.len());
    for (&yi, &wi) in y.iter().zip(w) {
        let wi = wi.max(f64::MIN_POSITIVE);
        blocks.push((yi, wi, 1));
        // Merge backwards while the last block is below its predecessor.
        while blocks.len() > 1 && blocks[blocks.len() - 2].0 > blocks[blocks.len() - 1].0 {
            let (m2, w2, n2) = blocks.pop().expect("len > 1");
            let (m1, w1, n1) = blocks.pop().expect("len > 1");
            let wt = w1 + w2;
            blocks.push(((m1 * w1 + m2 * w2) / wt, wt, n1 + n2));
        }
    }
    blocks
        .iter()
        .flat_map(|&(m, _, n)| std::iter::repeat_n(m, n))
        .collect()
}

/// Leaves lost by each session, read from each session's view counts: the
/// cumulative drops of the whole-leaf sequence `L` minimising
/// `Σ_sessions Σ_views min(|count − L|, 1) + penalty · Σ max(0, L[i−1] − L[i])`,
/// that is the views that disagree with `L` plus `penalty` per leaf lost.
///
/// A dead leaf never returns, so every lasting drop of the living count is a
/// leaf lost, while a rise costs nothing (leaves emerge). The penalty decides
/// how much evidence (views × sessions) a drop needs before it is believed
/// rather than taken for a miscount. Dynamic programming over `L` in
/// `0..=ceil(max count)`, O(sessions · L). A session without counts adds no
/// evidence. A penalty of 0 reads no deaths.
pub fn deaths(counts: &[Vec<f64>], penalty: f64) -> Vec<f64> {
    let top = counts.iter().flatten().fold(0.0f64, |m, &f| m.max(f)).ceil();
    // The program's tables grow with the largest count; no plant has that many leaves.
    if penalty <= 0.0 || counts.is_empty() || top.is_nan() || top > MAX_COUNT as f64 {
        return vec![0.0; counts.len()];
    }
    let top = top as usize;
    let levels = top + 1;
    // A view off by several leaves weighs no more than one off by one: a day of
    // wrong images (another plant's, say) must not buy deaths by its size.
    let err = |views: &[f64], l: usize| views.iter().map(|c| (c - l as f64).abs().min(1.0)).sum::<f64>();
    let mut cost: Vec<f64> = (0..levels).map(|l| err(&counts[0], l)).collect();
    // back[i][l]: the level at session i − 1 on the best path reaching l at session i.
    let mut back: Vec<Vec<usize>> = Vec::with_capacity(counts.len());
    back.push((0..levels).collect());
    for views in &counts[1..] {
        // Best predecessor at or below l (a rise is free); of equals the highest,
        // whose history holds the fewest deaths ...
        let mut below = vec![(0.0, 0usize); levels];
        let mut best = (f64::INFINITY, 0usize);
        for (l, &c) in cost.iter().enumerate() {
            if c <= best.0 {
                best = (c, l);
            }
            below[l] = best;
        }
        // ... and above l, each level dropped costing `penalty`.
        let mut above = vec![(f64::INFINITY, 0usize); levels];
        let mut run = (f64::INFINITY, 0usize);
        for l in (0..levels).rev() {
            run = (run.0 + penalty, run.1);
            if cost[l] < run.0 {
                run = (cost[l], l);
            }
            above[l] = run;
        }
        let mut from = vec![0usize; levels];
        let next: Vec<f64> = (0..levels)
            .map(|l| {
                // Ties keep the living count level or rising: a death must pay its way.
                let (c, k) = if below[l].0 <= above[l].0 {
                    below[l]
                } else {
                    above[l]
                };
                from[l] = k;
                c + err(views, l)
            })
            .collect();
        back.push(from);
        cost = next;
    }
    // Of equally good ends the highest: a death must pay its way here too.
    let mut level = (0..levels)
        .rev()
        .min_by(|&a, &b| cost[a].total_cmp(&cost[b]))
        .expect("levels >= 1");
    let mut path = vec![0usize; counts.len()];
    for i in (0..counts.len()).rev() {
        path[i] = level;
        level = back[i][level];
    }
    let mut lost = 0.0;
    let mut out = Vec::with_capacity(path.len());
    for (i, &l) in path.iter().enumerate() {
        if i > 0 && l < path[i - 1] {
            lost += (path[i - 1] - l) as f64;
        }
        out.push(lost);
    }
    out
}

/// Centred moving median with a window shrinking symmetrically at the ends.
pub fn moving_median(y: &[f64], window: usize) -> Vec<f64> {
    let half = window / 2;
    (0..y.len())
        .map(|i| {
            let h = half.min(i).min(y.len() - 1 - i);
            median(&y[i - h..=i + h])
        })
        .collect()
}

/// Computes a plant's timeline from all its observations, in any order.
pub fn compute(obs: &[Obs], p: &TimelineParams) -> Timeline {
    // People count by the day: a person's count joins that day's imaging
    // session (the nearest, if there are two), and starts its own only on a
    // day without images.
    let (people, images): (Vec<&Obs>, Vec<&Obs>) = obs.iter().partition(|o| o.view.is_person());
    let mut obs = images;
    obs.sort_by(|a, b| a.taken_at.cmp(&b.taken_at).then_with(|| a.view.cmp(&b.view)));
    let mut sessions: Vec<Session> = Vec::new();
    let mut last: Option<NaiveDateTime> = None;
    for o in obs {
        let new_session = match last {
            Some(t) => o.taken_at - t > p.session_gap,
            None => true,
        };
        if new_session {
            sessions.push(Session::open(o.taken_at));
        }
        sessions
            .last_mut()
            .expect("pushed above")
            .views
            .push((o.view.clone(), o.count));
        last = Some(o.taken_at);
    }
    for o in people {
        let same_day = sessions
            .iter_mut()
            .filter(|s| s.start.date() == o.taken_at.date())
            .min_by_key(|s| (s.start - o.taken_at).num_seconds().abs());
        match same_day {
            Some(s) => s.views.push((o.view.clone(), o.count)),
            None => {
                let at = sessions.partition_point(|s| s.start <= o.taken_at);
                let mut own = Session::open(o.taken_at);
                own.views.push((o.view.clone(), o.count));
                sessions.insert(at, own);
            }
        }
    }
    for s in &mut sessions {
        s.fused = p.fusion.fuse(&s.views).unwrap_or(0.0);
        // A person's count weighs as much in the fit as in reading deaths.
        let people = s.views.iter().filter(|(v, _)| v.is_person()).count();
        s.weight = (s.views.len() + people * (PERSON_AS_VIEWS - 1)) as f64;
    }
    let fused: Vec<f64> = sessions.iter().map(|s| s.fused).collect();
    let weights: Vec<f64> = sessions.iter().map(|s| s.weight).collect();
    // Every side view is evidence of a death (a dead leaf leaves every view),
    // so one view's miscount is outweighed by the others. A top view is none:
    // it sees a few leaves fewer, and a day imaged from the top only would
    // read as leaves lost.
    let evidence: Vec<Vec<f64>> = sessions.iter().map(|s| death_evidence(&s.views)).collect();
    let lost = deaths(&evidence, p.death_penalty);
    let with_lost: Vec<f64> = fused.iter().zip(&lost).map(|(f, l)| f + l).collect();
    let emerged = isotonic(&with_lost, &weights);
    let living = moving_median(&fused, p.living_window);
    for (i, s) in sessions.iter_mut().enumerate() {
        s.lost = lost[i];
        s.emerged = emerged[i];
        s.living = living[i];
    }
    let events = emergence_events(&sessions);
    let phyllochron_days = phyllochron(&events);
    Timeline {
        sessions,
        events,
        phyllochron_days,
    }
}

fn emergence_events(sessions: &[Session]) -> Vec<Event> {
    let mut events = Vec::new();
    let Some(first) = sessions.first() else {
        return events;
    };
    // Leaves counted at the first session emerged at an unknown earlier time.
    let mut next_leaf = (first.emerged + 0.5).floor().max(0.0) as u32 + 1;
    for pair in sessions.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        while b.emerged >= next_leaf as f64 - 0.5 {
            let level = next_leaf as f64 - 0.5;
            let frac = ((level - a.emerged) / (b.emerged - a.emerged)).clamp(0.0, 1.0);
            let span = (b.start - a.start).num_milliseconds() as f64;
            let at = a.start + Duration::milliseconds((frac * span).round() as i64);
            events.push(Event {
                leaf: next_leaf,
                at,
                seen_at: b.start,
            });
            next_leaf += 1;
        }
    }
    events
}

fn phyllochron(events: &[Event]) -> Option<f64> {
    if events.len() < 2 {
        return None;
    }
    let t0 = events[0].at;
    let xs: Vec<f64> = events.iter().map(|e| e.leaf as f64).collect();
    let ys: Vec<f64> = events
        .iter()
        .map(|e| (e.at - t0).num_milliseconds() as f64 / 86_400_000.0)
        .collect();
    least_squares::slope(&xs, &ys)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 56 item 1: a fit of 12.5 is 12 leaves wherever a person reads
    /// it, and a non-decreasing fit stays non-decreasing in whole leaves.
    #[test]
    fn whole_leaves_are_the_leaves_the_fit_has_reached() {
        assert_eq!(
            [0.0, 0.4, 12.5, 12.999_999_999_9, 13.0, -0.2].map(whole_leaves),
            [0, 0, 12, 13, 13, 0]
        );
        let fit = [3.0, 3.5, 3.5, 4.0, 5.25, 5.25, 7.0];
        let whole: Vec<u32> = fit.iter().map(|&f| whole_leaves(f)).collect();
        assert!(whole.windows(2).all(|w| w[0] <= w[1]), "{whole:?}");
    }
    use chrono::NaiveDate;

    /// Living leaves counted by a person on successive imaging days
    /// (docs/ARCHITECTURE.md, "Facility facts").
    const GROUND_TRUTH: [f64; 11] = [8., 8., 10., 10., 11., 11., 12., 13., 14., 12., 14.];

    fn day(i: i64) -> NaiveDateTime {
        NaiveDate::from_ymd_opt(2018, 4, 20)
            .unwrap()
            .and_hms_opt(10, 0, 0)
            .unwrap()
            + Duration::days(i)
    }

    #[test]
    fn isotonic_on_ground_truth() {
        let w = vec![1.0; GROUND_TRUTH.len()];
        let fit = isotonic(&GROUND_TRUTH, &w);
        // The 14, 12 dip pools to 13, 13; the final 14 stands.
        let want = [8., 8., 10., 10., 11., 11., 12., 13., 13., 13., 14.];
        for (f, w) in fit.iter().zip(want) {
            assert!((f - w).abs() < 1e-9, "{fit:?}");
        }
        assert!(fit.windows(2).all(|p| p[0] <= p[1]));
    }

    #[test]
    fn isotonic_respects_weights_and_is_identity_on_sorted() {
        assert_eq!(isotonic(&[1., 2., 3.], &[1., 1., 1.]), vec![1., 2., 3.]);
        // A heavy point pulls the pooled block towards itself.
        assert_eq!(isotonic(&[5., 1.], &[3., 1.]), vec![4., 4.]);
        assert_eq!(isotonic(&[3., 2., 1.], &[1., 1., 1.]), vec![2., 2., 2.]);
        assert!(isotonic(&[], &[]).is_empty());
    }

    #[test]
    fn ground_truth_timeline() {
        let obs: Vec<Obs> = GROUND_TRUTH
            .iter()
            .enumerate()
            .map(|(i, &c)| Obs {
                taken_at: day(i as i64),
                view: View::Side(108),
                count: c,
            })
            .collect();
        let t = compute(&obs, &TimelineParams::default());
        assert_eq!(t.sessions.len(), 11);
        // Living leaves keep the lasting drop pattern but lose nothing at the ends.
        let living: Vec<f64> = t.sessions.iter().map(|s| s.living).collect();
        assert_eq!(living, vec![8., 8., 10., 10., 11., 11., 12., 13., 13., 14., 14.]);
        // Leaves 9..=14 emerge after the first day: 9 and 10 between days 1 and 2.
        let leaves: Vec<u32> = t.events.iter().map(|e| e.leaf).collect();
        assert_eq!(leaves, vec![9, 10, 11, 12, 13, 14]);
        assert_eq!(t.events[0].at, day(1) + Duration::hours(6));
        assert_eq!(t.events[1].at, day(1) + Duration::hours(18));
        assert_eq!(t.events[2].at, day(3) + Duration::hours(12));
        assert_eq!(t.events[4].seen_at, day(7));
        // Leaf 14 is dated from the lasting rise (day 10), not the one-day spike at day 8.
        assert_eq!(t.events[5].at, day(9) + Duration::hours(12));
        let ph = t.phyllochron_days.unwrap();
        assert!(ph > 1.0 && ph < 2.0, "{ph}");
    }

    #[test]
    fn out_of_order_input_gives_the_same_timeline() {
        let mut obs: Vec<Obs> = Vec::new();
        for (i, &c) in GROUND_TRUTH.iter().enumerate() {
            for (k, a) in [0u16, 36, 72, 108, 144].iter().enumerate() {
                let view = View::Side(*a);
                let t = day(i as i64) + Duration::seconds(20 * k as i64);
                obs.push(Obs {
                    taken_at: t,
                    view,
                    count: c - (k % 2) as f64,
                });
            }
            obs.push(Obs {
                taken_at: day(i as i64) + Duration::minutes(3),
                view: View::Top(90),
                count: c + 5.0,
            });
        }
        let p = TimelineParams::default();
        let a = compute(&obs, &p);
        obs.reverse();
        obs.swap(3, 40);
        let b = compute(&obs, &p);
        assert_eq!(a, b);
        assert_eq!(a.sessions.len(), 11);
        // The default side-view rule ignores the (here inflated) top view.
        assert_eq!(a.sessions[0].fused, 8.0);
        assert_eq!(a.sessions[0].weight, 6.0);
    }

    #[test]
    fn fusion_rules() {
        let v = vec![
            (View::Side(0), 7.0),
            (View::Side(108), 9.0),
            (View::Side(36), 8.0),
            (View::Top(90), 10.0),
        ];
        let f = |r: &str| FusionRule::parse(r).unwrap().fuse(&v).unwrap();
        assert_eq!(f("max-side"), 9.0);
        assert_eq!(f("second-max-side"), 8.0);
        assert_eq!(f("max"), 10.0);
        assert_eq!(f("median-side"), 8.0);
        assert_eq!(f("mean-side"), 8.0);
        assert_eq!(f("view:SV_0"), 7.0);
        assert_eq!(f("view:SV_999"), 8.0);
        let top_only = vec![(View::Top(90), 4.0)];
        assert_eq!(FusionRule::MaxSide.fuse(&top_only), Some(4.0));
        assert_eq!(FusionRule::MaxSide.fuse(&[]), None);
        assert_eq!(FusionRule::SecondMaxSide.fuse(&top_only), Some(4.0));
        let one_over_count = vec![
            (View::Side(0), 12.0),
            (View::Side(36), 8.0),
            (View::Side(72), 8.0),
        ];
        assert_eq!(FusionRule::SecondMaxSide.fuse(&one_over_count), Some(8.0));
        assert_eq!(FusionRule::SecondMaxSide.fuse(&one_over_count[..1]), Some(12.0));
        assert!(FusionRule::parse("largest").is_err());
    }

    /// Five side views per day with these counts, each view off by `noise(day, view)`.
    fn five_views(counts: &[f64], noise: impl Fn(usize, usize) -> f64) -> Vec<Obs> {
        let mut obs = Vec::new();
        for (i, &c) in counts.iter().enumerate() {
            for (k, a) in [0u16, 36, 72, 108, 144].iter().enumerate() {
                obs.push(Obs {
                    taken_at: day(i as i64) + Duration::seconds(20 * k as i64),
                    view: View::Side(*a),
                    count: c + noise(i, k),
                });
            }
        }
        obs
    }

    #[test]
    fn a_persons_count_overrides_the_views() {
        let views = vec![
            (View::Side(0), 7.0),
            (View::Side(36), 7.0),
            (View::Side(72), 8.0),
            (View::parse("human:ana"), 9.0),
            (View::parse("Human"), 10.0),
        ];
        for rule in ["second-max-side", "max", "median-side", "view:SV_0"] {
            assert_eq!(FusionRule::parse(rule).unwrap().fuse(&views), Some(9.5), "{rule}");
        }
        assert!(View::parse("manual").is_person() && !View::parse("SV_0").is_person());
        assert!(!View::parse("humane").is_person());
    }

    #[test]
    fn a_persons_count_joins_that_days_imaging_session() {
        let mut obs = five_views(&[7., 8., 8., 9.], |_, _| 0.0);
        // Dated only (noon), hours after the images of day 1; and one on a day without images.
        obs.push(Obs {
            taken_at: day(1) + Duration::hours(6),
            view: View::parse("human"),
            count: 9.0,
        });
        obs.push(Obs {
            taken_at: day(6),
            view: View::parse("manual"),
            count: 10.0,
        });
        let t = compute(&obs, &TimelineParams::default());
        let fused: Vec<f64> = t.sessions.iter().map(|s| s.fused).collect();
        assert_eq!(fused, [7., 9., 8., 9., 10.]);
        assert_eq!(t.sessions[1].views.len(), 6);
        assert_eq!(t.sessions[4].start, day(6));
    }

    #[test]
    fn a_person_seeing_a_leaf_gone_is_a_death_at_once() {
        // The views keep seeing 8 (the dead leaf still looks like one to the
        // model), but a person counted 7 on day 3: that day decides.
        let mut obs = five_views(&[7., 8., 8., 8., 8., 9., 9.], |_, _| 0.0);
        obs.push(Obs {
            taken_at: day(3) + Duration::seconds(300),
            view: View::parse("human"),
            count: 7.0,
        });
        let t = compute(&obs, &TimelineParams::default());
        assert_eq!(t.sessions[3].fused, 7.0);
        // Five views and the person, who weighs as five.
        assert_eq!(t.sessions[3].weight, 10.0);
        let lost: Vec<f64> = t.sessions.iter().map(|s| s.lost).collect();
        assert_eq!(lost[3], 1.0, "{lost:?}");
    }

    #[test]
    fn lasting_drops_are_leaves_lost_and_later_leaves_keep_their_numbers() {
        // Living leaves: 6 emerge to 8, leaf 1 dies on day 4, leaves 9 and 10 follow.
        let living = [6., 7., 7., 8., 7., 7., 8., 8., 9.];
        let t = compute(&five_views(&living, |_, _| 0.0), &TimelineParams::default());
        let lost: Vec<f64> = t.sessions.iter().map(|s| s.lost).collect();
        assert_eq!(lost, vec![0., 0., 0., 0., 1., 1., 1., 1., 1.]);
        let emerged: Vec<f64> = t.sessions.iter().map(|s| s.emerged).collect();
        assert_eq!(emerged, vec![6., 7., 7., 8., 8., 8., 9., 9., 10.]);
        let leaves: Vec<u32> = t.events.iter().map(|e| e.leaf).collect();
        assert_eq!(leaves, vec![7, 8, 9, 10]);
        assert_eq!(t.events[2].seen_at, day(6));
        // Without reading deaths the drop is pooled away and leaf 10 is never dated.
        let off = TimelineParams {
            death_penalty: 0.0,
            ..TimelineParams::default()
        };
        let t = compute(&five_views(&living, |_, _| 0.0), &off);
        let leaves: Vec<u32> = t.events.iter().map(|e| e.leaf).collect();
        assert_eq!(leaves, vec![7, 8, 9]);
        assert_eq!(t.events[2].seen_at, day(8));
    }

    #[test]
    fn one_views_miscounts_are_not_deaths() {
        // Every day one view (a different one) counts a leaf fewer, twice two views do.
        let living = [6., 6., 7., 7., 7., 8., 8., 8.];
        let noise = |i: usize, k: usize| {
            if k == i % 5 || (i.is_multiple_of(3) && k == (i + 2) % 5) {
                -1.0
            } else {
                0.0
            }
        };
        let t = compute(&five_views(&living, noise), &TimelineParams::default());
        assert!(t.sessions.iter().all(|s| s.lost == 0.0), "{:?}", t.sessions);
        let leaves: Vec<u32> = t.events.iter().map(|e| e.leaf).collect();
        assert_eq!(leaves, vec![7, 8]);
    }

    #[test]
    fn a_day_of_wrong_images_loses_no_leaf() {
        // Day 4's five views are another, smaller plant's (a misread barcode).
        let living = [6., 6., 7., 7., 3., 7., 8., 8.];
        let t = compute(&five_views(&living, |_, _| 0.0), &TimelineParams::default());
        assert!(t.sessions.iter().all(|s| s.lost == 0.0), "{:?}", t.sessions);
        let leaves: Vec<u32> = t.events.iter().map(|e| e.leaf).collect();
        assert_eq!(leaves, vec![7, 8]);
    }

    #[test]
    fn a_day_with_the_top_view_only_loses_no_leaf() {
        let mut obs = five_views(&[6., 6., 7., 7., 7., 8., 8., 8.], |_, _| 0.0);
        // Day 3's side cameras failed: only its top view, counting 3, arrived.
        obs.retain(|o| o.taken_at < day(3) || o.taken_at >= day(4));
        obs.push(Obs {
            taken_at: day(3),
            view: View::Top(90),
            count: 3.0,
        });
        let t = compute(&obs, &TimelineParams::default());
        assert!(t.sessions.iter().all(|s| s.lost == 0.0), "{:?}", t.sessions);
        let leaves: Vec<u32> = t.events.iter().map(|e| e.leaf).collect();
        assert_eq!(leaves, vec![7, 8]);
    }

    #[test]
    fn deaths_on_plain_counts() {
        assert_eq!(deaths(&[], 3.0), Vec::<f64>::new());
        let one = |xs: &[f64]| xs.iter().map(|&x| vec![x]).collect::<Vec<_>>();
        // One count per session: a drop must cost more than the penalty to be believed.
        let lasting = one(&[5., 5., 5., 5., 4., 4., 4., 4.]);
        assert_eq!(deaths(&lasting, 3.0), vec![0., 0., 0., 0., 1., 1., 1., 1.]);
        assert_eq!(deaths(&lasting, 0.0), vec![0.; 8]);
        // Four sessions' evidence against a penalty of five: a miscount.
        assert_eq!(deaths(&lasting, 5.0), vec![0.; 8]);
        // A two-session dip (cost 2) is cheaper than a death and a new leaf.
        let dip = one(&[5., 5., 5., 5., 4., 4., 5., 5.]);
        assert_eq!(deaths(&dip, 3.0), vec![0.; 8]);
        // Two leaves at once.
        // Two leaves at once cost twice the penalty, so they need twice the evidence.
        let two = one(&[9., 9., 9., 9., 7., 7., 7., 7.]);
        assert_eq!(deaths(&two, 3.0), vec![0.; 8]);
        let two = one(&[9., 9., 9., 9., 9., 9., 9., 7., 7., 7., 7., 7., 7., 7.]);
        assert_eq!(deaths(&two, 3.0)[6..], [0., 2., 2., 2., 2., 2., 2., 2.]);
        // Five views: the views showing the drop must outnumber the rest by more than the penalty.
        let five = |xs: &[[f64; 5]]| xs.iter().map(|v| v.to_vec()).collect::<Vec<_>>();
        let (before, after) = ([5.; 5], [4., 4., 4., 4., 5.]);
        assert_eq!(deaths(&five(&[before, before, after]), 3.0), vec![0.; 3]);
        assert_eq!(
            deaths(&five(&[before, before, after, after]), 3.0),
            vec![0., 0., 1., 1.]
        );
        assert_eq!(deaths(&five(&[before, before, [4.; 5]]), 3.0), vec![0., 0., 1.]);
        // An absurd count reads no deaths rather than building a table that size.
        assert_eq!(deaths(&one(&[5., 4e9, 4., 4.]), 3.0), vec![0.; 4]);
    }

    #[test]
    fn single_session_has_no_events() {
        let obs = vec![Obs {
            taken_at: day(0),
            view: View::Side(0),
            count: 5.0,
        }];
        let t = compute(&obs, &TimelineParams::default());
        assert!(t.events.is_empty());
        assert_eq!(t.phyllochron_days, None);
        assert_eq!(t.sessions[0].emerged, 5.0);
    }
}
