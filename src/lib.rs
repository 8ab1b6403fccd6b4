//! Terrafuse: a planetary terrain workstation on the Ellipsoidal Cube Map (Lambers & Kolb 2012).
//!
//! Layers point one way: [`geodesy`] (ellipsoids, f64) → [`ecm`] (cube faces, QSC, quads) →
//! the command line ([`cli`]). See `ARCHITECTURE.md` for the path data take through them.

#![warn(missing_docs)]

pub mod cli;
pub mod colour;
pub mod compare;
pub mod ecm;
pub mod edit;
pub mod erosion;
pub mod files;
pub mod geodesy;
pub mod gpu;
pub mod gui;
pub mod layers;
pub mod project;
pub mod replay;
pub mod slurm;
pub mod store;
