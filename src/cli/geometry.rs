//! The flat-rule table of the ECM quad geometry (`terrafuse analyze cutoff`); the accuracy
//! benchmark that measures it lives in `crate::bench`.

use std::fmt::Write as _;

use crate::ecm::CubeProjection;
use crate::ecm::accuracy;
use crate::ecm::geometry::{self, FlatRule, HeightRange, cutoff_table, distinct_maps_per_level};
use crate::geodesy::Ellipsoid;

/// The flat rule fitted for `ellipsoid` and the per-level table, as text.
/// The rule the renderer uses: fitted for the body, with the tolerance capped at
/// `limit_fraction` of the f32 limit at each level's draw distance (default LOD model, 257
/// samples per quad edge); `limit_fraction` 0 keeps the absolute tolerance alone.
pub fn fitted_rule(ellipsoid: &Ellipsoid, tolerance_m: f64, limit_fraction: f64) -> FlatRule {
    let heights = HeightRange::for_body(ellipsoid);
    let draw0 = accuracy::LodModel::default().draw_distance_m(ellipsoid, 0, geometry::DEFAULT_SAMPLES);
    FlatRule::fit(ellipsoid, CubeProjection::Qsc, tolerance_m, heights).with_draw_limit(limit_fraction, draw0)
}

/// The flat rule fitted for `ellipsoid` and the per-level table, as text.
pub fn cutoff_report(
    ellipsoid: &Ellipsoid,
    tolerance_m: f64,
    limit_fraction: f64,
    max_level: u8,
    samples: u32,
) -> (String, FlatRule) {
    let heights = HeightRange::for_body(ellipsoid);
    let rule = fitted_rule(ellipsoid, tolerance_m, limit_fraction);
    let table = cutoff_table(ellipsoid, CubeProjection::Qsc, &rule, max_level, samples);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Static maps of the ECM on {} (a = {} m, b = {} m), QSC, tolerance {:e} m, heights {} … {} m",
        ellipsoid.name(),
        ellipsoid.a_m(),
        ellipsoid.b_m(),
        tolerance_m,
        heights.min_m,
        heights.max_m
    );
    let _ = writeln!(
        out,
        "flat rule: error ≤ A·w² + B·w/k (w quad side in face units, k ring distance from the face centre)\n  \
         A = {:.4e} m, B = {:.4e} m (fitted, ×1.25 margin); tolerance per level: {}; first level with flat quads: {}",
        rule.curvature_m,
        rule.cone_m,
        if rule.limit_fraction > 0.0 {
            format!(
                "min({:e} m, {} × the f32 limit at the level's draw distance)",
                rule.tolerance_m, rule.limit_fraction
            )
        } else {
            format!("{:e} m", rule.tolerance_m)
        },
        rule.first_flat_level().map_or("none".to_string(), |l| l.to_string())
    );
    let _ = writeln!(
        out,
        "measured on a scan of each level ({} samples per quad edge); |oₑ| bilinear is the paper's patch, \
         split the patch cut along the face diagonal",
        samples
    );
    let _ = writeln!(
        out,
        "{:>5} {:>11} {:>12} {:>12} {:>12} {:>11} {:>10} {:>9} {:>8} {:>12} {:>14} {:>11}",
        "level",
        "quad m",
        "|oₑ| bilin m",
        "|oₑ| split m",
        "n∠patch °",
        "|δn|",
        "tol m",
        "flat k≥",
        "flat %",
        "flat err m",
        "maps/level",
        "shared"
    );
    for row in &table {
        let (all, shared) = distinct_maps_per_level(row.level);
        let _ = writeln!(
            out,
            "{:>5} {:>11.4e} {:>12.4e} {:>12.4e} {:>12.4e} {:>11.3e} {:>10.3e} {:>9} {:>8.3} {:>12.3e} {:>14} {:>11}",
            row.level,
            row.quad_size_m,
            row.extremes.displacement_bilinear_m,
            row.extremes.displacement_m,
            row.extremes.normal_vs_patch_rad.to_degrees(),
            row.extremes.normal_delta,
            row.tolerance_m,
            row.flat_ring.map_or("-".to_string(), |k| k.to_string()),
            100.0 * row.flat_share,
            row.max_flat_error_m,
            all,
            shared
        );
    }
    let _ = writeln!(
        out,
        "n∠patch: angle between nₑ and the bilinear patch's normal (the paper's measure; first order in the quad \
         size, so never negligible for h·n, and from level ~27 the f64 rounding of the patch normal);\n\
         |δn|: departure of nₑ from the interpolated corner normals, what the flat path uses instead;\n\
         flat err: largest measured error of the flat path among the scanned quads the rule calls flat \
         (|oₑ| + 5·H·|δn|, must stay below tol);\nmaps/level: one per quad; shared: distinct maps after the symmetry"
    );
    (out, rule)
}
