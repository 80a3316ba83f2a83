//! The service's pipeline, one stage per module, data flowing one way
//! (sources → transforms → sinks, as in Vector; the service's shape follows
//! tokio's mini-redis):
//!
//! ```text
//! source::watch / source::scan ─► source::intake (stability, dedupe) ─► bounded queue
//!   ─► worker (hash, names, counting off the async runtime) ─► store (one transaction per image)
//! ```
//!
//! [`service`] wires the stages for `phyllo serve`; the boundary with the
//! model is [`crate::counting`], shared with `phyllo recount`; [`systemd`]
//! talks to the service manager.
//! See `docs/ARCHITECTURE.md`.

pub mod health;
pub mod job;
pub mod memory;
pub mod service;
pub mod source;
pub mod supervise;
pub mod systemd;
pub mod worker;
