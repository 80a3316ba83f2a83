//! 95 % intervals for the count metrics. Ten annotated frames pin an exact
//! agreement of 40 % down to roughly 17–69 %, and a reader comparing two
//! models needs to see that before believing a one-frame difference.
//!
//! Shares (exact, within ±1) get Wilson score intervals, which stay inside
//! 0–1 and behave at 0 % and 100 % where the normal approximation does not.
//! RMSE, MAE and bias get percentile bootstrap intervals over images, from a
//! fixed seed so that a rerun prints the same numbers.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::metrics::{count_errors, CountPair};

/// Two-sided 95 % normal quantile.
const Z95: f64 = 1.959_963_984_540_054;

/// Bootstrap resamples; enough for stable 2.5 % and 97.5 % percentiles.
pub const RESAMPLES: usize = 2000;

/// Seed of the bootstrap's generator (fixed: reruns print the same interval).
const SEED: u64 = 0x9e37_79b9_7f4a_7c15;

/// A closed interval `[lo, hi]`.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Interval {
    /// Whether `v` lies inside (ends included).
    pub fn contains(&self, v: f64) -> bool {
        self.lo <= v && v <= self.hi
    }
}

/// 95 % intervals of the headline count metrics.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct MetricIntervals {
    /// Exact agreement (Wilson).
    pub exact: Interval,
    /// Within one leaf (Wilson).
    pub within_1: Interval,
    /// Root mean squared error (bootstrap).
    pub rmse: Interval,
    /// Mean absolute error (bootstrap).
    pub mae: Interval,
    /// Mean of predicted minus true (bootstrap).
    pub bias: Interval,
    /// Bootstrap resamples drawn.
    pub resamples: usize,
}

impl MetricIntervals {
    /// Intervals of `pairs`; `None` for an empty set.
    pub fn of(pairs: &[CountPair]) -> Option<Self> {
        if pairs.is_empty() {
            return None;
        }
        let err = count_errors(pairs);
        let n = err.len();
        let exact = err.iter().filter(|e| **e == 0.0).count();
        let within = err.iter().filter(|e| e.abs() <= 1.0).count();
        let (rmse, mae, bias) = bootstrap(&err, RESAMPLES, SEED);
        Some(Self {
            exact: wilson(exact, n),
            within_1: wilson(within, n),
            rmse,
            mae,
            bias,
            resamples: RESAMPLES,
        })
    }

    /// One line for the text report.
    pub fn line(&self) -> String {
        format!(
            "95 % intervals (Wilson for shares; bootstrap over images, {} resamples, for errors): \
             exact [{:.1}, {:.1}] %; within ±1 [{:.1}, {:.1}] %; RMSE [{:.3}, {:.3}]; MAE [{:.3}, {:.3}]; \
             bias [{:+.3}, {:+.3}]",
            self.resamples,
            self.exact.lo * 100.0,
            self.exact.hi * 100.0,
            self.within_1.lo * 100.0,
            self.within_1.hi * 100.0,
            self.rmse.lo,
            self.rmse.hi,
            self.mae.lo,
            self.mae.hi,
            self.bias.lo,
            self.bias.hi
        )
    }
}

/// Wilson score 95 % interval of `successes` out of `n` (`n` > 0).
pub fn wilson(successes: usize, n: usize) -> Interval {
    let nf = n as f64;
    let p = successes as f64 / nf;
    let z2 = Z95 * Z95;
    let denom = 1.0 + z2 / nf;
    let centre = (p + z2 / (2.0 * nf)) / denom;
    let half = Z95 * (p * (1.0 - p) / nf + z2 / (4.0 * nf * nf)).sqrt() / denom;
    Interval {
        lo: (centre - half).max(0.0),
        hi: (centre + half).min(1.0),
    }
}

/// Percentile bootstrap 95 % intervals of RMSE, MAE and mean of `err`.
fn bootstrap(err: &[f64], resamples: usize, seed: u64) -> (Interval, Interval, Interval) {
    let n = err.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut rmse, mut mae, mut bias) = (
        Vec::with_capacity(resamples),
        Vec::with_capacity(resamples),
        Vec::with_capacity(resamples),
    );
    for _ in 0..resamples {
        let (mut sq, mut abs, mut sum) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let e = err[rng.random_range(0..n)];
            sq += e * e;
            abs += e.abs();
            sum += e;
        }
        let nf = n as f64;
        rmse.push((sq / nf).sqrt());
        mae.push(abs / nf);
        bias.push(sum / nf);
    }
    (percentiles(rmse), percentiles(mae), percentiles(bias))
}

/// The 2.5th and 97.5th percentiles (nearest rank) of `v`.
fn percentiles(mut v: Vec<f64>) -> Interval {
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
    Interval {
        lo: at(0.025),
        hi: at(0.975),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(errors: &[i32]) -> Vec<CountPair> {
        errors
            .iter()
            .map(|&e| CountPair {
                file: String::new(),
                view: "x".into(),
                truth: 10,
                predicted: (10 + e) as u32,
            })
            .collect()
    }

    #[test]
    fn wilson_matches_published_values() {
        // Newcombe (1998), table I: 81 of 263 gives 0.2553–0.3662.
        let i = wilson(81, 263);
        assert!(
            (i.lo - 0.2553).abs() < 5e-4 && (i.hi - 0.3662).abs() < 5e-4,
            "{i:?}"
        );
        // 4 of 10: 16.8–68.7 %.
        let i = wilson(4, 10);
        assert!(
            (i.lo - 0.1682).abs() < 5e-4 && (i.hi - 0.6873).abs() < 5e-4,
            "{i:?}"
        );
        // The ends stay inside 0–1 and are not degenerate.
        let none = wilson(0, 10);
        assert_eq!(none.lo, 0.0);
        assert!(none.hi > 0.25 && none.hi < 0.35, "{none:?}");
        let all = wilson(10, 10);
        assert!(all.hi > 1.0 - 1e-12, "{all:?}");
        assert!(all.lo > 0.65 && all.lo < 0.75, "{all:?}");
    }

    #[test]
    fn intervals_hold_the_point_estimates_and_narrow_with_more_images() {
        let errs = [0, 0, 1, -1, 0, 2, -3, 0, 1, 0];
        let small = MetricIntervals::of(&pairs(&errs)).unwrap();
        let m = super::super::metrics::CountMetrics::of(&pairs(&errs));
        assert!(small.exact.contains(m.exact) && small.within_1.contains(m.within_1));
        assert!(small.rmse.contains(m.rmse) && small.mae.contains(m.mae) && small.bias.contains(m.bias));
        assert!(
            small.rmse.lo > 0.0 && small.bias.lo < 0.0 && small.bias.hi > 0.0,
            "{small:?}"
        );
        let many: Vec<i32> = errs.iter().cycle().take(errs.len() * 40).copied().collect();
        let large = MetricIntervals::of(&pairs(&many)).unwrap();
        let width = |i: Interval| i.hi - i.lo;
        assert!(width(large.exact) < 0.5 * width(small.exact));
        assert!(width(large.rmse) < 0.5 * width(small.rmse));
        // Fixed seed: the same data gives the same interval.
        assert_eq!(MetricIntervals::of(&pairs(&errs)).unwrap(), small);
    }

    #[test]
    fn perfect_counts_have_zero_error_intervals() {
        let i = MetricIntervals::of(&pairs(&[0; 8])).unwrap();
        assert_eq!((i.rmse.lo, i.rmse.hi, i.bias.lo, i.bias.hi), (0.0, 0.0, 0.0, 0.0));
        assert!(i.exact.hi > 1.0 - 1e-12);
        assert!(MetricIntervals::of(&[]).is_none());
    }
}
