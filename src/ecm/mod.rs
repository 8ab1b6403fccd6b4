//! The Ellipsoidal Cube Map: cube faces, the QSC projection (and gnomonic variants for
//! comparison), quadtree quad ids, and the distortion analysis that justifies QSC.
//!
//! A geodetic surface point goes to the cube in two exact steps: the geocentric shift to the
//! unit sphere ([`crate::geodesy::sphere_direction_from_geodetic`]) and a projection of that
//! direction onto the face it falls on ([`CubeProjection`]). Face coordinates x, y lie in
//! [−1, 1]; for QSC they are PROJ's `+proj=qsc` metres divided by the semi-major axis.

pub mod accuracy;
pub mod area_mean;
pub mod distortion;
mod face;
pub mod geometry;
pub mod grid;
pub mod points;
mod projection;
mod quad;

pub use face::{Edge, Face};
pub use projection::{CubeProjection, FacePoint};
pub use quad::{FaceRect, MAX_LEVEL, Neighbour, QuadId, fold_onto_face};

/// Errors of the cube-map module.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EcmError {
    /// A face name or number that is not one of the six.
    #[error("unknown face '{0}': use front, right, back, left, top, bottom or 0–5")]
    UnknownFace(String),
    /// A projection name that is not known.
    #[error("unknown cube projection '{0}': use qsc, gnomonic or adjusted-gnomonic")]
    UnknownProjection(String),
    /// Face coordinates outside [−1, 1] (or not finite).
    #[error("face coordinates ({x}, {y}) are outside the face: x and y must lie in [-1, 1]")]
    OutsideFace {
        /// The x that was given.
        x: f64,
        /// The y that was given.
        y: f64,
    },
    /// A quad id outside the quadtree.
    #[error("no quad at level {level}, x {x}, y {y}: levels go to 30 and x, y below 2^level")]
    InvalidQuad {
        /// Level that was asked for.
        level: u8,
        /// Column that was asked for.
        x: u32,
        /// Row that was asked for.
        y: u32,
    },
}
