//! `phyllo serve --config FILE`.

use std::sync::Arc;

use anyhow::Context;
use tokio::sync::watch;

use super::ConfigArg;
use crate::config::Config;
use crate::pipeline::counting::LeafCounter;

/// Arguments of `phyllo serve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: ConfigArg,
}

/// Builds the model's counter from the config.
pub fn make_counter(cfg: &Config) -> anyhow::Result<Arc<dyn LeafCounter>> {
    crate::pipeline::counting::onnx_counter(&cfg.inference)
}

/// Runs the service until SIGTERM or SIGINT.
pub fn run(args: Args) -> anyhow::Result<()> {
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
        tokio::spawn(async move {
            wait_for_signal().await;
            tracing::info!("signal received, shutting down");
            let _ = tx.send(true);
        });
        crate::pipeline::service::run(config, counter, rx).await
    })
}

async fn wait_for_signal() {
    use tokio::signal::unix::{signal, SignalKind};
    match signal(SignalKind::terminate()) {
        Ok(mut term) => {
            tokio::select! {
                _ = term.recv() => {}
                _ = tokio::signal::ctrl_c() => {}
            }
        }
        Err(e) => {
            tracing::warn!("cannot listen for SIGTERM ({e}); only Ctrl-C stops the service");
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}
