//! A layer (or a stack) composed at one level, quads composed with the CPU reference when first
//! reached, sampled bilinearly at any point: what co-registration and profiles read.

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use super::CompareError;
use crate::ecm::QuadId;
use crate::scene::Scene;
use crate::scene::shifted::locate;
use crate::store::grid::bilinear;

/// A scene composed at one level, quads composed when first reached.
pub(crate) struct Mosaic {
    scene: Scene,
    level: u8,
    grids: HashMap<QuadId, Vec<f32>>,
}

impl Mosaic {
    /// An empty mosaic of a scene at a level.
    pub(crate) fn new(scene: Scene, level: u8) -> Mosaic {
        Mosaic { scene, level, grids: HashMap::new() }
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

    /// A's value at a point, bilinear (NaN outside its data or its composed quads).
    pub(crate) fn value(&self, p: DVec3) -> f64 {
        let Some((q, u, v)) = locate(&self.scene.ellipsoid, self.level, p) else { return f64::NAN };
        self.value_at(q, u, v)
    }

    /// A's value at grid position (u, v) ∈ [0, 256]² of a quad, bilinear (NaN where it has none).
    pub(crate) fn value_at(&self, quad: QuadId, u: f64, v: f64) -> f64 {
        self.grids.get(&quad).map_or(f64::NAN, |g| bilinear(g, u, v))
    }
}
