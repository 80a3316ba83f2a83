//! The `phyllo` command line: one module per subcommand.

pub mod backup;
pub mod bench;
pub mod count;
pub mod counter_args;
pub mod eval;
pub mod export;
pub mod forecast;
pub mod groups;
pub mod import;
pub mod recount;
pub mod restore;
pub mod review;
pub mod serve;
pub mod status;
pub mod tail;
pub mod timeline;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::config::Config;

/// phyllo: counts sorghum leaves in phenotyping images and keeps per-plant
/// leaf-emergence timelines.
#[derive(Debug, Parser)]
#[command(name = "phyllo", version, about, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the daemon: watch the drop directory, count leaves, keep timelines.
    Serve(serve::Args),
    /// Ingest CSVs made elsewhere: leaf counts, temperature logs, images to move to their plant (a file or a folder).
    Import(import::Args),
    /// Count the stored images again with the configured model and settings (after an upgrade).
    Recount(recount::Args),
    /// Follow new counts and emergence events as they land, until interrupted.
    Tail(tail::Args),
    /// Write CSV (images, sessions, timeline, events, plants; groups when set), atomically.
    Export(export::Args),
    /// Print (and plot) one plant's timeline.
    Timeline(timeline::Args),
    /// When each plant reaches a leaf stage (its next leaf, or leaf N).
    Forecast(forecast::Args),
    /// Summarise the plants per group (genotype, treatment, ... read from plant ids).
    Groups(groups::Args),
    /// List the plant sessions most in doubt, to count by hand and import back.
    Review(review::Args),
    /// Show the service's queue, progress, failures and model.
    Status(status::Args),
    /// Snapshot the database (checked, renamed into place), keeping the newest N.
    Backup(backup::Args),
    /// Put a snapshot in place of the database (the service stopped; old files kept aside).
    Restore(restore::Args),
    /// Count leaves in image files (exit 1 if any input failed).
    Count(count::Args),
    /// Time each inference stage on full camera frames, beside a Python pipeline.
    Bench(bench::Args),
    /// Measure counting accuracy on a phyllo-gen dataset or on real images with human counts.
    Eval(eval::Args),
}

/// `--config FILE`, shared by every subcommand that needs the config.
#[derive(Debug, clap::Args)]
pub struct ConfigArg {
    /// Configuration file (TOML).
    #[arg(long, short = 'c', value_name = "FILE", env = "PHYLLO_CONFIG")]
    pub config: PathBuf,
}

impl ConfigArg {
    /// Loads the configuration.
    pub fn load(&self) -> anyhow::Result<Config> {
        Config::load(&self.config)
    }
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    let ok = |r: anyhow::Result<()>| r.map(|()| ExitCode::SUCCESS);
    match cli.command {
        Command::Serve(a) => serve::run(a),
        Command::Import(a) => ok(import::run(a)),
        Command::Recount(a) => recount::run(a),
        Command::Tail(a) => ok(tail::run(a)),
        Command::Export(a) => ok(export::run(a)),
        Command::Timeline(a) => ok(timeline::run(a)),
        Command::Forecast(a) => ok(forecast::run(a)),
        Command::Groups(a) => ok(groups::run(a)),
        Command::Review(a) => ok(review::run(a)),
        Command::Status(a) => status::run(a),
        Command::Backup(a) => ok(backup::run(a)),
        Command::Restore(a) => ok(restore::run(a)),
        Command::Count(a) => count::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Eval(a) => eval::run(a),
    }
}
