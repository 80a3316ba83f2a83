//! phyllo: the leaf-counting daemon and its operator commands.
//!
//! Data flows one way, each stage in its own module (sources → transforms →
//! sinks, as in Vector; the service shape follows tokio's mini-redis):
//!
//! ```text
//! source::watch / source::scan ─► source::intake (stability, dedupe) ─► bounded queue
//!   ─► worker (hash, names, counter off the async runtime) ─► store (one transaction per image)
//!   ─► timeline (view fusion, isotonic fit, events; leaf_site: where each new leaf is)
//!   ─► sinks: tail, export, plot, site_overlay, status, backup
//!   (groups: plants → genotype / treatment summaries; review: the days to check; for export)
//! ```
//!
//! [`config`] is the TOML file; [`service`] wires the stages for `phyllo serve`.
//! The inference core (image → leaf count) is the `phyllo-inference` crate,
//! re-exported as [`inference`].

pub use phyllo_inference as inference;

pub mod cli;
pub mod config;
pub mod counting;
pub mod disk;
pub mod domain;
pub mod evaluation;
pub mod import_journal;
pub mod recount;
pub mod service;
pub mod sinks;
pub mod source;
pub mod store;
pub mod systemd;
pub mod worker;
