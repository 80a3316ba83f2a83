//! `phyllo bench`: per-stage timings of the inference path on full camera
//! frames, beside a Python pipeline in the same run. The work is
//! [`phyllo_evaluation::bench`]'s; this adds the model options.

use std::process::ExitCode;

use phyllo_evaluation::bench::{self, BenchArgs};
pub use phyllo_evaluation::bench::{make_frames, python_reference};

use super::counter_args::CounterArgs;

/// Arguments of `phyllo bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model and runtime options.
    #[command(flatten)]
    pub counter: CounterArgs,
    /// Frames, passes and the Python reference.
    #[command(flatten)]
    pub bench: BenchArgs,
}

/// Runs the benchmark and prints its table.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    bench::run(&args.bench, || args.counter.config())
}
