//! The `phyllo` binary.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = phyllo::cli::Cli::parse();
    phyllo::cli::init_logging(cli.verbose);
    match phyllo::cli::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("phyllo: {err:#}");
            std::process::ExitCode::from(2)
        }
    }
}
