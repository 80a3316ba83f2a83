//! phyllo: the leaf-counting service and its command-line interface.
//!
//! The inference core lives in the `phyllo-inference` crate and is re-exported
//! here as [`inference`]; this crate adds the operator-facing commands.

pub use phyllo_inference as inference;

pub mod cli;
