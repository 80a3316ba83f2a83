//! `phyllo-gen`: synthetic training data for phyllo.

fn main() {
    eprintln!("phyllo-gen: not built yet");
    std::process::exit(2);
}
