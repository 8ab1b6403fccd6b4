//! A co-registration fitted on some of the overlap's quads (at most `FIT_QUADS`, so the samples
//! held stay bounded), replayed over every sample for the whole area's statistics before and
//! after it: 16 quads at a time, each step as the pipeline ran it (A's elevation as the steps
//! before left it, A moved by the shift found after a Nuth & Kääb step, raised by the offset so
//! far, the biases summed), the differences spilled to a scratch file and their statistics made
//! in passes ([`super::streamed`]).

use std::path::Path;

use rayon::prelude::*;

use super::CompareError;
use super::coreg::{RefSample, differences, reference_samples};
use super::mosaic::{Interpolation, Mosaic};
use super::spill::{NO_CLASS, Record, Spill};
use super::stats::{HISTOGRAM_BINS, SLOPE_CLASSES_DEG, Stats, slope_class};
use super::streamed::streamed_stats;
use crate::ecm::QuadId;
use crate::geodesy::GeoBox;
use crate::layers::correction::Frame;
use crate::scene::Scene;

/// What a bias reads at a reference sample: where it is and B's attributes there.
pub(super) struct At {
    /// East metres in the frame of the pipeline's origin.
    pub east_m: f64,
    /// North.
    pub north_m: f64,
    /// A's elevation as the steps before left it, metres (NaN where A has no data).
    pub elevation_m: f64,
    /// B's slope, degrees.
    pub slope_deg: f64,
    /// B's maximal curvature, 100/m.
    pub max_curvature: f64,
}

/// Where a pipeline stood after one of its steps: A's move and raise so far.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Stand {
    /// East and north metres.
    pub shift: (f64, f64),
    /// Metres.
    pub up: f64,
}

/// What the replay reads: both layers alone, the level, every quad, the region and whether B's
/// curvature is needed, the pipeline's frame, and the folder of its scratch files.
pub(super) struct WholeArea<'a> {
    pub watch: &'a Option<std::sync::Arc<crate::progress::Watch>>,
    pub scene_a: &'a Scene,
    pub scene_b: &'a Scene,
    pub level: u8,
    pub quads: &'a [QuadId],
    pub region: Option<GeoBox>,
    pub curvature: bool,
    pub frame: &'a Frame,
    pub scratch: &'a Path,
}

/// What a bias reads at each sample (A's elevation filled in step by step).
pub(super) fn sample_attributes(frame: &Frame, reference: &[RefSample]) -> Vec<At> {
    reference
        .par_iter()
        .map(|r| {
            let (east_m, north_m) = frame.local(r.p);
            At {
                east_m,
                north_m,
                elevation_m: f64::from(r.b),
                slope_deg: r.tan_slope().atan().to_degrees(),
                max_curvature: f64::from(r.max_curvature),
            }
        })
        .collect()
}

/// The statistics of A − B over every sample before the pipeline and of A′ − B after it (each
/// step's bias at a sample, `bias_at(step, at)`, and where each step left A, `stands`),
/// cell-area weighted.
pub(super) fn whole_area_stats(
    area: &WholeArea,
    stands: &[Stand],
    bias_at: &dyn Fn(usize, &At) -> f64,
) -> Result<(Stats, Stats), CompareError> {
    let scratch_error = |path: &Path, e: std::io::Error| CompareError::File {
        path: path.to_path_buf(),
        problem: format!("the co-registration's scratch file: {e}"),
    };
    let mut before = Spill::create(area.scratch).map_err(|e| scratch_error(area.scratch, e))?;
    let mut after = Spill::create(area.scratch).map_err(|e| scratch_error(area.scratch, e))?;
    for chunk in area.quads.chunks(16) {
        super::tick(area.watch, chunk.len())?;
        let reference = reference_samples(area.scene_b, chunk, area.region, area.curvature)?;
        let mut at = sample_attributes(area.frame, &reference);
        let mut mosaic = Mosaic::new(area.scene_a.clone(), area.level, Interpolation::Bicubic);
        let raw_before = differences(&mut mosaic, &reference, 0.0, 0.0)?;
        let mut raw = raw_before.clone();
        let mut stand = Stand { shift: (0.0, 0.0), up: 0.0 };
        let mut bias = vec![0.0; reference.len()];
        for (k, next) in stands.iter().enumerate() {
            for ((a, r), (d, b)) in at.iter_mut().zip(&reference).zip(raw.iter().zip(&bias)) {
                a.elevation_m = d.map_or(f64::NAN, |d| f64::from(r.b) + (d + stand.up - b));
            }
            if next.shift != stand.shift {
                raw = differences(&mut mosaic, &reference, next.shift.0, next.shift.1)?;
            }
            stand = *next;
            for (b, a) in bias.iter_mut().zip(&at) {
                *b += bias_at(k, a);
            }
        }
        for (k, r) in reference.iter().enumerate() {
            let class =
                slope_class(&SLOPE_CLASSES_DEG, r.tan_slope().atan().to_degrees()).map_or(NO_CLASS, |c| c as u8);
            let record = |dh_m: f64| Record { dh_m, weight: r.area, class };
            if let Some(d) = raw_before[k] {
                before.push(record(d)).map_err(|e| scratch_error(before.path(), e))?;
            }
            if let Some(d) = raw[k] {
                after.push(record(d + stand.up - bias[k])).map_err(|e| scratch_error(after.path(), e))?;
            }
        }
    }
    let stats = |spill: &mut Spill| -> Result<Stats, CompareError> {
        spill.finish().map_err(|e| scratch_error(spill.path(), e))?;
        let s =
            streamed_stats(spill, 0, &SLOPE_CLASSES_DEG, HISTOGRAM_BINS).map_err(|e| scratch_error(spill.path(), e))?;
        Ok(s.stats)
    };
    Ok((stats(&mut before)?, stats(&mut after)?))
}
