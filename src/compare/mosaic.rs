//! A layer (or a stack) composed at one level, quads composed with the CPU reference when first
//! reached, sampled at any point: what co-registration, profiles and the uncertainty read.

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use super::CompareError;
use crate::ecm::QuadId;
use crate::ecm::grid::{bicubic, bilinear};
use crate::scene::Scene;
use crate::scene::shifted::locate;

/// How a mosaic is read between its samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Interpolation {
    /// From the 2 × 2 samples around the point (as `gdallocationinfo -r bilinear`): what a
    /// profile draws.
    Bilinear,
    /// Cubic Lagrange through the 4 × 4 samples around it. Co-registration reads A moved by
    /// fractions of a sample: bilinear interpolation flattens the terrain's curvature there but
    /// not at the samples, a bias that depends on the shift's fraction and pulls Nuth & Kääb
    /// towards whole samples. Cubic reads it to the fourth power of the spacing (the known-shift
    /// error at the data's level 0.080 m against 0.38 m bilinear; docs/comparison.md).
    Bicubic,
}

/// A scene composed at one level, quads composed when first reached.
pub(crate) struct Mosaic {
    scene: Scene,
    level: u8,
    interpolation: Interpolation,
    grids: HashMap<QuadId, Vec<f32>>,
}

impl Mosaic {
    /// An empty mosaic of a scene at a level, read with `interpolation`.
    pub(crate) fn new(scene: Scene, level: u8, interpolation: Interpolation) -> Mosaic {
        Mosaic { scene, level, interpolation, grids: HashMap::new() }
    }

    /// The body.
    pub(crate) fn ellipsoid(&self) -> crate::geodesy::Ellipsoid {
        self.scene.ellipsoid
    }

    /// The level it is composed at.
    pub(crate) fn level(&self) -> u8 {
        self.level
    }

    /// Composes the quads the points fall in that are not composed yet.
    pub(crate) fn prefetch(&mut self, points: &[DVec3]) -> Result<(), CompareError> {
        let e = self.scene.ellipsoid;
        let level = self.level;
        let mut wanted: Vec<QuadId> = points
            .par_iter()
            .filter_map(|p| locate(&e, level, *p).map(|l| l.0))
            .collect::<std::collections::HashSet<_>>()
            .into_iter()
            .collect();
        wanted.sort();
        self.prefetch_quads(&wanted)
    }

    /// Composes those of `quads` (of the mosaic's level) not composed yet, in order.
    pub(crate) fn prefetch_quads(&mut self, quads: &[QuadId]) -> Result<(), CompareError> {
        let wanted: Vec<QuadId> = quads.iter().copied().filter(|q| !self.grids.contains_key(q)).collect();
        for chunk in wanted.chunks(16) {
            self.grids.extend(self.scene.compose_cpu(chunk)?);
        }
        Ok(())
    }

    /// A's value at a point (NaN outside its data or its composed quads).
    pub(crate) fn value(&self, p: DVec3) -> f64 {
        let Some((q, u, v)) = locate(&self.scene.ellipsoid, self.level, p) else { return f64::NAN };
        self.value_at(q, u, v)
    }

    /// A's value at grid position (u, v) ∈ [0, 256]² of a quad (NaN where it has none).
    pub(crate) fn value_at(&self, quad: QuadId, u: f64, v: f64) -> f64 {
        self.grid(quad).map_or(f64::NAN, |grid| self.read(grid, u, v))
    }

    /// A composed quad's grid (None where it is not composed).
    pub(crate) fn grid(&self, quad: QuadId) -> Option<&[f32]> {
        self.grids.get(&quad).map(Vec::as_slice)
    }

    /// A grid of this mosaic read at (u, v) ∈ [0, 256]² by its interpolation.
    pub(crate) fn read(&self, grid: &[f32], u: f64, v: f64) -> f64 {
        match self.interpolation {
            Interpolation::Bilinear => bilinear(grid, u, v),
            Interpolation::Bicubic => bicubic(grid, u, v),
        }
    }
}
