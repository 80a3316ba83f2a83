//! Plants → groups (genotype, treatment, ...) and each group's summary: what
//! a breeder compares. Plant ids carry the design of the experiment
//! (`402-348-N276-WW-1`); `[groups] pattern` reads its parts with named
//! groups, and `[groups] by` says which parts make a group.

use serde::Deserialize;
use std::collections::BTreeMap;

use anyhow::{bail, Context};
use regex::Regex;
use serde::Serialize;

use crate::domain::plant::PlantTimeline;

/// `[groups]`: the experiment's design read from plant ids, for
/// `phyllo groups` and the nightly `groups.csv` / `group_days.csv`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GroupsConfig {
    /// Regular expression matched against each plant id, with named groups
    /// for its parts (`(?P<genotype>...)`). Unset: no group summaries.
    pub pattern: Option<String>,
    /// The named groups that make a group, in order; empty means all of them.
    pub by: Vec<String>,
    /// A named group of the pattern that holds the experiment's block
    /// (replicate, bench, compartment): group comparisons are then made
    /// within blocks and tested over them ([`crate::domain::group_compare`]).
    pub block: Option<String>,
}

/// How plant ids map to groups.
#[derive(Debug, Clone)]
pub struct GroupRule {
    regex: Regex,
    by: Vec<String>,
    block: Option<String>,
}

impl GroupRule {
    /// The rule of `[groups]`; `None` when no pattern is set.
    pub fn from_config(cfg: &GroupsConfig) -> anyhow::Result<Option<GroupRule>> {
        let Some(pattern) = &cfg.pattern else {
            if !cfg.by.is_empty() {
                bail!("groups.by is set but groups.pattern is not");
            }
            return Ok(None);
        };
        let regex = Regex::new(pattern).with_context(|| format!("groups.pattern {pattern:?}"))?;
        let names: Vec<String> = regex.capture_names().flatten().map(String::from).collect();
        if names.is_empty() {
            bail!("groups.pattern {pattern:?} has no named group, e.g. (?P<genotype>...)");
        }
        let by = if cfg.by.is_empty() {
            names.clone()
        } else {
            cfg.by.clone()
        };
        for b in &by {
            if !names.contains(b) {
                bail!(
                    "groups.by names {b:?}, which groups.pattern does not capture (it has: {})",
                    names.join(", ")
                );
            }
        }
        if let Some(block) = &cfg.block {
            if !names.contains(block) {
                bail!(
                    "groups.block names {block:?}, which groups.pattern does not capture (it has: {})",
                    names.join(", ")
                );
            }
            if by.contains(block) {
                bail!(
                    "groups.block {block:?} is also in groups.by: a block cannot be compared within itself"
                );
            }
        }
        Ok(Some(GroupRule {
            regex,
            by,
            block: cfg.block.clone(),
        }))
    }

    /// The parts that make a group, in order (the CSV's first columns).
    pub fn columns(&self) -> &[String] {
        &self.by
    }

    /// The name of the block field (`[groups] block`), if set.
    pub fn block_name(&self) -> Option<&str> {
        self.block.as_deref()
    }

    /// The plant's block, `None` if its id does not match or no block is set.
    pub fn block_of(&self, plant: &str) -> Option<String> {
        let block = self.block.as_ref()?;
        let caps = self.regex.captures(plant)?;
        Some(caps.name(block).map_or("", |m| m.as_str()).to_string())
    }

    /// The plant's group (one value per [`Self::columns`]), `None` if its id
    /// does not match.
    pub fn group_of(&self, plant: &str) -> Option<Vec<String>> {
        let caps = self.regex.captures(plant)?;
        Some(
            self.by
                .iter()
                .map(|b| caps.name(b).map_or("", |m| m.as_str()).to_string())
                .collect(),
        )
    }
}

/// Mean, standard deviation (n − 1) and number of values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation; 0 for a single value.
    pub sd: f64,
    /// Number of values.
    pub n: usize,
}

impl Spread {
    /// The spread of `xs`; `None` when empty.
    pub fn of(xs: &[f64]) -> Option<Spread> {
        let n = xs.len();
        if n == 0 {
            return None;
        }
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = if n > 1 {
            (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Some(Spread { mean, sd, n })
    }
}

/// One group's summary: where its plants stand at their latest session.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupSummary {
    /// The group's values, one per [`GroupRule::columns`].
    pub group: Vec<String>,
    /// Plants in the group.
    pub plants: usize,
    /// Leaves emerged at each plant's latest session.
    pub leaves_emerged: Option<Spread>,
    /// Living leaves at each plant's latest session.
    pub living: Option<Spread>,
    /// Leaves lost by each plant's latest session.
    pub leaves_lost: Option<Spread>,
    /// Days per leaf, over the plants that have one.
    pub phyllochron_days: Option<Spread>,
    /// Degree-days per leaf, over the plants that have one (a temperature
    /// log covering their leaves).
    pub phyllochron_cd: Option<Spread>,
    /// First and last session of any of its plants (facility time).
    pub first_session: String,
    /// See `first_session`.
    pub last_session: String,
}

/// One group on one calendar day: its plants imaged that day.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupDay {
    /// The group's values.
    pub group: Vec<String>,
    /// Calendar date (YYYY-MM-DD, facility time).
    pub date: String,
    /// Leaves emerged over the plants imaged that day (a plant's last session of the day).
    pub leaves_emerged: Spread,
    /// Living leaves, likewise.
    pub living: Spread,
}

/// Everything the group report holds.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct GroupReport {
    /// One row per group, in group order.
    pub summaries: Vec<GroupSummary>,
    /// One row per group and day, in group then date order.
    pub days: Vec<GroupDay>,
    /// Plants whose id the pattern does not match.
    pub unmatched: Vec<String>,
}

/// Groups the plants by `rule` and summarises each group.
pub fn summarise(rule: &GroupRule, plants: &[PlantTimeline]) -> GroupReport {
    let mut by_group: BTreeMap<Vec<String>, Vec<&PlantTimeline>> = BTreeMap::new();
    let mut unmatched = Vec::new();
    for p in plants {
        match rule.group_of(&p.plant) {
            Some(g) => by_group.entry(g).or_default().push(p),
            None => unmatched.push(p.plant.clone()),
        }
    }
    let mut report = GroupReport {
        unmatched,
        ..GroupReport::default()
    };
    for (group, members) in by_group {
        let latest: Vec<_> = members.iter().filter_map(|p| p.sessions.last()).collect();
        let pick = |f: fn(&crate::domain::plant::SessionRow) -> f64| {
            Spread::of(&latest.iter().map(|s| f(s)).collect::<Vec<_>>())
        };
        let starts = members
            .iter()
            .flat_map(|p| p.sessions.iter().map(|s| s.start.as_str()));
        report.summaries.push(GroupSummary {
            group: group.clone(),
            plants: members.len(),
            leaves_emerged: pick(|s| s.leaves_emerged),
            living: pick(|s| s.living),
            leaves_lost: pick(|s| s.leaves_lost),
            phyllochron_days: Spread::of(
                &members
                    .iter()
                    .filter_map(|p| p.phyllochron_days)
                    .collect::<Vec<_>>(),
            ),
            phyllochron_cd: Spread::of(
                &members
                    .iter()
                    .filter_map(|p| p.phyllochron_cd)
                    .collect::<Vec<_>>(),
            ),
            first_session: starts.clone().min().unwrap_or_default().to_string(),
            last_session: starts.max().unwrap_or_default().to_string(),
        });
        // Per day, each plant's last session of that day.
        let mut per_day: BTreeMap<&str, Vec<(f64, f64)>> = BTreeMap::new();
        for p in &members {
            let mut last_of_day: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
            for s in &p.sessions {
                last_of_day.insert(&s.start[..s.start.len().min(10)], (s.leaves_emerged, s.living));
            }
            for (day, v) in last_of_day {
                per_day.entry(day).or_default().push(v);
            }
        }
        for (date, vals) in per_day {
            let emerged: Vec<f64> = vals.iter().map(|v| v.0).collect();
            let living: Vec<f64> = vals.iter().map(|v| v.1).collect();
            report.days.push(GroupDay {
                group: group.clone(),
                date: date.to_string(),
                leaves_emerged: Spread::of(&emerged).expect("a day has a plant"),
                living: Spread::of(&living).expect("a day has a plant"),
            });
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::plant::SessionRow;

    fn rule(pattern: &str, by: &[&str]) -> anyhow::Result<Option<GroupRule>> {
        GroupRule::from_config(&GroupsConfig {
            pattern: Some(pattern.into()),
            by: by.iter().map(|s| s.to_string()).collect(),
            block: None,
        })
    }

    const UNL: &str =
        r"^(?P<experiment>\d+)-(?P<pot>\d+)-(?P<genotype>[^-]+)-(?P<treatment>WW|WL)-(?P<rep>\d+)$";

    #[test]
    fn plant_ids_map_to_groups() {
        let r = rule(UNL, &["genotype", "treatment"]).unwrap().unwrap();
        assert_eq!(r.columns(), ["genotype", "treatment"]);
        assert_eq!(
            r.group_of("402-348-N276-WW-1"),
            Some(vec!["N276".into(), "WW".into()])
        );
        assert_eq!(r.group_of("81-265-CML332"), None);
        // `by` empty: every named group, in pattern order.
        let all = rule(r"^SYN-(?P<genotype>[a-z0-9]+)-(?P<n>\d+)$", &[])
            .unwrap()
            .unwrap();
        assert_eq!(all.columns(), ["genotype", "n"]);
    }

    #[test]
    fn bad_rules_are_refused_with_the_reason() {
        let e = rule(UNL, &["variety"]).unwrap_err().to_string();
        assert!(e.contains("\"variety\"") && e.contains("genotype"), "{e}");
        assert!(rule(r"^\d+$", &[])
            .unwrap_err()
            .to_string()
            .contains("no named group"));
        assert!(rule("(?P<g>[", &[]).is_err());
        let by_alone = GroupsConfig {
            pattern: None,
            by: vec!["genotype".into()],
            block: None,
        };
        assert!(GroupRule::from_config(&by_alone).is_err());
        assert!(GroupRule::from_config(&GroupsConfig::default())
            .unwrap()
            .is_none());
    }

    #[test]
    fn spread_is_the_sample_spread() {
        assert_eq!(Spread::of(&[]), None);
        assert_eq!(
            Spread::of(&[4.0]),
            Some(Spread {
                mean: 4.0,
                sd: 0.0,
                n: 1
            })
        );
        let s = Spread::of(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]).unwrap();
        assert_eq!(s.mean, 5.0);
        assert!((s.sd - (32.0f64 / 7.0).sqrt()).abs() < 1e-12);
    }

    fn plant(name: &str, sessions: &[(&str, f64, f64)], phyllochron: Option<f64>) -> PlantTimeline {
        PlantTimeline {
            plant: name.into(),
            phyllochron_days: phyllochron,
            phyllochron_cd: phyllochron.map(|d| d * 12.0),
            climate_zone: String::new(),
            next_leaf: None,
            sessions: sessions
                .iter()
                .map(|&(start, emerged, living)| SessionRow {
                    start: start.into(),
                    views: BTreeMap::new(),
                    fused: living,
                    leaves_emerged: emerged,
                    living,
                    leaves_lost: emerged - living,
                })
                .collect(),
            events: Vec::new(),
            sites: Vec::new(),
        }
    }

    #[test]
    fn groups_are_summarised_at_each_plants_latest_session_and_per_day() {
        let r = rule(r"^(?P<genotype>[A-Z]+)-\d+$", &[]).unwrap().unwrap();
        let plants = [
            plant(
                "A-1",
                &[
                    ("2026-11-01T10:00:00.000", 4.0, 4.0),
                    ("2026-11-02T10:00:00.000", 5.0, 5.0),
                ],
                Some(2.0),
            ),
            plant(
                "A-2",
                &[
                    ("2026-11-01T10:00:00.000", 6.0, 6.0),
                    ("2026-11-01T16:00:00.000", 7.0, 6.0),
                ],
                Some(3.0),
            ),
            plant("B-1", &[("2026-11-02T09:00:00.000", 3.0, 3.0)], None),
            plant("odd", &[("2026-11-02T09:00:00.000", 3.0, 3.0)], None),
        ];
        let rep = summarise(&r, &plants);
        assert_eq!(rep.unmatched, ["odd"]);
        let a = &rep.summaries[0];
        assert_eq!((a.group.clone(), a.plants), (vec!["A".to_string()], 2));
        assert_eq!(a.leaves_emerged.unwrap().mean, 6.0); // 5 and 7
        assert_eq!(a.leaves_lost.unwrap().mean, 0.5); // 0 and 1
        let ph = a.phyllochron_days.unwrap();
        assert_eq!((ph.mean, ph.n), (2.5, 2));
        assert_eq!(a.first_session, "2026-11-01T10:00:00.000");
        assert_eq!(a.last_session, "2026-11-02T10:00:00.000");
        let b = &rep.summaries[1];
        assert_eq!((b.plants, b.phyllochron_days), (1, None));
        // Day 1: A-1 at 4, A-2's later session of the day at 7; day 2: A-1 only.
        let days: Vec<(String, f64, usize)> = rep
            .days
            .iter()
            .filter(|d| d.group == ["A"])
            .map(|d| (d.date.clone(), d.leaves_emerged.mean, d.leaves_emerged.n))
            .collect();
        assert_eq!(
            days,
            [
                ("2026-11-01".to_string(), 5.5, 2),
                ("2026-11-02".to_string(), 5.0, 1)
            ]
        );
    }
}
