//! `phyllo eval`: count accuracy (and, with labels, segmentation quality) of
//! the model on a phyllo-gen dataset or on real images with human counts.
//! The work is [`phyllo_evaluation::eval`]'s; this adds the model options.

use std::process::ExitCode;

use phyllo_evaluation::eval::{self, EvalArgs};

use super::counter_args::CounterArgs;

/// Arguments of `phyllo eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model and runtime options.
    #[command(flatten)]
    pub counter: CounterArgs,
    /// What to evaluate and how to report it.
    #[command(flatten)]
    pub eval: EvalArgs,
}

/// Runs the evaluation.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    eval::run(&args.eval, || args.counter.config())
}
