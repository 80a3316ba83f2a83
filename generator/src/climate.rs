//! Greenhouse air temperature for growth sequences, and the plant's
//! development driven by it.
//!
//! Plants develop with thermal time, the integral of the air temperature
//! above a base (10 °C for sorghum), not with calendar days: in a cool
//! spring a leaf takes more days to appear than in summer, while its
//! degree-days stay about the same. With a climate, `phyllo-gen sequence`
//! ages each plant by the degree-days since sowing, written as
//! `climate.csv` (`timestamp,temp_c`, every 15 minutes, the log a greenhouse
//! controller keeps), so `phyllo import` can take it and the daemon's
//! phyllochron in degree-days per leaf can be checked against the truth.
//!
//! The presets' day values ([`crate::plant::preset`]'s `phyllochron_days`
//! and the rest) hold at a constant [`REFERENCE_C`]: a plant's
//! development age is its degree-days since sowing over
//! `REFERENCE_C - BASE_C` per day. Between readings the temperature is
//! linear and the area above the base is integrated exactly, the rule the
//! daemon uses too (written again here, so the truth does not lean on the
//! code it checks).

use crate::date::Date;
use crate::rng::{self, Draw};
use anyhow::{bail, Context};
use std::fmt::Write as _;

/// Base temperature of development (°C), the daemon's default `base_temp_c`.
pub const BASE_C: f64 = 10.0;
/// Constant temperature at which the presets' day values hold (°C).
pub const REFERENCE_C: f64 = 25.0;
/// Minutes between logged readings.
pub const STEP_MINUTES: u32 = 15;

/// The climate asked for on the command line: `MEAN[,SWING[,DRIFT]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClimateSpec {
    /// Mean daily air temperature (°C).
    pub mean_c: f64,
    /// Half the day–night swing (°C): warmest mid-afternoon, coolest before dawn.
    pub swing_c: f64,
    /// Day-to-day spread of the daily mean (°C, standard deviation of a
    /// slowly wandering weather term).
    pub drift_c: f64,
}

impl ClimateSpec {
    /// Parses `MEAN[,SWING[,DRIFT]]`; the swing defaults to 4 °C and the drift to 1.5 °C.
    pub fn parse(s: &str) -> anyhow::Result<ClimateSpec> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() > 3 || parts.iter().any(|p| p.is_empty()) {
            bail!("climate {s:?} is not MEAN[,SWING[,DRIFT]] in °C");
        }
        let num = |i: usize, default: f64| -> anyhow::Result<f64> {
            parts.get(i).map_or(Ok(default), |p| {
                p.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .with_context(|| format!("climate {s:?}: {p:?} is not a number"))
            })
        };
        let spec = ClimateSpec {
            mean_c: num(0, REFERENCE_C)?,
            swing_c: num(1, 4.0)?,
            drift_c: num(2, 1.5)?,
        };
        if !(BASE_C + 2.0..=40.0).contains(&spec.mean_c) {
            bail!(
                "climate {s:?}: a mean of {} °C is outside {}..=40 (plants barely develop near the {BASE_C} °C base)",
                spec.mean_c,
                BASE_C + 2.0
            );
        }
        if !(0.0..=15.0).contains(&spec.swing_c) || !(0.0..=8.0).contains(&spec.drift_c) {
            bail!("climate {s:?}: the swing must be 0..=15 °C and the drift 0..=8 °C");
        }
        Ok(spec)
    }
}

/// A simulated temperature log from midnight of its first day, with the
/// degree-days accumulated at each reading.
#[derive(Debug, Clone)]
pub struct Climate {
    start: Date,
    temps: Vec<f64>,
    cumulative: Vec<f64>,
}

impl Climate {
    /// Simulates `days` days from midnight of `start`, deterministic in `seed`.
    pub fn simulate(spec: ClimateSpec, seed: u64, start: Date, days: u32) -> Climate {
        let mut r = rng::stream(seed, "climate", 0);
        let per_day = (24 * 60 / STEP_MINUTES) as usize;
        let n = days as usize * per_day + 1;
        let mut temps = Vec::with_capacity(n);
        // Weather wanders: an AR(1) daily term whose spread is `drift_c`.
        let keep = 0.7f64;
        let mut weather = 0.0f64;
        let mut daily = Vec::with_capacity(days as usize + 1);
        for _ in 0..=days {
            let shock = f64::from(r.normal(0.0, 1.0)) * spec.drift_c * (1.0 - keep * keep).sqrt();
            weather = keep * weather + shock;
            daily.push(weather);
        }
        for i in 0..n {
            let hours = (i as f64) * f64::from(STEP_MINUTES) / 60.0;
            let day = (hours / 24.0).floor() as usize;
            // The weather term moves smoothly from one day's value to the next.
            let f = hours / 24.0 - day as f64;
            let w = daily[day] + (daily[(day + 1).min(days as usize)] - daily[day]) * f;
            // Warmest at 14:00, coolest at 02:00.
            let diurnal = spec.swing_c * (std::f64::consts::TAU * (hours - 8.0) / 24.0).sin();
            let noise = f64::from(r.normal(0.0, 0.2));
            // Logged to 0.01 °C, and integrated as logged, so the file is the truth.
            temps.push(((spec.mean_c + w + diurnal + noise) * 100.0).round() / 100.0);
        }
        let step_hours = f64::from(STEP_MINUTES) / 60.0;
        let mut cumulative = Vec::with_capacity(n);
        let mut sum = 0.0;
        for i in 0..n {
            if i > 0 {
                sum += degree_days(temps[i - 1], temps[i], step_hours);
            }
            cumulative.push(sum);
        }
        Climate {
            start,
            temps,
            cumulative,
        }
    }

    /// Minutes the log spans.
    fn span_minutes(&self) -> f64 {
        ((self.temps.len() - 1) as f64) * f64::from(STEP_MINUTES)
    }

    /// Degree-days above [`BASE_C`] from the log's start to `minutes` after it
    /// (clamped to the log).
    pub fn degree_days_at(&self, minutes: f64) -> f64 {
        let m = minutes.clamp(0.0, self.span_minutes());
        let step = f64::from(STEP_MINUTES);
        let a = ((m / step).floor() as usize).min(self.temps.len() - 2);
        let into = m - a as f64 * step;
        let t_at = self.temps[a] + (self.temps[a + 1] - self.temps[a]) * into / step;
        self.cumulative[a] + degree_days(self.temps[a], t_at, into / 60.0)
    }

    /// Development age (days at [`REFERENCE_C`]) `minutes` after the log's start.
    pub fn development_days_at(&self, minutes: f64) -> f64 {
        self.degree_days_at(minutes) / (REFERENCE_C - BASE_C)
    }

    /// The first minute after the log's start at which the development age
    /// reaches `days`; `None` when the log ends before.
    pub fn minutes_of_development(&self, days: f64) -> Option<f64> {
        let target = days * (REFERENCE_C - BASE_C);
        if target <= 0.0 {
            return Some(0.0);
        }
        if *self.cumulative.last()? < target {
            return None;
        }
        // The thermal clock never runs backwards, so bisect on it.
        let (mut lo, mut hi) = (0.0, self.span_minutes());
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if self.degree_days_at(mid) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(hi)
    }

    /// The calendar date and `HH:MM:SS` of `minutes` after the log's start.
    pub fn clock(&self, minutes: f64) -> (Date, String) {
        let secs = (minutes * 60.0).round() as i64;
        let date = self.start.add_days(secs.div_euclid(86_400));
        let s = secs.rem_euclid(86_400);
        (date, format!("{:02}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60))
    }

    /// The log as `timestamp,temp_c` CSV, the shape `phyllo import` takes.
    pub fn csv(&self) -> String {
        let mut out = String::from("timestamp,temp_c\n");
        for (i, t) in self.temps.iter().enumerate() {
            let (date, time) = self.clock(i as f64 * f64::from(STEP_MINUTES));
            let _ = writeln!(out, "{date}T{time},{t:.2}");
        }
        out
    }

    /// Mean logged temperature (°C).
    pub fn mean_c(&self) -> f64 {
        self.temps.iter().sum::<f64>() / self.temps.len() as f64
    }
}

/// ∫ max(0, T − base) over `hours` with T linear from `t0` to `t1`, in degree-days.
fn degree_days(t0: f64, t1: f64, hours: f64) -> f64 {
    let (a, b) = (t0 - BASE_C, t1 - BASE_C);
    let area_hours = if a >= 0.0 && b >= 0.0 {
        0.5 * (a + b) * hours
    } else if a <= 0.0 && b <= 0.0 {
        0.0
    } else {
        // Only the part of the segment above the base counts: a triangle.
        let hi = a.max(b);
        0.5 * hi * hours * hi / (a - b).abs()
    };
    area_hours / 24.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start() -> Date {
        Date::parse("2018-03-27").unwrap()
    }

    #[test]
    fn a_constant_reference_climate_develops_one_day_per_day() {
        let spec = ClimateSpec {
            mean_c: REFERENCE_C,
            swing_c: 0.0,
            drift_c: 0.0,
        };
        let c = Climate::simulate(spec, 1, start(), 30);
        // Only the 0.2 °C logging noise is left: within a few tenths of a percent.
        for day in [1.0, 7.5, 29.0] {
            let got = c.development_days_at(day * 1440.0);
            assert!((got - day).abs() < 0.01 * day, "day {day}: {got}");
        }
    }

    #[test]
    fn development_inverts_and_cool_climates_develop_slower() {
        let cool = Climate::simulate(ClimateSpec::parse("19").unwrap(), 3, start(), 40);
        let warm = Climate::simulate(ClimateSpec::parse("29").unwrap(), 3, start(), 40);
        for days in [3.0, 10.0, 17.25] {
            let m = cool.minutes_of_development(days).unwrap();
            assert!((cool.development_days_at(m) - days).abs() < 1e-6);
            assert!(m > warm.minutes_of_development(days).unwrap());
        }
        // 9 °C above the base against 19: about twice the calendar days.
        let ratio = cool.minutes_of_development(12.0).unwrap() / warm.minutes_of_development(12.0).unwrap();
        assert!((1.7..2.5).contains(&ratio), "ratio {ratio}");
        assert!(cool.minutes_of_development(1e6).is_none());
    }

    #[test]
    fn the_log_is_deterministic_and_swings_by_day() {
        let a = Climate::simulate(ClimateSpec::parse("22,5,2").unwrap(), 9, start(), 3);
        let b = Climate::simulate(ClimateSpec::parse("22,5,2").unwrap(), 9, start(), 3);
        assert_eq!(a.csv(), b.csv());
        let csv = a.csv();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], "timestamp,temp_c");
        assert_eq!(lines[1].split(',').next().unwrap(), "2018-03-27T00:00:00");
        assert_eq!(lines.len(), 1 + 3 * 96 + 1);
        let temp = |i: usize| lines[1 + i].split(',').nth(1).unwrap().parse::<f64>().unwrap();
        // 14:00 (reading 56) is warmer than 02:00 (reading 8) on the first day.
        assert!(temp(56) > temp(8) + 6.0);
        assert!((a.mean_c() - 22.0).abs() < 4.0);
    }

    #[test]
    fn degree_days_count_only_the_part_above_the_base() {
        assert!((degree_days(20.0, 20.0, 24.0) - 10.0).abs() < 1e-12);
        assert_eq!(degree_days(5.0, 8.0, 24.0), 0.0);
        // From 0 to 20 °C over a day: above the base half the day, 0..10 above it.
        assert!((degree_days(0.0, 20.0, 24.0) - 2.5).abs() < 1e-12);
        assert!((degree_days(20.0, 0.0, 24.0) - 2.5).abs() < 1e-12);
    }

    #[test]
    fn bad_climates_are_refused_with_the_reason() {
        for bad in ["", "warm", "25,,1", "5", "25,40", "1,2,3,4"] {
            assert!(ClimateSpec::parse(bad).is_err(), "{bad:?}");
        }
        let e = ClimateSpec::parse("8").unwrap_err().to_string();
        assert!(e.contains("base"), "{e}");
    }
}
