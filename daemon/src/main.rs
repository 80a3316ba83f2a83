//! The `phyllo` binary: parses the command line and runs it.

use std::process::ExitCode;

use clap::Parser;
use tracing_subscriber::EnvFilter;

fn main() -> ExitCode {
    // Logs go to stderr; under systemd they land in the journal, which adds timestamps.
    let under_systemd = std::env::var_os("JOURNAL_STREAM").is_some();
    let builder = tracing_subscriber::fmt()
        .with_env_filter(EnvFilter::try_from_env("PHYLLO_LOG").unwrap_or_else(|_| EnvFilter::new("info")))
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(false);
    if under_systemd {
        builder.without_time().init();
    } else {
        builder.init();
    }
    let cli = phyllo::cli::Cli::parse();
    if !matches!(cli.command, phyllo::cli::Command::Serve(_)) {
        // A command piped into `head` should end quietly when the reader
        // leaves, as cat and grep do, rather than panic in println! or report
        // "Broken pipe". The service keeps Rust's default (SIGPIPE ignored):
        // a closed socket must never kill it.
        // SAFETY: resetting one signal's disposition before any thread starts.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    match phyllo::cli::run(cli) {
        Ok(code) => code,
        Err(e) => {
            // Exit 2: the command could not run at all (bad config, missing
            // model or runtime); exit 1 is kept for "ran, but some inputs failed".
            eprintln!("phyllo: error: {e:#}");
            ExitCode::from(2)
        }
    }
}
