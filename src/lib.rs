//! Terrafuse: a planetary terrain workstation on the Ellipsoidal Cube Map (Lambers & Kolb 2012).
//!
//! From the maths to the front ends: [`geodesy`] (ellipsoids, boxes, f64) → [`ecm`] (cube faces,
//! QSC, quads, static geometry) → [`store`] (tile stores) and [`layers`] (the layer stack's CPU
//! reference, with [`edit`] and [`erosion`]) → [`scene`] (what is drawn, loaded and selected, on
//! the CPU) → [`gpu`] (the renderer and its kernels) →
//! [`compare`], [`project`], [`replay`], [`export`] → the workstation ([`gui`]) and the command line
//! ([`cli`]); [`attributes`] (terrain attributes of a height raster) sits beside [`geodesy`]. `ARCHITECTURE.md` draws the module graph and the path data take through it.

#![warn(missing_docs)]

pub mod attributes;
pub mod bench;
pub mod cli;
pub mod colour;
pub mod compare;
pub mod ecm;
pub mod edit;
pub mod erosion;
pub mod errors;
pub mod export;
pub mod files;
pub mod geodesy;
pub mod gpu;
pub mod gui;
pub mod layers;
pub mod maths;
pub mod plan;
pub mod progress;
pub mod project;
pub mod replay;
pub mod scene;
pub mod slurm;
pub mod store;

pub use errors::Invalid;
