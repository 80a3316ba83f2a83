//! Plant science on plain data: no SQL, no I/O, no configuration file.
//!
//! Every module here takes plain values (counts, times, plant ids, rules
//! already compiled) and returns plain values; the store ([`crate::store`])
//! feeds it stored rows through one door (`store::derive`) and keeps what it
//! returns. See `docs/ARCHITECTURE.md` for the layer rules.

pub mod climate_zone;
pub mod forecast;
pub mod group_compare;
pub mod groups;
pub mod image_facts;
pub mod leaf_site;
pub mod least_squares;
pub mod names;
pub mod plant;
pub mod rel_path;
pub mod review;
pub mod thermal;
pub mod timeline;
