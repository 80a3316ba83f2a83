//! Command-line interface: one module per subcommand.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::config::Config;

pub mod bench;
pub mod count;
pub mod counter_args;
pub mod export;
pub mod import;
pub mod serve;
pub mod status;
pub mod tail;
pub mod timeline;

/// Top-level arguments.
#[derive(Debug, Parser)]
#[command(
    name = "phyllo",
    version,
    about = "Counts sorghum leaves and tracks leaf emergence"
)]
pub struct Cli {
    /// More log output (repeat for more).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Count leaves in image files.
    Count(count::Args),
    /// Time each inference stage on full camera frames, beside a Python pipeline.
    Bench(bench::Args),
    /// Run the daemon: watch the drop directory, count leaves, keep timelines.
    Serve(serve::Args),
    /// Ingest leaf counts made elsewhere (CSV: plant,timestamp,view,leaf_count).
    Import(import::Args),
    /// Follow new counts and emergence events as they land, until interrupted.
    Tail(tail::Args),
    /// Write CSV (images, sessions, timeline or events), atomically.
    Export(export::Args),
    /// Print (and plot) one plant's timeline.
    Timeline(timeline::Args),
    /// Show the service's queue, progress, failures and model.
    Status(status::Args),
}

/// `--config FILE`, shared by the daemon's subcommands.
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

/// Sets up `tracing` to stderr; `RUST_LOG` overrides the level.
pub fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    // No colour codes when stderr is a file or the journal.
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(ansi)
        .try_init();
}

/// Runs the chosen subcommand.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    let done = |r: anyhow::Result<()>| r.map(|()| ExitCode::SUCCESS);
    match cli.command {
        Command::Count(args) => count::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Serve(a) => done(serve::run(a)),
        Command::Import(a) => done(import::run(a)),
        Command::Tail(a) => done(tail::run(a)),
        Command::Export(a) => done(export::run(a)),
        Command::Timeline(a) => done(timeline::run(a)),
        Command::Status(a) => done(status::run(a)),
    }
}
