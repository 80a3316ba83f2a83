//! `phyllo eval`: how well the model counts, on synthetic datasets with exact
//! labels and on real images with human counts, through the same inference
//! path as the daemon.

pub mod fingerprint;
pub mod intervals;
pub mod leaf_errors;
pub mod metrics;
pub mod plots;
pub mod segment_table;
pub mod segmentation;
pub mod sources;
pub mod tip_errors;
pub mod tip_overlay;
