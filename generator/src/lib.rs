//! `phyllo-gen`: procedural sorghum plants in a virtual LemnaTec chamber,
//! path traced into image + exact panoptic label pairs for training phyllo's
//! leaf-counting model.
//!
//! The layout follows the pipeline: [`plant`] grows a plant and meshes it,
//! [`render`] places it in the [`render::chamber`] and traces it into an RGB
//! [`render::film`] plus a [`label`] image, and [`dataset`], [`sequence`] and
//! [`bench`](mod@bench) drive whole runs from the [`cli`]. [`tips`] finds each visible
//! leaf's apparent tip for the dataset manifest.

pub mod bench;
pub mod cli;
pub mod climate;
pub mod coco;
pub mod dataset;
pub mod date;
pub mod label;
pub mod mesh;
pub mod plant;
pub mod png_io;
pub mod render;
pub mod rng;
pub mod sampling;
pub mod sequence;
pub mod tips;
