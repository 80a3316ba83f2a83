//! phyllo-evaluation: how well the model counts, on synthetic datasets with
//! exact labels and on real images with human counts, through the same
//! inference path as the daemon ([`eval`]); and how fast that path runs on
//! full camera frames ([`bench`](mod@bench)).
//!
//! The `phyllo eval` and `phyllo bench` subcommands parse the model options
//! into a [`phyllo_inference::CounterConfig`] and hand the rest to
//! [`eval::run`] and [`bench::run`]; nothing here depends on the service.

#![warn(missing_docs)]

pub mod bench;
pub mod eval;
pub mod fingerprint;
pub mod image_names;
pub mod intervals;
pub mod leaf_errors;
pub mod metrics;
pub mod plots;
pub mod segment_table;
pub mod segmentation;
pub mod sources;
pub mod tip_errors;
pub mod tip_overlay;
