//! `phyllo-gen` command-line entry point.

fn main() -> std::process::ExitCode {
    phyllo_gen::cli::main()
}
