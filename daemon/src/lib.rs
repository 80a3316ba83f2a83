//! phyllo: the leaf-counting daemon and its operator commands.
//!
//! Layers, each depending only on those below it (`docs/ARCHITECTURE.md`):
//!
//! ```text
//! cli ─► pipeline (sources ─► intake ─► workers ─► store) · ops (imports, backup, recount) · sinks
//!          └────────────► store (all SQL; derive: the door to the domain) ─► domain (pure plant science)
//! config: serde types of the TOML file, its sections' types declared in domain
//! ```
//!
//! [`pipeline`] wires the stages for `phyllo serve`. The inference core
//! (image → leaf count) is the `phyllo-inference` crate, re-exported as
//! [`inference`].

pub use phyllo_inference as inference;

pub mod cli;
pub mod config;
pub mod counting;
pub mod domain;
pub mod files;
pub mod ops;
pub mod pipeline;
pub mod sinks;
pub mod store;
