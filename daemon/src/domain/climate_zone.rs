//! Greenhouse compartments ("zones"), each with its own temperature log.
//!
//! One imaging station often serves plants grown in several compartments,
//! kept at different temperatures: a phyllochron in degree-days is only right
//! when each plant's leaves are timed against the air it grew in. A zone is
//! declared with a regular expression over plant ids (`[[timeline.zones]]`),
//! a temperature log names its zone in a `zone` column, and a plant takes the
//! log of the first zone whose expression matches its id. A plant in no zone,
//! and a log row without a zone, belong to the facility's log (zone `""`).

use serde::Deserialize;
use std::collections::BTreeMap;

use anyhow::{bail, Context};
use regex::Regex;

use crate::domain::thermal::ThermalClock;

/// `[[timeline.zones]]`: one greenhouse compartment ([`crate::domain::climate_zone`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZoneConfig {
    /// The name a temperature log's `zone` column gives.
    pub name: String,
    /// Regular expression over plant ids: the plants grown in this zone.
    pub plants: String,
}

/// The facility's log: readings without a zone, for plants in none.
pub const FACILITY: &str = "";

/// The declared zones, in the order they are tried.
#[derive(Debug, Clone, Default)]
pub struct ZoneRules {
    zones: Vec<(String, Regex)>,
}

impl ZoneRules {
    /// Compiles `[[timeline.zones]]`; errors name the zone and the problem.
    pub fn from_config(cfg: &[ZoneConfig]) -> anyhow::Result<ZoneRules> {
        let mut zones: Vec<(String, Regex)> = Vec::with_capacity(cfg.len());
        for z in cfg {
            check_name(&z.name).context("timeline.zones")?;
            if zones.iter().any(|(n, _)| n == &z.name) {
                bail!("timeline.zones: zone {:?} is declared twice", z.name);
            }
            let re = Regex::new(&z.plants)
                .with_context(|| format!("timeline.zones: zone {:?}: plants {:?}", z.name, z.plants))?;
            zones.push((z.name.clone(), re));
        }
        Ok(ZoneRules { zones })
    }

    /// The zone whose log times `plant`'s leaves; [`FACILITY`] when none matches.
    pub fn zone_of(&self, plant: &str) -> &str {
        self.zones
            .iter()
            .find(|(_, re)| re.is_match(plant))
            .map_or(FACILITY, |(name, _)| name.as_str())
    }

    /// True when `name` is a declared zone or the facility's log.
    pub fn knows(&self, name: &str) -> bool {
        name == FACILITY || self.zones.iter().any(|(n, _)| n == name)
    }

    /// The declared zone names, in order.
    pub fn names(&self) -> Vec<&str> {
        self.zones.iter().map(|(n, _)| n.as_str()).collect()
    }

    /// The rules as the stored fit's settings record them; empty without zones,
    /// so that a store from before zones existed is not refitted for nothing.
    pub fn fingerprint(&self) -> String {
        if self.zones.is_empty() {
            return String::new();
        }
        let parts: Vec<String> = self
            .zones
            .iter()
            .map(|(n, re)| format!("{n}={}", re.as_str()))
            .collect();
        format!(";zones={}", parts.join("|"))
    }
}

/// Every zone's thermal clock, and which one times each plant.
#[derive(Debug, Clone)]
pub struct ZoneClocks {
    rules: ZoneRules,
    clocks: BTreeMap<String, ThermalClock>,
}

impl ZoneClocks {
    /// Every zone's clock (`zone → clock`, [`FACILITY`] for the facility's log)
    /// and the rules that pick a plant's zone.
    pub fn new(rules: ZoneRules, clocks: BTreeMap<String, ThermalClock>) -> ZoneClocks {
        ZoneClocks { rules, clocks }
    }

    /// The clock that times `plant`'s leaves; `None` when its zone has no log.
    pub fn for_plant(&self, plant: &str) -> Option<&ThermalClock> {
        self.clocks.get(self.rules.zone_of(plant))
    }

    /// The zone whose log times `plant`.
    pub fn zone_of<'a>(&'a self, plant: &str) -> &'a str {
        self.rules.zone_of(plant)
    }

    /// True when no zone has a log.
    pub fn is_empty(&self) -> bool {
        self.clocks.is_empty()
    }
}

/// A zone's name: what a log's `zone` column and `phyllo status` show.
fn check_name(name: &str) -> anyhow::Result<()> {
    if name.is_empty() {
        bail!("a zone needs a name");
    }
    if !name
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ' '))
        || name.trim() != name
    {
        bail!("zone name {name:?}: use letters, digits, '-', '_', '.' and inner spaces");
    }
    Ok(())
}

/// Human wording of a zone: "zone house-2" or "the facility log".
pub fn describe(zone: &str) -> String {
    if zone == FACILITY {
        "the facility's temperature log".into()
    } else {
        format!("zone {zone}'s temperature log")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zone(name: &str, plants: &str) -> ZoneConfig {
        ZoneConfig {
            name: name.into(),
            plants: plants.into(),
        }
    }

    #[test]
    fn first_matching_zone_wins_and_others_fall_to_the_facility() {
        let rules = ZoneRules::from_config(&[zone("house-2", "^40[23]-"), zone("house-5", "^4")]).unwrap();
        assert_eq!(rules.zone_of("402-348-N276-WW-1"), "house-2");
        assert_eq!(rules.zone_of("404-1"), "house-5");
        assert_eq!(rules.zone_of("81-235"), FACILITY);
        assert!(rules.knows("house-5") && rules.knows(FACILITY) && !rules.knows("house-9"));
        assert_eq!(rules.fingerprint(), ";zones=house-2=^40[23]-|house-5=^4");
        assert_eq!(ZoneRules::default().fingerprint(), "");
    }

    #[test]
    fn bad_zones_are_named() {
        let err = format!(
            "{:#}",
            ZoneRules::from_config(&[zone("a", "x"), zone("a", "y")]).unwrap_err()
        );
        assert!(err.contains("\"a\" is declared twice"), "{err}");
        let err = format!("{:#}", ZoneRules::from_config(&[zone("h2", "(")]).unwrap_err());
        assert!(err.contains("zone \"h2\""), "{err}");
        let err = format!("{:#}", ZoneRules::from_config(&[zone("h/2", "x")]).unwrap_err());
        assert!(err.contains("h/2"), "{err}");
    }
}
