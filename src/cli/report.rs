//! Text reports: the distortion table and the overview printed by `terrafuse overview`.

use std::fmt::Write as _;

use crate::ecm::distortion::{self, DistortionSummary, GridSystem, Location, Sampling};
use crate::ecm::{CubeProjection, QuadId};
use crate::geodesy::{self, Ellipsoid, Geodetic};

fn describe(location: &Location) -> String {
    format!(
        "{} (u,v)=({:.4},{:.4}) lat {:.3} lon {:.3}",
        location.chart, location.uv.0, location.uv.1, location.lat_deg, location.lon_deg
    )
}

/// Runs [`distortion::analyze`] on every system, pointwise on `n`×`n` points per chart and on
/// the cells of quadtree level `level`, and formats the comparison table with the published
/// figures beside the computed ones.
pub fn tissot_report(n: usize, level: u8) -> (String, Vec<(DistortionSummary, DistortionSummary)>) {
    let results: Vec<(DistortionSummary, DistortionSummary)> = GridSystem::ALL
        .iter()
        .map(|s| (distortion::analyze(*s, Sampling::Pointwise(n)), distortion::analyze(*s, Sampling::Cells(level))))
        .collect();
    let mut out = String::new();
    let _ = writeln!(out, "Distortion by Tissot's indicatrix (paper: Lambers & Kolb 2012, sec. 3)");
    let _ = writeln!(
        out,
        "pointwise: supremum over the sphere ({n}x{n} points per chart); cells: every cell of level {level}"
    );
    let _ = writeln!(
        out,
        "{:<36} {:>9} {:>9} {:>6} {:>11} {:>6} | {:>9} {:>11}",
        "system", "ω sup °", "ω corner", "paper", "area ratio", "paper", "cells ω °", "cells area"
    );
    for (point, cells) in &results {
        let (paper_omega, paper_ratio) = match point.system.published() {
            Some((o, r)) => (format!("{o:.1}"), format!("{r:.2}")),
            None => ("-".to_string(), "-".to_string()),
        };
        let corner = match point.system {
            GridSystem::Cube(p) => format!("{:.2}", distortion::cube_corner_omega_deg(p)),
            _ => "-".to_string(),
        };
        let (omega, ratio) = if point.max_omega_deg > 179.0 {
            ("degen.".to_string(), "degen.".to_string())
        } else {
            (format!("{:.2}", point.max_omega_deg), format!("{:.3}", point.area_ratio))
        };
        let _ = writeln!(
            out,
            "{:<36} {:>9} {:>9} {:>6} {:>11} {:>6} | {:>9.2} {:>11.3}",
            point.system.label(),
            omega,
            corner,
            paper_omega,
            ratio,
            paper_ratio,
            cells.max_omega_deg,
            cells.area_ratio
        );
    }
    let _ = writeln!(out, "\nwhere the extremes lie (cube maps: front face, x,y >= 0; u,v = chart coordinates):");
    for (point, cells) in &results {
        let _ = writeln!(out, "{}:", point.system.label());
        let _ = writeln!(out, "  pointwise max ω at {}", describe(&point.max_omega_at));
        let _ = writeln!(out, "  cells max ω     at {}", describe(&cells.max_omega_at));
        let _ = writeln!(out, "  cells max area  at {}", describe(&cells.max_area_at));
        let _ = writeln!(out, "  cells min area  at {}", describe(&cells.min_area_at));
    }
    let _ = writeln!(
        out,
        "\nQSC: the paper's 24.9° is ω at the face corners; the supremum, ≈25.17°, is approached along the face\n\
         diagonals towards the face centre, where QSC is not differentiable (see docs/decisions.md).\n\
         90x90 + polar caps: each polar quarter has a straight angle at its arc midpoint, so the pointwise\n\
         indicatrix degenerates there (ω → 180°, area → 0); the cell figures show what that costs."
    );
    (out, results)
}

/// The overview printed by `terrafuse overview`: what the program does so far, shown on the
/// bundled landmark sample (`projects/samples/landmarks.txt`, lines of `name lat lon h`).
pub fn overview(landmarks: &str) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "Terrafuse {}: the Ellipsoidal Cube Map, in f64.", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(out, "Bodies: {}; {}; {}", Ellipsoid::WGS84, Ellipsoid::MOON, Ellipsoid::MARS);
    let _ = writeln!(out, "\nLandmarks on WGS84 → QSC face and level-12 quad, ECEF, and back:");
    let _ = writeln!(
        out,
        "{:<18} {:>10} {:>11} {:>7}  {:<6} {:>9} {:>9}  {:<22} {:>12}",
        "name", "lat", "lon", "h (m)", "face", "x", "y", "quad (face/level/x/y)", "roundtrip m"
    );
    let ellipsoid = Ellipsoid::WGS84;
    for line in landmarks.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')) {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let parsed: Option<(f64, f64, f64)> = (fields.len() == 4)
            .then(|| Some((fields[1].parse().ok()?, fields[2].parse().ok()?, fields[3].parse().ok()?)))
            .flatten();
        let Some((lat, lon, h)) = parsed else {
            let _ = writeln!(out, "(skipped malformed line '{line}')");
            continue;
        };
        let p = CubeProjection::Qsc.face_point_from_geodetic(&ellipsoid, lat.to_radians(), lon.to_radians());
        let quad = QuadId::containing(p, 12).map(|q| q.to_string()).unwrap_or_default();
        let g = Geodetic::from_degrees(lat, lon, h);
        let ecef = geodesy::ecef_from_geodetic(&ellipsoid, g);
        let back = geodesy::ecef_from_geodetic(&ellipsoid, geodesy::geodetic_from_ecef(&ellipsoid, ecef));
        let _ = writeln!(
            out,
            "{:<18} {:>10.5} {:>11.5} {:>7.0}  {:<6} {:>9.6} {:>9.6}  {:<22} {:>12.1e}",
            fields[0],
            lat,
            lon,
            h,
            p.face.name(),
            p.x,
            p.y,
            quad,
            (back - ecef).length()
        );
    }
    let _ = writeln!(
        out,
        "\nCommands: terrafuse geo to-face|from-face|to-ecef|from-ecef --body B (stdin → stdout, like cct),\n          terrafuse analyze tissot|cutoff, terrafuse import SRC… --store S --body B,\n          terrafuse store info|sample|export, terrafuse bench accuracy|import. See README.md."
    );
    out
}

/// What `export` (and a sharded export's merge) prints.
pub(super) fn export_line(
    out: &std::path::Path,
    attribute: Option<crate::attributes::Attribute>,
    report: &crate::export::ComposedReport,
    took: std::time::Duration,
) -> String {
    format!(
        "wrote {}{} ({}×{} pixels, level {}, {} quads composed on the {}, {} pixels with data) in {:.1} s\n",
        out.display(),
        attribute.map(|a| format!(": {} in {}", a.name(), a.unit())).unwrap_or_default(),
        report.size.0,
        report.size.1,
        report.level,
        report.quads,
        report.composer,
        report.valid,
        took.as_secs_f64()
    )
}
