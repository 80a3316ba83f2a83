//! The rules a configuration's text describes, compiled once at load.
//!
//! Name patterns, zones, the fusion rule and the group pattern are regular
//! expressions and small languages: compiling them at load makes a bad rule
//! an error before anything starts, and holding the compiled form in the
//! [`super::Config`] means no caller compiles them again.

use crate::domain::groups::GroupRule;
use crate::domain::names::NamePatterns;
use crate::domain::timeline::TimelineParams;

/// The compiled `[names]`, `[timeline]` (fusion and zones) and `[groups]`.
#[derive(Debug, Clone)]
pub struct Rules {
    /// `[names]`: file name → plant, capture time and view.
    pub names: NamePatterns,
    /// `[timeline]` with its fusion rule and `[[timeline.zones]]`.
    pub timeline: TimelineParams,
    /// `[groups]`; `None` when no pattern is set.
    pub groups: Option<GroupRule>,
}

impl Rules {
    /// Compiles the sections of `cfg`, naming the section of a bad rule.
    pub fn compile(cfg: &super::Config) -> anyhow::Result<Rules> {
        Ok(Rules {
            timeline: TimelineParams::from_config(&cfg.timeline)?,
            names: NamePatterns::from_config(&cfg.names)?,
            groups: GroupRule::from_config(&cfg.groups)?,
        })
    }

    /// The defaults' rules: what a config holds between being read and being
    /// compiled.
    pub(super) fn defaults() -> Rules {
        Rules {
            timeline: TimelineParams::default(),
            names: NamePatterns::from_config(&Default::default()).expect("the default names compile"),
            groups: None,
        }
    }
}
