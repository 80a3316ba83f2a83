//! Arguments shared by every command that runs the model.

use std::path::PathBuf;

use anyhow::{bail, Context};
use phyllo_inference::region::RegionMode;
use phyllo_inference::CounterConfig;

/// Model and runtime options.
#[derive(Debug, Clone, clap::Args)]
pub struct CounterArgs {
    /// ONNX model (default: $PHYLLO_MODEL, then the model shipped with phyllo).
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// ONNX Runtime shared library (default: $PHYLLO_ORT_LIB, then a search).
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// ONNX Runtime intra-op threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Plant region: `auto` (by colour), `full`, or a fixed box `x0,y0,x1,y1` in image pixels.
    #[arg(long, default_value = "auto")]
    pub region: String,
}

impl CounterArgs {
    /// The counter configuration these arguments describe.
    pub fn config(&self) -> anyhow::Result<CounterConfig> {
        Ok(CounterConfig {
            model: self.model.clone(),
            ort_lib: self.ort_lib.clone(),
            intra_threads: self.threads,
            region: parse_region(&self.region)?,
            ..CounterConfig::default()
        })
    }
}

/// Parses `auto`, `full` or `x0,y0,x1,y1`.
pub fn parse_region(s: &str) -> anyhow::Result<RegionMode> {
    match s {
        "auto" => Ok(RegionMode::Auto),
        "full" => Ok(RegionMode::Full),
        _ => {
            let v: Vec<u32> = s
                .split(',')
                .map(|p| p.trim().parse::<u32>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--region {s:?}: expected auto, full or x0,y0,x1,y1"))?;
            if v.len() != 4 || v[2] <= v[0] || v[3] <= v[1] {
                bail!("--region {s:?}: expected x0,y0,x1,y1 with x1 > x0 and y1 > y0");
            }
            Ok(RegionMode::Fixed {
                x0: v[0],
                y0: v[1],
                x1: v[2],
                y1: v[3],
            })
        }
    }
}
