//! Count agreement metrics: exact, within ±1, RMSE, MAE, bias, R², confusion,
//! per view.

use std::collections::BTreeMap;

use serde::Serialize;

/// One image's true and predicted leaf counts.
#[derive(Debug, Clone, Serialize)]
pub struct CountPair {
    /// Image file.
    pub file: String,
    /// View (`SV_108`, `TV_90`, a dataset's view name, or `?`).
    pub view: String,
    /// True (human or label) count.
    pub truth: u32,
    /// Predicted count.
    pub predicted: u32,
}

/// Agreement between true and predicted counts.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CountMetrics {
    /// Images compared.
    pub images: usize,
    /// Fraction with exactly the true count.
    pub exact: f64,
    /// Fraction within one leaf of the true count.
    pub within_1: f64,
    /// Root mean squared error, leaves.
    pub rmse: f64,
    /// Mean absolute error, leaves.
    pub mae: f64,
    /// Mean of predicted minus true: positive means overcounting.
    pub bias: f64,
    /// Coefficient of determination of the predictions (1 - SSres/SStot).
    pub r2: f64,
    /// Least-squares fit predicted = slope * true + intercept.
    pub slope: f64,
    /// Intercept of that fit.
    pub intercept: f64,
}

impl CountMetrics {
    /// Metrics of `pairs` (all zero when empty).
    pub fn of(pairs: &[CountPair]) -> Self {
        let n = pairs.len();
        if n == 0 {
            return Self {
                images: 0,
                exact: 0.0,
                within_1: 0.0,
                rmse: 0.0,
                mae: 0.0,
                bias: 0.0,
                r2: 0.0,
                slope: 0.0,
                intercept: 0.0,
            };
        }
        let nf = n as f64;
        let err = count_errors(pairs);
        let exact = err.iter().filter(|e| **e == 0.0).count() as f64 / nf;
        let within_1 = err.iter().filter(|e| e.abs() <= 1.0).count() as f64 / nf;
        let rmse = (err.iter().map(|e| e * e).sum::<f64>() / nf).sqrt();
        let mae = err.iter().map(|e| e.abs()).sum::<f64>() / nf;
        let bias = err.iter().sum::<f64>() / nf;
        let t: Vec<f64> = pairs.iter().map(|p| f64::from(p.truth)).collect();
        let y: Vec<f64> = pairs.iter().map(|p| f64::from(p.predicted)).collect();
        let tm = t.iter().sum::<f64>() / nf;
        let ym = y.iter().sum::<f64>() / nf;
        let ss_tot: f64 = t.iter().map(|v| (v - tm).powi(2)).sum();
        let ss_res: f64 = err.iter().map(|e| e * e).sum();
        let r2 = if ss_tot > 0.0 { 1.0 - ss_res / ss_tot } else { 0.0 };
        let sxy: f64 = t.iter().zip(&y).map(|(a, b)| (a - tm) * (b - ym)).sum();
        let slope = if ss_tot > 0.0 { sxy / ss_tot } else { 0.0 };
        Self {
            images: n,
            exact,
            within_1,
            rmse,
            mae,
            bias,
            r2,
            slope,
            intercept: ym - slope * tm,
        }
    }
}

/// Predicted minus true count of each pair, in leaves.
pub fn count_errors(pairs: &[CountPair]) -> Vec<f64> {
    pairs
        .iter()
        .map(|p| f64::from(p.predicted) - f64::from(p.truth))
        .collect()
}

/// Number of images per (true, predicted) count.
pub fn confusion(pairs: &[CountPair]) -> BTreeMap<(u32, u32), usize> {
    let mut m = BTreeMap::new();
    for p in pairs {
        *m.entry((p.truth, p.predicted)).or_insert(0) += 1;
    }
    m
}

/// Metrics per view.
pub fn per_view(pairs: &[CountPair]) -> BTreeMap<String, CountMetrics> {
    let mut groups: BTreeMap<String, Vec<CountPair>> = BTreeMap::new();
    for p in pairs {
        groups.entry(p.view.clone()).or_default().push(p.clone());
    }
    groups
        .into_iter()
        .map(|(k, v)| (k, CountMetrics::of(&v)))
        .collect()
}

/// Renders the confusion as a text table: rows are true counts, columns predicted.
pub fn confusion_table(pairs: &[CountPair]) -> String {
    let m = confusion(pairs);
    if m.is_empty() {
        return String::new();
    }
    let lo = pairs.iter().map(|p| p.truth.min(p.predicted)).min().unwrap_or(0);
    let hi = pairs.iter().map(|p| p.truth.max(p.predicted)).max().unwrap_or(0);
    let mut s = String::from("true\\pred");
    for c in lo..=hi {
        s.push_str(&format!("{c:>4}"));
    }
    s.push('\n');
    for r in lo..=hi {
        if !pairs.iter().any(|p| p.truth == r) {
            continue;
        }
        s.push_str(&format!("{r:>9}"));
        for c in lo..=hi {
            match m.get(&(r, c)) {
                Some(n) => s.push_str(&format!("{n:>4}")),
                None => s.push_str("   ."),
            }
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(t: u32, p: u32, view: &str) -> CountPair {
        CountPair {
            file: String::new(),
            view: view.into(),
            truth: t,
            predicted: p,
        }
    }

    #[test]
    fn metrics_match_hand_computation() {
        let pairs = [
            pair(5, 5, "a"),
            pair(6, 7, "a"),
            pair(8, 6, "b"),
            pair(10, 10, "b"),
        ];
        let m = CountMetrics::of(&pairs);
        assert_eq!(m.images, 4);
        assert_eq!(m.exact, 0.5);
        assert_eq!(m.within_1, 0.75);
        assert!((m.rmse - (5.0f64 / 4.0).sqrt()).abs() < 1e-12);
        assert_eq!(m.mae, 0.75);
        assert_eq!(m.bias, -0.25);
        // SStot of truth (5,6,8,10; mean 7.25) = 15.5 + ... = 14.75; SSres = 5.
        assert!((m.r2 - (1.0 - 5.0 / 14.75)).abs() < 1e-12);
        let v = per_view(&pairs);
        assert_eq!(v["a"].exact, 0.5);
        assert_eq!(v["b"].bias, -1.0);
        assert_eq!(confusion(&pairs)[&(8, 6)], 1);
        let table = confusion_table(&pairs);
        assert!(table.lines().count() == 5, "{table}");
    }

    #[test]
    fn perfect_predictions_fit_the_identity() {
        let pairs: Vec<_> = (4..12).map(|n| pair(n, n, "x")).collect();
        let m = CountMetrics::of(&pairs);
        assert_eq!((m.exact, m.rmse, m.r2), (1.0, 0.0, 1.0));
        assert!((m.slope - 1.0).abs() < 1e-12 && m.intercept.abs() < 1e-9);
    }
}
