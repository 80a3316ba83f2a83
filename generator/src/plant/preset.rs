//! Genotype presets: plain TOML data files (in `generator/presets/`) that give
//! the distributions a plant's parameters are drawn from. The built-in ones
//! are embedded at compile time; any other file can be loaded by path. Every
//! preset is validated on load so a typo is reported with its file and field,
//! not discovered as a strange-looking plant.

use serde::Deserialize;
use std::path::Path;

/// A closed interval `[lo, hi]` a parameter is drawn from uniformly.
pub type Range = [f32; 2];

/// Error raised when a preset cannot be found, read, parsed or validated.
#[derive(Debug, thiserror::Error)]
pub enum PresetError {
    /// No built-in preset and no file with this name.
    #[error("unknown preset `{name}`: built-in presets are {known}; or pass a path to a .toml file")]
    Unknown {
        /// The name asked for.
        name: String,
        /// Comma-separated built-in names.
        known: String,
    },
    /// The file could not be read.
    #[error("preset file {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The TOML did not parse into the preset's shape.
    #[error("preset {origin}: {message}")]
    Parse {
        /// File path or built-in name.
        origin: String,
        /// Parser message (names the field and line).
        message: String,
    },
    /// A value is out of its allowed range.
    #[error("preset {origin}: `{field}` {problem}")]
    Invalid {
        /// File path or built-in name.
        origin: String,
        /// Dotted field name.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

/// A genotype preset.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    /// Short name used on the command line and in manifests.
    pub name: String,
    /// `sorghum` or `maize`.
    pub species: String,
    /// Free text: where the numbers come from.
    #[serde(default)]
    pub description: String,
    /// Relative weight when a dataset mixes presets (0 = only on request).
    #[serde(default = "one")]
    pub weight: f32,
    /// Leaf emergence, growth and life span.
    pub growth: Growth,
    /// Leaf shape.
    pub leaf: LeafShape,
    /// Stem and sheaths.
    pub stem: Stem,
    /// Colours (linear reflectance / transmittance).
    pub colour: Colour,
    /// Optional panicle (class 3).
    #[serde(default)]
    pub panicle: Option<Panicle>,
}

fn one() -> f32 {
    1.0
}

/// Timing of leaf emergence, expansion and death.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Growth {
    /// Total number of leaves the plant will produce.
    pub final_leaf_count: [u32; 2],
    /// Day after sowing the first leaf tip appears.
    pub first_emergence_day: Range,
    /// Days between successive leaf tip appearances.
    pub phyllochron_days: Range,
    /// Days from tip appearance to a fully expanded leaf.
    pub expansion_days: Range,
    /// Days a leaf lives after full expansion (lower leaves die first).
    pub lifespan_days: Range,
    /// Days of visible senescence (yellowing, browning) before death.
    pub senescence_days: Range,
    /// Share of plants whose dead leaves leave remnants: the dried sheath
    /// stays wrapped round the stem with a shrivelled stub of blade hanging
    /// from its collar, both labelled stem. Real grown plants carry them
    /// (the real crop `402-586…SV_288` has several, each counted as a leaf);
    /// 0, the default, makes a dead leaf vanish whole, as before.
    #[serde(default)]
    pub dead_remnant_chance: f32,
}

/// Leaf blade geometry.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LeafShape {
    /// Final blade length of the longest leaf (scene units).
    pub max_length: Range,
    /// Relative rank (0 = first leaf, 1 = last) of the longest leaf.
    pub longest_rank: Range,
    /// Length of the first leaf relative to the longest.
    pub first_length_fraction: Range,
    /// Length of the last (flag) leaf relative to the longest.
    pub last_length_fraction: Range,
    /// Maximum blade width relative to its length.
    pub width_ratio: Range,
    /// Relative position along the blade of the widest point.
    pub width_peak: Range,
    /// Width at the collar relative to the maximum.
    pub base_width: Range,
    /// Blade angle from vertical at the collar, degrees, for mature leaves.
    pub insertion_angle_deg: Range,
    /// Extra insertion angle per leaf rank below the top, degrees.
    pub insertion_angle_per_rank_deg: Range,
    /// Bending under weight: 0 = straight, 1 = tip turned about horizontal.
    pub droop: Range,
    /// Half-angle of the V across the midrib, degrees.
    pub v_angle_deg: Range,
    /// Margin waviness amplitude relative to the local half-width.
    pub waviness: Range,
    /// Margin wave length (scene units).
    pub wave_length: Range,
    /// Total twist of the blade from collar to tip, degrees.
    pub twist_deg: Range,
    /// Standard deviation of the azimuth around the two distichous ranks, degrees.
    pub azimuth_sd_deg: f32,
    /// Lateral wander of the skeleton relative to length.
    pub wander: Range,
    /// Chance that the longest leaf buckles at its midrib and hangs from a
    /// sharp fold instead of an even arc; shorter leaves buckle less often
    /// in proportion to their length. Real drooping maize and sorghum leaves
    /// do this, and models trained on even arcs split them at the fold.
    #[serde(default)]
    pub kink_chance: f32,
    /// Relative position along the blade of the fold.
    #[serde(default = "default_kink_position")]
    pub kink_position: Range,
    /// Extra bend at the fold, degrees.
    #[serde(default)]
    pub kink_angle_deg: Range,
}

fn default_kink_position() -> Range {
    [0.4, 0.7]
}

/// Stem and sheath geometry.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stem {
    /// Stem radius at the base (scene units).
    pub base_radius: Range,
    /// Final length of an elongated internode (scene units).
    pub internode_length: Range,
    /// Internodes of leaves below this rank stay short.
    pub elongation_start_rank: u32,
    /// Days an internode takes to elongate.
    pub elongation_days: Range,
    /// Sheath length relative to its blade's final length.
    pub sheath_fraction: Range,
}

/// Linear RGB colours of plant tissue.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Colour {
    /// Diffuse reflectance of a healthy leaf.
    pub leaf_reflectance: [f32; 3],
    /// Diffuse transmittance of a healthy leaf.
    pub leaf_transmittance: [f32; 3],
    /// Reflectance of a yellowing (senescing) leaf.
    pub senescent_reflectance: [f32; 3],
    /// Reflectance of a dry, brown leaf just before it dies.
    pub dry_reflectance: [f32; 3],
    /// Reflectance of stem and sheaths.
    pub stem_reflectance: [f32; 3],
    /// Multiplicative jitter applied per plant to the colours.
    pub jitter: f32,
}

/// Panicle (inflorescence) parameters.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Panicle {
    /// Day after sowing the panicle appears above the flag leaf.
    pub emergence_day: Range,
    /// Panicle length (scene units).
    pub length: Range,
    /// Panicle radius (scene units).
    pub radius: Range,
    /// Panicle reflectance.
    pub reflectance: [f32; 3],
}

const BUILTIN: &[(&str, &str)] = &[
    ("btx623", include_str!("../../presets/btx623.toml")),
    ("tx3197", include_str!("../../presets/tx3197.toml")),
    ("rtx430", include_str!("../../presets/rtx430.toml")),
    ("sc301", include_str!("../../presets/sc301.toml")),
    ("pawaga", include_str!("../../presets/pawaga.toml")),
    ("maize", include_str!("../../presets/maize.toml")),
    ("maize-late", include_str!("../../presets/maize-late.toml")),
    ("maize-whorl", include_str!("../../presets/maize-whorl.toml")),
];

impl Preset {
    /// Names of the built-in presets.
    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN.iter().map(|(n, _)| *n).collect()
    }

    /// All built-in presets, validated.
    pub fn builtins() -> Result<Vec<Preset>, PresetError> {
        BUILTIN
            .iter()
            .map(|(n, t)| Preset::parse(t, &format!("built-in `{n}`")))
            .collect()
    }

    /// A built-in preset by name, or a preset file by path.
    pub fn load(name_or_path: &str) -> Result<Preset, PresetError> {
        let key = name_or_path.to_ascii_lowercase();
        if let Some((n, t)) = BUILTIN.iter().find(|(n, _)| *n == key) {
            return Preset::parse(t, &format!("built-in `{n}`"));
        }
        let path = Path::new(name_or_path);
        if path.extension().is_some_and(|e| e == "toml") || path.exists() {
            let text = std::fs::read_to_string(path).map_err(|source| PresetError::Io {
                path: path.display().to_string(),
                source,
            })?;
            return Preset::parse(&text, &path.display().to_string());
        }
        Err(PresetError::Unknown {
            name: name_or_path.into(),
            known: Self::builtin_names().join(", "),
        })
    }

    /// Parses and validates preset text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Preset, PresetError> {
        let preset: Preset = toml::from_str(text).map_err(|e| PresetError::Parse {
            origin: origin.into(),
            message: e.to_string(),
        })?;
        preset.validate(origin)?;
        Ok(preset)
    }

    /// Checks every value against its allowed range, reporting the first
    /// offender by its dotted field name.
    fn validate(&self, origin: &str) -> Result<(), PresetError> {
        let bad = |field: &str, problem: String| invalid(origin, field, problem);
        if self.name.is_empty() || !self.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '-') {
            return bad(
                "name",
                format!(
                    "must be non-empty ASCII letters, digits or '-', got {:?}",
                    self.name
                ),
            );
        }
        if self.species != "sorghum" && self.species != "maize" {
            return bad(
                "species",
                format!("must be \"sorghum\" or \"maize\", got {:?}", self.species),
            );
        }
        if !(self.weight >= 0.0 && self.weight.is_finite()) {
            return bad(
                "weight",
                format!("must be a finite number >= 0, got {}", self.weight),
            );
        }
        let [lo, hi] = self.growth.final_leaf_count;
        if lo > hi || lo < 4 || hi > 30 {
            return bad(
                "growth.final_leaf_count",
                format!("must be an ordered pair within 4..=30, got [{lo}, {hi}]"),
            );
        }
        self.validate_ranges(origin)?;
        self.colour.validate(origin)?;
        match &self.panicle {
            Some(p) => p.validate(origin),
            None => Ok(()),
        }
    }

    /// The drawn parameters: each a finite, ordered pair within its bounds
    /// (a single chance or spread stands as a pair of itself).
    fn validate_ranges(&self, origin: &str) -> Result<(), PresetError> {
        let g = &self.growth;
        let l = &self.leaf;
        let s = &self.stem;
        let ranges: [(&str, Range, f32, f32); 30] = [
            ("growth.first_emergence_day", g.first_emergence_day, 0.0, 30.0),
            ("growth.phyllochron_days", g.phyllochron_days, 0.5, 15.0),
            ("growth.expansion_days", g.expansion_days, 1.0, 30.0),
            ("growth.lifespan_days", g.lifespan_days, 1.0, 200.0),
            ("growth.senescence_days", g.senescence_days, 0.5, 60.0),
            (
                "growth.dead_remnant_chance",
                [g.dead_remnant_chance, g.dead_remnant_chance],
                0.0,
                1.0,
            ),
            ("leaf.max_length", l.max_length, 0.05, 2.0),
            ("leaf.longest_rank", l.longest_rank, 0.0, 1.0),
            ("leaf.first_length_fraction", l.first_length_fraction, 0.01, 1.0),
            ("leaf.last_length_fraction", l.last_length_fraction, 0.01, 1.0),
            ("leaf.width_ratio", l.width_ratio, 0.005, 0.5),
            ("leaf.width_peak", l.width_peak, 0.05, 0.95),
            ("leaf.base_width", l.base_width, 0.05, 1.0),
            ("leaf.insertion_angle_deg", l.insertion_angle_deg, 0.0, 90.0),
            (
                "leaf.insertion_angle_per_rank_deg",
                l.insertion_angle_per_rank_deg,
                0.0,
                20.0,
            ),
            ("leaf.droop", l.droop, 0.0, 2.0),
            ("leaf.v_angle_deg", l.v_angle_deg, 0.0, 80.0),
            ("leaf.waviness", l.waviness, 0.0, 1.0),
            ("leaf.wave_length", l.wave_length, 0.005, 1.0),
            ("leaf.twist_deg", l.twist_deg, -360.0, 360.0),
            ("leaf.wander", l.wander, 0.0, 0.3),
            ("leaf.kink_chance", [l.kink_chance, l.kink_chance], 0.0, 1.0),
            ("leaf.kink_position", l.kink_position, 0.1, 0.9),
            ("leaf.kink_angle_deg", l.kink_angle_deg, 0.0, 120.0),
            ("stem.base_radius", s.base_radius, 0.001, 0.1),
            ("stem.internode_length", s.internode_length, 0.0, 0.5),
            ("stem.elongation_days", s.elongation_days, 0.5, 60.0),
            ("stem.sheath_fraction", s.sheath_fraction, 0.0, 1.0),
            (
                "colour.jitter",
                [self.colour.jitter, self.colour.jitter],
                0.0,
                0.5,
            ),
            (
                "leaf.azimuth_sd_deg",
                [l.azimuth_sd_deg, l.azimuth_sd_deg],
                0.0,
                90.0,
            ),
        ];
        for (field, [lo, hi], min, max) in ranges {
            if !lo.is_finite() || !hi.is_finite() {
                return invalid(origin, field, format!("must be finite, got [{lo}, {hi}]"));
            }
            if lo > hi {
                return invalid(
                    origin,
                    field,
                    format!("lower bound {lo} is above upper bound {hi}"),
                );
            }
            if lo < min || hi > max {
                return invalid(
                    origin,
                    field,
                    format!("must lie within [{min}, {max}], got [{lo}, {hi}]"),
                );
            }
        }
        Ok(())
    }
}

impl Colour {
    /// Every component a fraction, and no leaf that reflects and transmits
    /// more light than it receives.
    fn validate(&self, origin: &str) -> Result<(), PresetError> {
        let colours = [
            ("colour.leaf_reflectance", self.leaf_reflectance),
            ("colour.leaf_transmittance", self.leaf_transmittance),
            ("colour.senescent_reflectance", self.senescent_reflectance),
            ("colour.dry_reflectance", self.dry_reflectance),
            ("colour.stem_reflectance", self.stem_reflectance),
        ];
        for (field, rgb) in colours {
            if rgb.iter().any(|v| !(0.0..=1.0).contains(v)) {
                return invalid(
                    origin,
                    field,
                    format!("components must lie within [0, 1], got {rgb:?}"),
                );
            }
        }
        for i in 0..3 {
            if self.leaf_reflectance[i] + self.leaf_transmittance[i] > 1.0 {
                return invalid(
                    origin,
                    "colour.leaf_transmittance",
                    "reflectance + transmittance must not exceed 1 in any channel (energy)".into(),
                );
            }
        }
        Ok(())
    }
}

impl Panicle {
    /// Ordered ranges within bounds, and a fraction for every colour component.
    fn validate(&self, origin: &str) -> Result<(), PresetError> {
        for (field, [lo, hi], min, max) in [
            ("panicle.emergence_day", self.emergence_day, 1.0, 400.0),
            ("panicle.length", self.length, 0.01, 1.0),
            ("panicle.radius", self.radius, 0.002, 0.3),
        ] {
            if !(lo <= hi && lo >= min && hi <= max) {
                return invalid(
                    origin,
                    field,
                    format!("must be an ordered pair within [{min}, {max}], got [{lo}, {hi}]"),
                );
            }
        }
        if self.reflectance.iter().any(|v| !(0.0..=1.0).contains(v)) {
            return invalid(
                origin,
                "panicle.reflectance",
                format!("components must lie within [0, 1], got {:?}", self.reflectance),
            );
        }
        Ok(())
    }
}

/// The error for `field` of the preset from `origin`.
fn invalid(origin: &str, field: &str, problem: String) -> Result<(), PresetError> {
    Err(PresetError::Invalid {
        origin: origin.into(),
        field: field.into(),
        problem,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_validate() {
        let all = Preset::builtins().unwrap();
        assert!(all.len() >= 6);
        assert!(all.iter().any(|p| p.species == "maize"));
    }

    #[test]
    fn errors_name_the_field() {
        let text = include_str!("../../presets/btx623.toml").replace("droop = [", "droop = [3.0, 4.0] #");
        let err = Preset::parse(&text, "x.toml").unwrap_err().to_string();
        assert!(err.contains("x.toml") && err.contains("leaf.droop"), "{err}");
        let text = include_str!("../../presets/btx623.toml").replace("[leaf]", "[leaf]\nbogus = 1");
        let err = Preset::parse(&text, "y.toml").unwrap_err().to_string();
        assert!(err.contains("y.toml") && err.contains("bogus"), "{err}");
        let err = Preset::load("nope").unwrap_err().to_string();
        assert!(err.contains("unknown preset") && err.contains("btx623"), "{err}");
        let err = Preset::load("/nonexistent/p.toml").unwrap_err().to_string();
        assert!(err.contains("/nonexistent/p.toml"), "{err}");
    }
}
