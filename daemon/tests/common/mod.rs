//! The harness shared by the `phyllo` crate's integration tests, one module
//! a concern:
//!
//! - `run`: the binary under test and its processes — [`phyllo`]/[`ok`]
//!   runners, [`wait_for`], [`signal`], a spawned `phyllo tail` reader
//!   ([`spawn_tail`]), a running `phyllo serve` ([`Daemon`]), [`env_or`]
//!   knobs, a small file system ([`mount_tmpfs`]);
//! - `site`: config writers ([`config_text`], [`write_config`]) and a
//!   test's directories with a fast-intake config ([`Site`]);
//! - `db`: reading the database ([`q`], [`qs`], [`rows`], [`timelines`]);
//! - `images`: images and file names to drop ([`image_stream`],
//!   [`small_png`], [`drop_file`], ...);
//! - `fakes`: `LeafCounter`s that stand in for the model ([`TextCounter`],
//!   [`SlowCounter`]).
//!
//! Each test file includes it with `mod common;` (the `cli` test, whose files
//! live in `tests/cli/`, with `#[path]`) and uses what it needs.

#![allow(dead_code)] // each test binary uses a different subset
#![allow(unused_imports)] // likewise for the re-exports below

pub mod db;
pub mod fakes;
pub mod images;
pub mod run;
pub mod site;

pub use db::*;
pub use fakes::*;
pub use images::*;
pub use run::*;
pub use site::*;
