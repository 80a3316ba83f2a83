//! Are two groups different? Pairwise Welch t-tests between every two groups
//! on what [`crate::domain::groups`] summarises per plant: phyllochron (days per
//! leaf, and degree-days per leaf with a temperature log) and leaves emerged
//! at each plant's latest session.
//!
//! Welch's test does not assume equal variances, which genotypes seldom
//! have. Where the experiment is laid out in blocks (replicates, benches,
//! compartments: `[groups] block`), plants of one block share its light,
//! temperature and position, and a comparison across blocks mixes those
//! into the difference. Then each pair is compared within each block the
//! two groups share (the difference of their means there), and those
//! differences are tested against zero over the blocks (a paired t-test on
//! block means, the randomised complete block analysis of one pair); a block
//! holding only one of the two adds nothing. With many groups, many pairs are tested, so each p-value is also
//! given Holm-adjusted over the pairs of its measure: a pair with an
//! adjusted p under 0.05 stays a difference after that many looks. The test
//! treats plants as independent and the plant values as exact; phyllo's own
//! per-plant error (docs/daemon.md, "Groups") adds to the spread it sees, so
//! small true differences come out as not significant.

use std::collections::BTreeMap;

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, StudentsT};

use crate::domain::groups::GroupRule;
use crate::domain::plant::PlantTimeline;

/// One group's plant values: block (`""` without blocks) → one list per measure.
type Blocks = BTreeMap<String, [Vec<f64>; 3]>;

/// The measures compared, as named in the CSV.
pub const MEASURES: [&str; 3] = ["phyllochron_days", "phyllochron_cd", "leaves_emerged"];

/// One pair of groups on one measure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// What is compared (one of [`MEASURES`]).
    pub measure: &'static str,
    /// The first group's values (one per [`GroupRule::columns`]).
    pub a: Vec<String>,
    /// The second group's values.
    pub b: Vec<String>,
    /// Plants with a value in `a`.
    pub n_a: usize,
    /// Plants with a value in `b`.
    pub n_b: usize,
    /// Mean of `a`.
    pub mean_a: f64,
    /// Mean of `b`.
    pub mean_b: f64,
    /// `mean_a − mean_b`.
    pub difference: f64,
    /// 95 % confidence interval of the difference (Welch).
    pub ci95: (f64, f64),
    /// Welch's t statistic.
    pub t: f64,
    /// Welch–Satterthwaite degrees of freedom.
    pub df: f64,
    /// Two-sided p-value.
    pub p: f64,
    /// `p` Holm-adjusted over the pairs of this measure.
    pub p_holm: f64,
    /// Blocks both groups share with a value, for a comparison within blocks;
    /// `None` for Welch's test over plants.
    pub blocks: Option<usize>,
}

/// Every pair of groups with at least two plants valued on each side and
/// some spread, per measure; measures in [`MEASURES`] order, pairs in group
/// order.
/// With `[groups] block`, pairs are compared within blocks (at least two
/// blocks shared, and some spread of the block differences).
pub fn compare(rule: &GroupRule, plants: &[PlantTimeline]) -> Vec<Comparison> {
    let mut values: BTreeMap<Vec<String>, Blocks> = BTreeMap::new();
    for p in plants {
        let Some(group) = rule.group_of(&p.plant) else {
            continue;
        };
        let block = rule.block_of(&p.plant).unwrap_or_default();
        let v = values.entry(group).or_default().entry(block).or_default();
        v[0].extend(p.phyllochron_days);
        v[1].extend(p.phyllochron_cd);
        if let Some(last) = p.sessions.last() {
            v[2].push(last.leaves_emerged);
        }
    }
    let blocked = rule.block_name().is_some();
    let groups: Vec<(&Vec<String>, &Blocks)> = values.iter().collect();
    let mut out = Vec::new();
    for (m, measure) in MEASURES.iter().enumerate() {
        let first = out.len();
        for (i, (ga, va)) in groups.iter().enumerate() {
            for (gb, vb) in &groups[i + 1..] {
                let tested = if blocked {
                    within_blocks(va, vb, m)
                } else {
                    let all =
                        |v: &Blocks| -> Vec<f64> { v.values().flat_map(|x| x[m].iter().copied()).collect() };
                    welch(&all(va), &all(vb))
                };
                if let Some(c) = tested {
                    out.push(Comparison {
                        measure,
                        a: (*ga).clone(),
                        b: (*gb).clone(),
                        ..c
                    });
                }
            }
        }
        holm(&mut out[first..]);
    }
    out
}

/// The paired test over the blocks `a` and `b` share on measure `m`: each
/// block's difference of group means, tested against zero; `None` with
/// under two shared blocks or no spread of the differences.
fn within_blocks(a: &Blocks, b: &Blocks, m: usize) -> Option<Comparison> {
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    let (mut means_a, mut means_b, mut n_a, mut n_b) = (Vec::new(), Vec::new(), 0, 0);
    for (block, va) in a {
        let Some(vb) = b.get(block) else { continue };
        if va[m].is_empty() || vb[m].is_empty() {
            continue;
        }
        means_a.push(mean(&va[m]));
        means_b.push(mean(&vb[m]));
        n_a += va[m].len();
        n_b += vb[m].len();
    }
    let n = means_a.len();
    if n < 2 {
        return None;
    }
    let d: Vec<f64> = means_a.iter().zip(&means_b).map(|(x, y)| x - y).collect();
    let md = mean(&d);
    let var = d.iter().map(|x| (x - md).powi(2)).sum::<f64>() / (n - 1) as f64;
    if var <= 0.0 {
        return None;
    }
    let se = (var / n as f64).sqrt();
    Some(Comparison {
        n_a,
        n_b,
        blocks: Some(n),
        ..t_test(mean(&means_a), mean(&means_b), se, (n - 1) as f64)?
    })
}

/// Welch's test of `a` against `b`; `None` with under two values on a side
/// or no spread in either.
fn welch(a: &[f64], b: &[f64]) -> Option<Comparison> {
    let (na, nb) = (a.len(), b.len());
    if na < 2 || nb < 2 {
        return None;
    }
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    let var = |x: &[f64], m: f64| x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (x.len() - 1) as f64;
    let (ma, mb) = (mean(a), mean(b));
    let (qa, qb) = (var(a, ma) / na as f64, var(b, mb) / nb as f64);
    let se2 = qa + qb;
    if se2 <= 0.0 {
        return None;
    }
    let se = se2.sqrt();
    let df = se2 * se2 / (qa * qa / (na - 1) as f64 + qb * qb / (nb - 1) as f64);
    Some(Comparison {
        n_a: na,
        n_b: nb,
        ..t_test(ma, mb, se, df)?
    })
}

/// The t test of `mean_a − mean_b` with standard error `se` on `df` degrees
/// of freedom: t, the two-sided p-value and the 95 % interval, in a
/// comparison whose groups, sizes and measure the caller fills in.
fn t_test(mean_a: f64, mean_b: f64, se: f64, df: f64) -> Option<Comparison> {
    let dist = StudentsT::new(0.0, 1.0, df).ok()?;
    let difference = mean_a - mean_b;
    let t = difference / se;
    let p = (2.0 * (1.0 - dist.cdf(t.abs()))).clamp(0.0, 1.0);
    let half = dist.inverse_cdf(0.975) * se;
    Some(Comparison {
        measure: "",
        a: Vec::new(),
        b: Vec::new(),
        n_a: 0,
        n_b: 0,
        mean_a,
        mean_b,
        difference,
        ci95: (difference - half, difference + half),
        t,
        df,
        p,
        p_holm: p,
        blocks: None,
    })
}

/// Holm's step-down adjustment of the p-values of `pairs`, in place.
fn holm(pairs: &mut [Comparison]) {
    let m = pairs.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| pairs[i].p.total_cmp(&pairs[j].p));
    let mut running: f64 = 0.0;
    for (rank, &i) in order.iter().enumerate() {
        running = running.max(((m - rank) as f64 * pairs[i].p).min(1.0));
        pairs[i].p_holm = running;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::groups::GroupsConfig;
    use crate::domain::plant::SessionRow;

    fn plant(name: &str, phyllochron: f64, emerged: f64) -> PlantTimeline {
        PlantTimeline {
            plant: name.into(),
            phyllochron_days: Some(phyllochron),
            phyllochron_cd: None,
            climate_zone: String::new(),
            next_leaf: None,
            sessions: vec![SessionRow {
                start: "2026-11-01T08:00:00.000".into(),
                views: BTreeMap::new(),
                fused: emerged,
                leaves_emerged: emerged,
                living: emerged,
                leaves_lost: 0.0,
            }],
            events: Vec::new(),
            sites: Vec::new(),
        }
    }

    #[test]
    fn welch_matches_a_textbook_case() {
        // By hand: means 3.2 and 3.82, variances 0.025 and 0.037, so
        // t = -0.62 / sqrt(0.005 + 0.0074) = -5.5678 and
        // df = 0.0124² / (0.005²/4 + 0.0074²/4) = 7.7111. The p-value and the
        // 97.5 % quantile (2.32113) from the regularized incomplete beta
        // (mpmath: betainc(df/2, 1/2, 0, df/(df+t²), regularized=True)).
        let c = welch(&[3.0, 3.2, 3.4, 3.1, 3.3], &[3.6, 3.9, 3.7, 4.1, 3.8]).unwrap();
        assert!((c.t + 5.5678).abs() < 1e-4, "{c:?}");
        assert!((c.df - 7.7111).abs() < 1e-4, "{c:?}");
        assert!((c.p - 0.000_602_99).abs() < 1e-8, "{c:?}");
        assert!(
            (c.ci95.0 + 0.87847).abs() < 1e-5 && (c.ci95.1 + 0.36153).abs() < 1e-5,
            "{c:?}"
        );
        assert!(welch(&[1.0], &[2.0, 3.0]).is_none());
        assert!(welch(&[2.0, 2.0], &[2.0, 2.0]).is_none());
    }

    #[test]
    fn holm_adjusts_step_down_and_keeps_order() {
        let mut pairs: Vec<Comparison> = [0.01, 0.04, 0.03]
            .iter()
            .map(|&p| Comparison {
                p,
                ..welch(&[1.0, 2.0], &[3.0, 4.0]).unwrap()
            })
            .collect();
        holm(&mut pairs);
        let adjusted: Vec<f64> = pairs.iter().map(|c| c.p_holm).collect();
        // 3 × 0.01, then max(0.03, 2 × 0.03), then max(0.06, 1 × 0.04).
        assert!((adjusted[0] - 0.03).abs() < 1e-12 && (adjusted[2] - 0.06).abs() < 1e-12);
        assert!((adjusted[1] - 0.06).abs() < 1e-12, "{adjusted:?}");
    }

    #[test]
    fn every_pair_of_groups_is_compared_per_measure() {
        let rule = GroupRule::from_config(&GroupsConfig {
            pattern: Some(r"^(?P<genotype>[a-z]+)-\d+$".into()),
            by: Vec::new(),
            block: None,
        })
        .unwrap()
        .unwrap();
        let plants = [
            plant("fast-1", 2.0, 12.0),
            plant("fast-2", 2.2, 13.0),
            plant("fast-3", 1.9, 12.0),
            plant("slow-1", 4.1, 7.0),
            plant("slow-2", 3.9, 8.0),
            plant("slow-3", 4.0, 7.0),
            plant("lone-1", 3.0, 9.0),
            plant("other", 3.0, 9.0),
        ];
        let got = compare(&rule, &plants);
        // "lone" has one plant: nothing to test it with; "other" matches no pattern.
        assert_eq!(got.len(), 2);
        assert_eq!(
            (got[0].measure, got[0].a[0].as_str(), got[0].b[0].as_str()),
            ("phyllochron_days", "fast", "slow")
        );
        assert!(
            (got[0].difference + 1.9667).abs() < 1e-3 && got[0].p < 0.001,
            "{:?}",
            got[0]
        );
        assert_eq!(got[1].measure, "leaves_emerged");
        assert!(got[1].difference > 4.0 && got[1].p_holm == got[1].p);
    }

    /// Four replicate blocks whose benches differ by a day per leaf: across
    /// blocks the half-day genotype difference drowns (Welch), within them it
    /// is plain.
    #[test]
    fn blocks_take_the_bench_out_of_the_difference() {
        let cfg = |block: Option<&str>| GroupsConfig {
            pattern: Some(r"^(?P<genotype>g\d)-(?P<rep>r\d)-\d$".into()),
            by: vec!["genotype".into()],
            block: block.map(String::from),
        };
        let plants = [
            plant("g1-r1-1", 3.0, 10.0),
            plant("g1-r2-1", 4.05, 10.0),
            plant("g1-r3-1", 4.95, 10.0),
            plant("g1-r4-1", 6.0, 10.0),
            plant("g2-r1-1", 3.5, 11.0),
            plant("g2-r2-1", 4.5, 11.0),
            plant("g2-r3-1", 5.55, 12.0),
            plant("g2-r4-1", 6.45, 11.0),
            plant("g2-r5-1", 9.0, 11.0), // a block g1 is not in: no pair there
        ];
        let across = compare(&GroupRule::from_config(&cfg(None)).unwrap().unwrap(), &plants);
        assert!(across[0].p > 0.2 && across[0].blocks.is_none(), "{:?}", across[0]);
        let within = compare(
            &GroupRule::from_config(&cfg(Some("rep"))).unwrap().unwrap(),
            &plants,
        );
        let c = &within[0];
        // Block differences −0.5, −0.45, −0.6, −0.45: mean −0.5, SD 0.0707,
        // t = −0.5 / (0.0707 / 2) = −14.14 on 3 degrees of freedom.
        assert_eq!(
            (c.measure, c.blocks, c.n_a, c.n_b),
            ("phyllochron_days", Some(4), 4, 4)
        );
        assert!(
            (c.difference + 0.5).abs() < 1e-9 && (c.t + 14.142).abs() < 1e-2,
            "{c:?}"
        );
        assert!(c.df == 3.0 && c.p < 0.001 && c.ci95.1 < 0.0, "{c:?}");
        assert!(
            (c.mean_a - 4.5).abs() < 1e-9 && (c.mean_b - 5.0).abs() < 1e-9,
            "{c:?}"
        );
        let bad = GroupsConfig {
            block: Some("genotype".into()),
            ..cfg(None)
        };
        assert!(
            GroupRule::from_config(&bad).is_err(),
            "a block cannot also make the groups"
        );
        let unknown = GroupsConfig {
            block: Some("bench".into()),
            ..cfg(None)
        };
        let err = format!("{:#}", GroupRule::from_config(&unknown).unwrap_err());
        assert!(err.contains("groups.block names \"bench\""), "{err}");
    }
}
