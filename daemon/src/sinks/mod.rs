//! Sinks: what leaves the database for people and other programs, each file
//! renamed into place whole ([`crate::files::atomic`]).
//!
//! [`export`] writes CSV atomically, [`plot`] draws a plant's timeline,
//! [`tail`] follows the feed from another process, [`group_report`] writes the per-group
//! summaries, [`review_sheet`] the days to check as a sheet to fill in and
//! import, and [`index_html`] the page that links the nightly export.

pub mod export;
pub mod group_report;
pub mod index_html;
pub mod nightly;
pub mod plot;
pub mod review_sheet;
pub mod site_overlay;
pub mod tail;
