//! The `phyllo` binary.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = phyllo::cli::Cli::parse();
    // The daemon logs what it counts at info level (into the journal under systemd);
    // the one-shot commands stay quiet unless asked.
    let verbose = match cli.command {
        phyllo::cli::Command::Serve(_) => cli.verbose.max(1),
        _ => cli.verbose,
    };
    phyllo::cli::init_logging(verbose);
    match phyllo::cli::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("phyllo: {err:#}");
            std::process::ExitCode::from(2)
        }
    }
}
