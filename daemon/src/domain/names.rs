//! File names → plant id, time taken and view.
//!
//! The facility has used three layouts (docs/ARCHITECTURE.md, "Facility facts"); each is a
//! built-in preset. Sites add their own regular expressions in the config.
//! Patterns are matched against the path *relative to the drop directory*
//! (with `/` separators), so the snapshot layouts can take the plant and time
//! from the folder name.

use serde::Deserialize;
use std::fmt;
use std::path::Path;

use anyhow::{bail, Context};
use chrono::{NaiveDate, NaiveDateTime, NaiveTime};
use regex::Regex;

/// `[names]`: file-name patterns.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NamesConfig {
    /// Built-in layouts to try, in order: `flat`, `snapshot-dir`, `snapshot-file`.
    pub presets: Vec<String>,
    /// Extra patterns, tried before the presets.
    pub patterns: Vec<PatternConfig>,
    /// The earliest capture date believed; an image named earlier (a station
    /// clock reset to 1970, a typo) fails instead of reaching the timeline.
    /// Times more than [`MAX_AHEAD_HOURS`] ahead of the clock fail too.
    pub earliest: NaiveDate,
}

impl Default for NamesConfig {
    fn default() -> Self {
        Self {
            presets: PRESET_NAMES.iter().map(|s| s.to_string()).collect(),
            patterns: vec![],
            earliest: NaiveDate::from_ymd_opt(2010, 1, 1).expect("a valid date"),
        }
    }
}

/// How far ahead of the service's clock a capture time may be (a station
/// clock running a little fast, a time zone's offset), in hours.
pub const MAX_AHEAD_HOURS: i64 = 24;

/// `[[names.patterns]]`: one custom file-name pattern.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternConfig {
    /// Name shown in errors and in `phyllo status`.
    pub name: String,
    /// Regular expression matched against the path relative to the drop
    /// directory, with `/` separators. Named groups: `plant`, `date`
    /// (YYYY-MM-DD), `time` (HH-MM-SS, HH:MM:SS or HHMMSS, optional fraction)
    /// are required; `kind` (`SV`/`side` or `TV`/`top`) and `angle` optional.
    pub regex: String,
}

/// Names of the built-in presets, in the order they are tried by default.
pub const PRESET_NAMES: [&str; 3] = ["flat", "snapshot-dir", "snapshot-file"];

const EXT: &str = r"(?i:png|jpe?g|tiff?)";
const DATE: &str = r"(?P<date>\d{4}-\d{2}-\d{2})";
const TIME: &str = r"(?P<time>\d{2}-\d{2}-\d{2}(?:\.\d+)?)";

/// The regular expression of a built-in preset.
pub fn preset_regex(name: &str) -> Option<String> {
    Some(match name {
        // <plant>_<YYYY-MM-DD>_<HH-MM-SS[.mmm]>_Vis_SV_<angle>[.Crp].<ext>
        "flat" => format!(
            r"(?:^|/)(?P<plant>[^/]+?)_{DATE}_{TIME}_Vis_(?P<kind>SV|TV)_(?P<angle>\d+)(?:\.Crp)?\.{EXT}$"
        ),
        // <date>_<experiment>_<plant>_<YYYY-MM-DD>_<HH-MM-SS>_<n>/Vis_SV_<angle>/0_0_0.png
        "snapshot-dir" => format!(
            r"(?:^|/)(?:[^/]*_)?(?P<plant>[^/_]+)_{DATE}_{TIME}_\d+/Vis_(?P<kind>SV|TV)_(?P<angle>\d+)/0_0_0\.{EXT}$"
        ),
        // <date>_<experiment>_<plant>_<YYYY-MM-DD>_<HH-MM-SS>_<n>/0_<angle>_0.png, top: top_0_90_0.png
        "snapshot-file" => format!(
            r"(?:^|/)(?:[^/]*_)?(?P<plant>[^/_]+)_{DATE}_{TIME}_\d+/(?:(?P<kind>top)_)?0_(?P<angle>\d+)_0\.{EXT}$"
        ),
        _ => return None,
    })
}

/// A file name each built-in layout reads, for error messages.
pub fn preset_example(name: &str) -> Option<&'static str> {
    Some(match name {
        "flat" => "P1_2019-05-10_09-18-07_Vis_SV_108.png",
        "snapshot-dir" => "2019-05-10_E1_P1_2019-05-10_09-18-07_1/Vis_SV_108/0_0_0.png",
        "snapshot-file" => "2019-05-10_E1_P1_2019-05-10_09-18-07_1/0_108_0.png",
        _ => return None,
    })
}

/// Which way the camera looked.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum View {
    /// Side view at this turntable angle (degrees).
    Side(u16),
    /// Top view (the facility labels it 90).
    Top(u16),
    /// Anything else, e.g. an imported person's count (`human`, see
    /// [`View::is_person`]); fused like a side view unless it is a person's.
    Other(String),
}

impl View {
    /// Parses the stored / imported form: `SV_108`, `Vis_SV_108`, `TV_90`,
    /// `top`, `side_36`; anything else becomes [`View::Other`].
    pub fn parse(s: &str) -> View {
        let t = s.trim();
        let t = t.strip_prefix("Vis_").unwrap_or(t);
        let upper = t.to_ascii_uppercase();
        let split = |rest: &str| rest.trim_start_matches(['_', '-', ' ']).parse::<u16>().ok();
        for (prefix, side) in [("SV", true), ("SIDE", true), ("TV", false), ("TOP", false)] {
            if let Some(rest) = upper.strip_prefix(prefix) {
                if rest.is_empty() && !side {
                    return View::Top(90);
                }
                if let Some(a) = split(rest) {
                    return if side { View::Side(a) } else { View::Top(a) };
                }
            }
        }
        View::Other(t.to_string())
    }

    /// True for the top view.
    pub fn is_top(&self) -> bool {
        matches!(self, View::Top(_))
    }

    /// True for a person's count brought in by `phyllo import`: the view
    /// `human` or `manual`, alone or with a name after a colon (`human:ana`).
    pub fn is_person(&self) -> bool {
        let View::Other(s) = self else { return false };
        let kind = s.split(':').next().unwrap_or("").trim();
        kind.eq_ignore_ascii_case("human") || kind.eq_ignore_ascii_case("manual")
    }
}

impl fmt::Display for View {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            View::Side(a) => write!(f, "SV_{a}"),
            View::Top(a) => write!(f, "TV_{a}"),
            View::Other(s) => f.write_str(s),
        }
    }
}

/// What a file name says about its image.
#[derive(Debug, Clone, PartialEq)]
pub struct ParsedName {
    /// Plant identifier (e.g. `402-127-N55-WW-1`).
    pub plant: String,
    /// When the image was taken (facility local time, as in the name).
    pub taken_at: NaiveDateTime,
    /// Camera view.
    pub view: View,
    /// Which pattern matched.
    pub pattern: String,
}

/// A compiled, ordered list of file-name patterns.
#[derive(Debug, Clone)]
pub struct NamePatterns {
    patterns: Vec<(String, Regex)>,
    earliest: NaiveDate,
}

impl NamePatterns {
    /// Compiles custom patterns (first) and presets (after), checking that each
    /// has the required named groups.
    pub fn from_config(cfg: &NamesConfig) -> anyhow::Result<NamePatterns> {
        let mut patterns = Vec::new();
        for p in &cfg.patterns {
            let re = Regex::new(&p.regex).with_context(|| format!("names.patterns '{}'", p.name))?;
            let groups: Vec<&str> = re.capture_names().flatten().collect();
            for g in ["plant", "date", "time"] {
                if !groups.contains(&g) {
                    bail!(
                        "names.patterns '{}': regex has no named group (?P<{g}>...)",
                        p.name
                    );
                }
            }
            patterns.push((p.name.clone(), re));
        }
        for name in &cfg.presets {
            let Some(src) = preset_regex(name) else {
                bail!(
                    "names.presets: unknown preset '{name}' (known: {})",
                    PRESET_NAMES.join(", ")
                );
            };
            patterns.push((name.clone(), Regex::new(&src).expect("preset regexes compile")));
        }
        if patterns.is_empty() {
            bail!("names: no presets and no patterns: no file could ever match");
        }
        Ok(NamePatterns {
            patterns,
            earliest: cfg.earliest,
        })
    }

    /// Refuses a capture time outside the plausible window: before
    /// `[names] earliest` or more than [`MAX_AHEAD_HOURS`] after `now` (the
    /// facility's local time). One image dated 2091 would otherwise give its
    /// plant a phyllochron of years and leaves that "emerge" decades ahead.
    pub fn check_time(&self, rel: &Path, taken_at: NaiveDateTime, now: NaiveDateTime) -> anyhow::Result<()> {
        let shown = printable(&rel.to_string_lossy());
        if taken_at.date() < self.earliest {
            bail!(
                "file {shown}: capture time {taken_at} is before {} ([names] earliest): a wrong station clock or name?",
                self.earliest
            );
        }
        let latest = now + chrono::Duration::hours(MAX_AHEAD_HOURS);
        if taken_at > latest {
            bail!(
                "file {shown}: capture time {taken_at} is more than {MAX_AHEAD_HOURS} h ahead of this computer's clock ({}): a wrong station clock or name?",
                now.format("%Y-%m-%d %H:%M")
            );
        }
        Ok(())
    }

    /// Names of the patterns, in the order tried.
    pub fn names(&self) -> Vec<&str> {
        self.patterns.iter().map(|(n, _)| n.as_str()).collect()
    }

    /// Parses a path relative to the drop directory. The error names the file
    /// and every pattern tried.
    pub fn parse(&self, rel: &Path) -> anyhow::Result<ParsedName> {
        // No `\` → `/` mapping: a backslash here is rel_path's escape (the
        // drop directory's paths are joined with `/` already).
        let s = rel.to_string_lossy();
        // Control characters (a newline in a file name) would forge lines in the
        // log, `tail` and the CSV exports: shown escaped, and refused in plant ids.
        let shown = printable(&s);
        for (name, re) in &self.patterns {
            let Some(c) = re.captures(&s) else { continue };
            let get = |g: &str| c.name(g).map(|m| m.as_str());
            let plant = get("plant").unwrap_or_default().to_string();
            let taken_at = parse_datetime(get("date").unwrap_or_default(), get("time").unwrap_or_default())
                .with_context(|| {
                format!("file {shown}: pattern '{name}' matched but the date/time is invalid")
            })?;
            if plant.is_empty() {
                bail!("file {shown}: pattern '{name}' matched an empty plant id");
            }
            // Control characters and bytes that are not UTF-8 arrive escaped
            // (`\xNN`, [`crate::domain::rel_path`]); raw ones from elsewhere.
            if plant.chars().any(char::is_control) || plant.contains("\\x") {
                bail!("file {shown}: pattern '{name}' matched a plant id with control characters");
            }
            let angle = match get("angle").filter(|a| !a.is_empty()) {
                None => None,
                Some(a) => match a.parse::<u16>() {
                    Ok(deg) if deg < 360 => Some(deg),
                    // Read as 0 it would merge into another view's counts unseen.
                    _ => bail!(
                        "file {shown}: pattern '{name}' matched angle '{a}', not an angle in degrees (0-359)"
                    ),
                },
            };
            let view = match get("kind").map(|k| k.to_ascii_lowercase()) {
                Some(k) if k == "tv" || k == "top" => View::Top(angle.unwrap_or(90)),
                _ => View::Side(angle.unwrap_or(0)),
            };
            return Ok(ParsedName {
                plant,
                taken_at,
                view,
                pattern: name.clone(),
            });
        }
        // An example of each layout says more to a person than its regex; a
        // site's own pattern has no example, so its regex is shown.
        let tried: Vec<String> = self
            .patterns
            .iter()
            .map(|(n, re)| match preset_example(n) {
                Some(e) => format!("{n} (e.g. {e})"),
                None => format!("{n} = /{}/", re.as_str()),
            })
            .collect();
        bail!(
            "file name {shown} matches none of the patterns tried: {}",
            tried.join("; ")
        )
    }
}

/// `s` with control characters escaped (`\n`, `\u{1b}`), for messages: a
/// file name must not be able to forge log lines.
pub fn printable(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_debug().collect()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// Parses `YYYY-MM-DD` plus `HH-MM-SS[.fff]` (also `HH:MM:SS`, `HHMMSS`).
fn parse_datetime(date: &str, time: &str) -> anyhow::Result<NaiveDateTime> {
    let d = NaiveDate::parse_from_str(date, "%Y-%m-%d").with_context(|| format!("date '{date}'"))?;
    let (hms, frac) = time.split_once('.').unwrap_or((time, ""));
    let digits: String = hms.chars().filter(|c| c.is_ascii_digit()).collect();
    let norm = if frac.is_empty() {
        digits
    } else {
        format!("{digits}.{frac}")
    };
    let t = NaiveTime::parse_from_str(&norm, "%H%M%S%.f").with_context(|| format!("time '{time}'"))?;
    Ok(d.and_time(t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn defaults() -> NamePatterns {
        NamePatterns::from_config(&NamesConfig::default()).unwrap()
    }

    fn dt(s: &str) -> NaiveDateTime {
        NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M:%S%.f").unwrap()
    }

    #[test]
    fn flat_layout_real_names() {
        let p = defaults();
        let n = p
            .parse(Path::new(
                "402-127-N55-WW-1_2019-05-10_09-18-07.937_Vis_SV_108.jpg",
            ))
            .unwrap();
        assert_eq!(n.plant, "402-127-N55-WW-1");
        assert_eq!(n.taken_at, dt("2019-05-10T09:18:07.937"));
        assert_eq!(n.view, View::Side(108));
        assert_eq!(n.pattern, "flat");
        let n = p
            .parse(Path::new("sub/dir/P1_2018-04-02_10-00-00_Vis_TV_90.png"))
            .unwrap();
        assert_eq!((n.plant.as_str(), n.view), ("P1", View::Top(90)));
        let n = p
            .parse(Path::new(
                "402-100-N28-WW-1_2019-05-05_09-06-07.388_Vis_SV_252.Crp.jpg",
            ))
            .unwrap();
        assert_eq!(n.view, View::Side(252));
    }

    #[test]
    fn snapshot_layouts() {
        let p = defaults();
        let n = p
            .parse(Path::new(
                "2018-04-01_Sorghum_P042_2018-04-20_10-32-16_5512/Vis_SV_144/0_0_0.png",
            ))
            .unwrap();
        assert_eq!(
            (n.plant.as_str(), n.view.clone(), n.pattern.as_str()),
            ("P042", View::Side(144), "snapshot-dir")
        );
        assert_eq!(n.taken_at, dt("2018-04-20T10:32:16"));
        let n = p
            .parse(Path::new(
                "2018-04-01_Sorghum_P042_2018-04-20_10-32-16_5512/0_72_0.png",
            ))
            .unwrap();
        assert_eq!(
            (n.view.clone(), n.pattern.as_str()),
            (View::Side(72), "snapshot-file")
        );
        let n = p
            .parse(Path::new(
                "x/2018-04-01_Sorghum_P042_2018-04-20_10-32-16_5512/top_0_90_0.png",
            ))
            .unwrap();
        assert_eq!((n.plant.as_str(), n.view), ("P042", View::Top(90)));
    }

    #[test]
    fn unmatched_name_names_file_and_patterns() {
        let err = defaults()
            .parse(Path::new("holiday/beach.png"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("holiday/beach.png"), "{err}");
        for preset in PRESET_NAMES {
            assert!(err.contains(preset), "{err}");
            // The example shown is one the layout reads, not a regex.
            let example = preset_example(preset).unwrap();
            assert!(err.contains(example) && !err.contains("(?P<"), "{err}");
            assert_eq!(defaults().parse(Path::new(example)).unwrap().pattern, preset);
        }
        assert!(err.len() < 300, "{} characters: {err}", err.len());
    }

    #[test]
    fn invalid_date_is_an_error() {
        let err = defaults()
            .parse(Path::new("P1_2018-13-40_10-00-00_Vis_SV_0.png"))
            .unwrap_err();
        assert!(format!("{err:#}").contains("2018-13-40"), "{err:#}");
    }

    #[test]
    fn capture_times_outside_the_plausible_window_are_refused() {
        let p = defaults();
        let now = dt("2026-12-06T10:00:00");
        for (file, says) in [
            (
                "P1_2091-05-09_10-00-00_Vis_SV_0.png",
                "ahead of this computer's clock",
            ),
            ("P1_1970-01-01_00-00-00_Vis_SV_0.png", "before 2010-01-01"),
            (
                "P1_2026-12-07_12-00-00_Vis_SV_0.png",
                "ahead of this computer's clock",
            ),
        ] {
            let n = p.parse(Path::new(file)).unwrap();
            let err = format!(
                "{:#}",
                p.check_time(Path::new(file), n.taken_at, now).unwrap_err()
            );
            assert!(err.contains(file) && err.contains(says), "{err}");
        }
        for file in [
            "P1_2010-01-01_00-00-00_Vis_SV_0.png",
            "P1_2026-12-07_09-00-00_Vis_SV_0.png",
        ] {
            let n = p.parse(Path::new(file)).unwrap();
            p.check_time(Path::new(file), n.taken_at, now).unwrap();
        }
    }

    #[test]
    fn an_angle_out_of_range_is_an_error() {
        for angle in ["99999999999999999999", "360"] {
            let file = format!("P1_2018-04-02_10-00-00_Vis_SV_{angle}.png");
            let err = format!("{:#}", defaults().parse(Path::new(&file)).unwrap_err());
            assert!(
                err.contains(&file) && err.contains(&format!("angle '{angle}'")),
                "{err}"
            );
        }
        let ok = defaults()
            .parse(Path::new("P1_2018-04-02_10-00-00_Vis_SV_324.png"))
            .unwrap();
        assert_eq!(ok.view, View::Side(324));
    }

    #[test]
    fn custom_patterns_come_first() {
        let cfg = NamesConfig {
            presets: vec!["flat".into()],
            patterns: vec![PatternConfig {
                name: "site-b".into(),
                regex: r"^(?P<plant>\w+)/(?P<date>\d{4}-\d{2}-\d{2})T(?P<time>\d{2}:\d{2}:\d{2})_(?P<kind>top|side)(?P<angle>\d*)\.png$".into(),
            }],
            ..NamesConfig::default()
        };
        let p = NamePatterns::from_config(&cfg).unwrap();
        assert_eq!(p.names(), vec!["site-b", "flat"]);
        let n = p.parse(Path::new("B7/2020-01-02T03:04:05_side36.png")).unwrap();
        assert_eq!(
            (n.plant.as_str(), n.view, n.taken_at),
            ("B7", View::Side(36), dt("2020-01-02T03:04:05"))
        );
        let n = p.parse(Path::new("B7/2020-01-02T03:04:05_top.png")).unwrap();
        assert_eq!(n.view, View::Top(90));
    }

    #[test]
    fn view_round_trip() {
        for s in ["SV_0", "SV_108", "TV_90", "human"] {
            assert_eq!(View::parse(s).to_string(), s);
        }
        assert_eq!(View::parse("Vis_SV_36"), View::Side(36));
        assert_eq!(View::parse("top"), View::Top(90));
        assert_eq!(View::parse("side_72"), View::Side(72));
    }

    #[test]
    fn control_characters_refused_in_plant_ids_and_escaped_in_messages() {
        let p = defaults();
        let e = p
            .parse(Path::new("EVIL\nline_2018-04-02_10-00-00_Vis_SV_0.png"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("control characters") && e.contains("EVIL\\nline"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
        // As the drop directory's paths arrive (crate::domain::rel_path): escaped.
        let e = p
            .parse(Path::new("EVIL\\x0aline_2018-04-02_10-00-00_Vis_SV_0.png"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("control characters") && e.contains("EVIL\\x0aline"),
            "{e}"
        );
        let e = p.parse(Path::new("x\u{1b}[2J.png")).unwrap_err().to_string();
        assert!(!e.contains('\u{1b}') && e.contains("\\u{1b}"), "{e}");
        // Quotes and spaces are data, not control characters.
        assert_eq!(
            p.parse(Path::new(
                "x'); DROP TABLE images;--_2018-04-02_10-00-00_Vis_SV_0.png"
            ))
            .unwrap()
            .plant,
            "x'); DROP TABLE images;--"
        );
    }
}
