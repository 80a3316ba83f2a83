//! `phyllo tail --config FILE [--plant P] [--json]`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::ConfigArg;

/// Arguments of `phyllo tail`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
    /// Only this plant.
    #[arg(long)]
    plant: Option<String>,
    /// One JSON object per line instead of text.
    #[arg(long)]
    json: bool,
    /// Replay the whole feed first instead of starting with what lands next.
    #[arg(long)]
    from_start: bool,
}

/// Runs `phyllo tail` until SIGINT/SIGTERM.
pub fn run(args: Args) -> anyhow::Result<()> {
    let config = args.config.load()?;
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [libc_sigint(), libc_sigterm()] {
        // Signal handling without an async runtime: a flag checked between polls.
        signal_hook_flag(sig, stop.clone());
    }
    let mut out = std::io::stdout().lock();
    let result = crate::sinks::tail::follow(
        &config.database,
        args.plant.as_deref(),
        args.json,
        args.from_start,
        &mut out,
        &|| stop.load(Ordering::Relaxed),
    );
    match result {
        // A closed pipe (`phyllo tail | head`) is a normal way to stop.
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        r => r,
    }
}

const fn libc_sigint() -> i32 {
    2
}

const fn libc_sigterm() -> i32 {
    15
}

/// Sets `flag` when `sig` arrives, using a tiny current-thread tokio runtime
/// on a helper thread (tokio is already a dependency; no extra crate).
fn signal_hook_flag(sig: i32, flag: Arc<AtomicBool>) {
    std::thread::spawn(move || {
        let Ok(rt) = tokio::runtime::Builder::new_current_thread().enable_io().build() else {
            return;
        };
        rt.block_on(async {
            let kind = tokio::signal::unix::SignalKind::from_raw(sig);
            if let Ok(mut s) = tokio::signal::unix::signal(kind) {
                s.recv().await;
                flag.store(true, Ordering::Relaxed);
            }
        });
    });
}
