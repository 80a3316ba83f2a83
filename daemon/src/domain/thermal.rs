//! Thermal time: leaf appearance in degree-days above a base temperature.
//!
//! Leaves appear faster when it is warm, so a phyllochron in days depends on
//! the season; crop physiologists give it in degree-days per leaf (°Cd), the
//! integral of the air temperature above a base below which the plant does
//! not develop (about 10 °C for sorghum, 8–10 °C for maize). Greenhouses log
//! their air temperature; `phyllo import` takes such a log
//! (`timestamp,temp_c`), and every plant's phyllochron is then also given in
//! °Cd per leaf.
//!
//! Between two readings the temperature is taken as linear and the area above
//! the base integrated exactly. Readings further apart than [`MAX_GAP_HOURS`]
//! leave a hole: no thermal time is given across it rather than a guess.

use chrono::NaiveDateTime;

/// Readings further apart than this leave the time between them unknown.
pub const MAX_GAP_HOURS: f64 = 6.0;

/// Cumulative thermal time over a temperature log.
#[derive(Debug, Clone)]
pub struct ThermalClock {
    times: Vec<NaiveDateTime>,
    temps: Vec<f64>,
    /// Degree-days from the start of its stretch to each reading.
    cumulative: Vec<f64>,
    /// Which stretch of the log (between holes) each reading belongs to.
    stretch: Vec<usize>,
    base: f64,
}

impl ThermalClock {
    /// A clock over `readings` (time, °C; any order, one per time) above `base` °C.
    pub fn new(mut readings: Vec<(NaiveDateTime, f64)>, base: f64) -> ThermalClock {
        readings.sort_by_key(|r| r.0);
        readings.dedup_by_key(|r| r.0);
        let (times, temps): (Vec<_>, Vec<_>) = readings.into_iter().unzip();
        let mut cumulative = Vec::with_capacity(times.len());
        let mut stretch = Vec::with_capacity(times.len());
        let (mut sum, mut k) = (0.0, 0);
        for i in 0..times.len() {
            if i > 0 {
                let span = hours(times[i - 1], times[i]);
                if span > MAX_GAP_HOURS {
                    (sum, k) = (0.0, k + 1);
                } else {
                    sum += degree_days(temps[i - 1], temps[i], span, base);
                }
            }
            cumulative.push(sum);
            stretch.push(k);
        }
        ThermalClock {
            times,
            temps,
            cumulative,
            stretch,
            base,
        }
    }

    /// Degree-days from `from` to `to`; `None` when either lies outside the
    /// log or the two are not in the same stretch of it (a hole between).
    pub fn between(&self, from: NaiveDateTime, to: NaiveDateTime) -> Option<f64> {
        let (sa, a) = self.at(from)?;
        let (sb, b) = self.at(to)?;
        (sa == sb).then_some(b - a)
    }

    /// (stretch, degree-days from its start) at `t`.
    fn at(&self, t: NaiveDateTime) -> Option<(usize, f64)> {
        let i = self.times.partition_point(|&x| x <= t);
        if i == 0 {
            return None;
        }
        let a = i - 1;
        if self.times[a] == t {
            return Some((self.stretch[a], self.cumulative[a]));
        }
        let b = i;
        if b == self.times.len() || self.stretch[b] != self.stretch[a] {
            return None;
        }
        let span = hours(self.times[a], self.times[b]);
        let h = hours(self.times[a], t);
        let temp_t = self.temps[a] + (self.temps[b] - self.temps[a]) * h / span;
        Some((
            self.stretch[a],
            self.cumulative[a] + degree_days(self.temps[a], temp_t, h, self.base),
        ))
    }

    /// True when the log holds no reading.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The base temperature (°C) above which it counts.
    pub fn base(&self) -> f64 {
        self.base
    }

    /// The last reading's time.
    pub fn last_reading(&self) -> Option<NaiveDateTime> {
        self.times.last().copied()
    }

    /// The time after `from` when `degree_days` more have accrued, within
    /// the log (to a minute); `None` when the log ends first or a hole lies
    /// between.
    pub fn when(&self, from: NaiveDateTime, degree_days: f64) -> Option<NaiveDateTime> {
        let end = self.last_reading()?;
        if self.between(from, end)? < degree_days {
            return None;
        }
        // Thermal time never falls, so halving the interval finds the moment.
        let (mut lo, mut hi) = (from, end);
        while hi - lo > chrono::Duration::minutes(1) {
            let mid = lo + (hi - lo) / 2;
            if self.between(from, mid)? < degree_days {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(hi)
    }
}

/// Degree-days per leaf: the least-squares slope of thermal time at
/// emergence against leaf number, over `events` (leaf, time); `None` with
/// fewer than two events or one outside the log.
pub fn phyllochron(clock: &ThermalClock, events: &[(u32, NaiveDateTime)]) -> Option<f64> {
    if events.len() < 2 {
        return None;
    }
    let first = events[0].1;
    let ys = events
        .iter()
        .map(|&(_, t)| clock.between(first, t))
        .collect::<Option<Vec<f64>>>()?;
    let xs: Vec<f64> = events.iter().map(|&(leaf, _)| leaf as f64).collect();
    crate::domain::least_squares::slope(&xs, &ys)
}

fn hours(a: NaiveDateTime, b: NaiveDateTime) -> f64 {
    (b - a).num_milliseconds() as f64 / 3_600_000.0
}

/// ∫ max(0, T − base) over `hours` with T linear from `t0` to `t1`, in degree-days.
fn degree_days(t0: f64, t1: f64, hours: f64, base: f64) -> f64 {
    let (e0, e1) = (t0 - base, t1 - base);
    let degree_hours = if e0 >= 0.0 && e1 >= 0.0 {
        (e0 + e1) / 2.0 * hours
    } else if e0 <= 0.0 && e1 <= 0.0 {
        0.0
    } else {
        // Only the part above the base counts: a triangle up to the crossing.
        let above = e0.max(e1);
        let fraction = above / (e0 - e1).abs();
        above / 2.0 * hours * fraction
    };
    degree_hours / 24.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(h: i64) -> NaiveDateTime {
        chrono::NaiveDate::from_ymd_opt(2026, 11, 1)
            .unwrap()
            .and_hms_opt(0, 0, 0)
            .unwrap()
            + chrono::Duration::hours(h)
    }

    #[test]
    fn a_steady_25_degrees_gives_15_degree_days_a_day() {
        let clock = ThermalClock::new((0..=48).map(|h| (at(h), 25.0)).collect(), 10.0);
        assert_eq!(clock.between(at(0), at(24)), Some(15.0));
        assert!((clock.between(at(6), at(42)).unwrap() - 22.5).abs() < 1e-12);
        assert!((clock.between(at(42), at(6)).unwrap() + 22.5).abs() < 1e-12);
        assert_eq!(clock.between(at(-1), at(3)), None);
        assert_eq!(clock.between(at(3), at(49)), None);
    }

    #[test]
    fn only_the_warmth_above_the_base_counts() {
        // 5 °C to 15 °C over ten hours: above 10 °C for the last five, a
        // triangle of 5 × 5 / 2 = 12.5 degree-hours.
        let clock = ThermalClock::new(vec![(at(0), 5.0), (at(5), 10.0), (at(10), 15.0)], 10.0);
        assert!((clock.between(at(0), at(10)).unwrap() - 12.5 / 24.0).abs() < 1e-12);
        assert_eq!(clock.between(at(0), at(5)), Some(0.0));
        let two = ThermalClock::new(vec![(at(0), 5.0), (at(4), 15.0)], 10.0);
        // Crossing mid-segment: above 10 °C for the last 2 h, 5 × 2 / 2 = 5 degree-hours.
        assert!((two.between(at(0), at(4)).unwrap() - 5.0 / 24.0).abs() < 1e-12);
        // Falling through the base counts the same.
        let down = ThermalClock::new(vec![(at(0), 15.0), (at(4), 5.0)], 10.0);
        assert!((down.between(at(0), at(4)).unwrap() - 5.0 / 24.0).abs() < 1e-12);
        // Wholly below: nothing.
        let cold = ThermalClock::new(vec![(at(0), 4.0), (at(4), 8.0)], 10.0);
        assert_eq!(cold.between(at(0), at(4)), Some(0.0));
    }

    #[test]
    fn a_hole_in_the_log_is_not_bridged() {
        let mut r: Vec<_> = (0..=12).map(|h| (at(h), 20.0)).collect();
        r.extend((24..=36).map(|h| (at(h), 20.0)));
        let clock = ThermalClock::new(r, 10.0);
        assert_eq!(clock.between(at(6), at(18)), None);
        assert_eq!(clock.between(at(6), at(30)), None, "across the hole");
        assert!((clock.between(at(24), at(36)).unwrap() - 5.0).abs() < 1e-12);
    }

    #[test]
    fn the_phyllochron_is_degree_days_per_leaf() {
        // A leaf every 3 days at a steady 22 °C: 3 × 12 = 36 °Cd per leaf.
        let clock = ThermalClock::new((0..=240).map(|h| (at(h), 22.0)).collect(), 10.0);
        let events: Vec<_> = (0..4).map(|k| (5 + k as u32, at(12 + 72 * k))).collect();
        assert!((phyllochron(&clock, &events).unwrap() - 36.0).abs() < 1e-9);
        assert_eq!(phyllochron(&clock, &events[..1]), None);
        let late = [(5, at(12)), (6, at(300))];
        assert_eq!(phyllochron(&clock, &late), None, "outside the log");
    }
}
