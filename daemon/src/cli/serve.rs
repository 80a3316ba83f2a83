//! `phyllo serve --config FILE`.

use std::process::ExitCode;
use std::sync::Arc;

use anyhow::Context;
use tokio::sync::watch;

use super::ConfigArg;
use crate::config::Config;
use crate::counting::LeafCounter;

/// Arguments of `phyllo serve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
}

/// Builds the model's counter from the config.
pub fn make_counter(cfg: &Config) -> anyhow::Result<Arc<dyn LeafCounter>> {
    crate::counting::onnx_counter(&cfg.inference)
}

/// Exit status after SIGHUP (`EX_TEMPFAIL`): the service stopped cleanly and
/// asks to be started again, reading its config anew. systemd's
/// `Restart=on-failure` restarts any non-zero exit; exit 0 would leave it down.
pub const EXIT_HANGUP: u8 = 75;

/// The signal that stops the service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stop {
    /// SIGTERM or SIGINT: stop for good.
    Terminate,
    /// SIGHUP (a reload, a closed terminal): stop, to be started again.
    Hangup,
}

/// Runs the service until SIGTERM or SIGINT (exit 0), or SIGHUP (a clean
/// stop too, exit [`EXIT_HANGUP`]).
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let config = args.config.load()?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("phyllo-rt")
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    rt.block_on(async move {
        // Loading the model can take a while: keep it off the runtime's workers.
        let cfg = config.clone();
        let counter = tokio::task::spawn_blocking(move || make_counter(&cfg)).await??;
        let (tx, rx) = watch::channel(false);
        let stop = tokio::spawn(async move {
            let stop = wait_for_signal().await;
            match stop {
                Stop::Terminate => tracing::info!("signal received, shutting down"),
                Stop::Hangup => tracing::info!(
                    "SIGHUP received: stopping cleanly; exit {EXIT_HANGUP} so that systemd starts phyllo again with its config read anew"
                ),
            }
            let _ = tx.send(true);
            stop
        });
        crate::pipeline::service::run(config, counter, rx).await?;
        let hung_up = stop.is_finished() && matches!(stop.await, Ok(Stop::Hangup));
        Ok(if hung_up {
            ExitCode::from(EXIT_HANGUP)
        } else {
            ExitCode::SUCCESS
        })
    })
}

/// Waits for SIGTERM, SIGINT or SIGHUP. The default action of SIGHUP ends
/// the process on the spot, in the middle of a count, with a status systemd
/// takes for a clean stop; handled, it stops the service as SIGTERM does.
async fn wait_for_signal() -> Stop {
    use tokio::signal::unix::{signal, SignalKind};
    let mut hangup = match signal(SignalKind::hangup()) {
        Ok(s) => Some(s),
        Err(e) => {
            tracing::warn!("cannot listen for SIGHUP ({e})");
            None
        }
    };
    let hup = async {
        match hangup.as_mut() {
            Some(s) => s.recv().await,
            None => std::future::pending().await,
        }
    };
    match signal(SignalKind::terminate()) {
        Ok(mut term) => {
            tokio::select! {
                _ = term.recv() => Stop::Terminate,
                _ = tokio::signal::ctrl_c() => Stop::Terminate,
                _ = hup => Stop::Hangup,
            }
        }
        Err(e) => {
            tracing::warn!("cannot listen for SIGTERM ({e}); only Ctrl-C and SIGHUP stop the service");
            tokio::select! {
                _ = tokio::signal::ctrl_c() => Stop::Terminate,
                _ = hup => Stop::Hangup,
            }
        }
    }
}
