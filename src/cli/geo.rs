//! `terrafuse geo …`: line-by-line conversions between geodetic, ECEF and cube-face coordinates.

use super::{CliError, Within};
use std::io::{self, BufRead, Write};

use glam::DVec3;

use super::format_f64;
use crate::ecm::{CubeProjection, Face, FacePoint};
use crate::geodesy::{self, Ellipsoid, Geodetic};

/// One conversion of `terrafuse geo`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeoOperation {
    /// `lat lon` (degrees) → `face x y`.
    ToFace,
    /// `face x y` → `lat lon` (degrees).
    FromFace,
    /// `lat lon h` (degrees, metres) → `X Y Z` (metres).
    ToEcef,
    /// `X Y Z` (metres) → `lat lon h`.
    FromEcef,
}

impl GeoOperation {
    fn expected(self) -> &'static str {
        match self {
            GeoOperation::ToFace => "`lat lon` in degrees",
            GeoOperation::FromFace => "`face x y` (face name or 0-5, x and y in [-1, 1])",
            GeoOperation::ToEcef => "`lat lon h` (degrees, degrees, metres)",
            GeoOperation::FromEcef => "`X Y Z` in metres",
        }
    }
}

/// What a batch run did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BatchReport {
    /// Lines converted.
    pub converted: usize,
    /// Lines refused (each reported on the error stream with its line number).
    pub refused: usize,
}

/// Reads one record per line from `input` and writes one converted record per line to
/// `output`. Blank lines and lines starting with `#` are copied through, so output lines stay
/// aligned with input lines. A malformed line is reported on `errors` as
/// `line N: …` and written as `nan` fields; the caller exits non-zero when any was refused.
pub fn run_batch(
    operation: GeoOperation,
    ellipsoid: &Ellipsoid,
    projection: CubeProjection,
    input: impl BufRead,
    mut output: impl Write,
    mut errors: impl Write,
) -> io::Result<BatchReport> {
    let mut report = BatchReport::default();
    for (index, line) in input.lines().enumerate() {
        let line = line?;
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            writeln!(output, "{line}")?;
            continue;
        }
        match convert(operation, ellipsoid, projection, trimmed) {
            Ok(fields) => {
                report.converted += 1;
                writeln!(output, "{}", fields.join(" "))?;
            }
            Err(message) => {
                report.refused += 1;
                writeln!(errors, "line {}: {message}: expected {}, got '{trimmed}'", index + 1, operation.expected())?;
                let width = if operation == GeoOperation::FromFace { 2 } else { 3 };
                let nan = vec!["nan"; width];
                writeln!(output, "{}", nan.join(" "))?;
            }
        }
    }
    output.flush()?;
    Ok(report)
}

fn numbers<const N: usize>(fields: &[&str]) -> Result<[f64; N], CliError> {
    if fields.len() < N {
        return Err(format!("{} field(s), need {N}", fields.len()).into());
    }
    let mut out = [0.0; N];
    for (slot, field) in out.iter_mut().zip(fields) {
        *slot = field.parse::<f64>().map_err(|_| CliError::Usage(format!("'{field}' is not a number")))?;
        if !slot.is_finite() {
            return Err(format!("'{field}' is not a finite number").into());
        }
    }
    Ok(out)
}

fn check_lat(lat_deg: f64) -> Result<(), CliError> {
    if lat_deg.abs() > 90.0 {
        return Err(format!("latitude {lat_deg} is outside [-90, 90]").into());
    }
    Ok(())
}

fn convert(
    operation: GeoOperation,
    ellipsoid: &Ellipsoid,
    projection: CubeProjection,
    line: &str,
) -> Result<Vec<String>, CliError> {
    let fields: Vec<&str> = line.split_whitespace().collect();
    match operation {
        GeoOperation::ToFace => {
            let [lat, lon] = numbers::<2>(&fields)?;
            check_lat(lat)?;
            let p = projection.face_point_from_geodetic(ellipsoid, lat.to_radians(), lon.to_radians());
            Ok(vec![p.face.name().to_string(), format_f64(p.x), format_f64(p.y)])
        }
        GeoOperation::FromFace => {
            let face: Face =
                fields.first().ok_or("empty line")?.parse().map_err(|e: crate::ecm::EcmError| e.to_string())?;
            let [x, y] = numbers::<2>(&fields[1..])?;
            let (lat, lon) = projection.geodetic_from_face_point(ellipsoid, FacePoint { face, x, y })?;
            Ok(vec![format_f64(lat.to_degrees()), format_f64(lon.to_degrees())])
        }
        GeoOperation::ToEcef => {
            let [lat, lon, h] = numbers::<3>(&fields)?;
            check_lat(lat)?;
            let p = geodesy::ecef_from_geodetic(ellipsoid, Geodetic::from_degrees(lat, lon, h));
            Ok(vec![format_f64(p.x), format_f64(p.y), format_f64(p.z)])
        }
        GeoOperation::FromEcef => {
            let [x, y, z] = numbers::<3>(&fields)?;
            let g = geodesy::geodetic_from_ecef(ellipsoid, DVec3::new(x, y, z));
            Ok(vec![format_f64(g.lat_rad.to_degrees()), format_f64(g.lon_rad.to_degrees()), format_f64(g.height_m)])
        }
    }
}

/// A `--region` box as every command takes it: `WEST,SOUTH,EAST,NORTH` in degrees (west > east
/// crosses the antimeridian); the error names the flag.
pub fn parse_box(text: &str) -> Result<crate::geodesy::GeoBox, CliError> {
    text.parse::<crate::geodesy::GeoBox>().within("--region")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(op: GeoOperation, text: &str) -> (String, String, BatchReport) {
        let mut out = Vec::new();
        let mut err = Vec::new();
        let report =
            run_batch(op, &Ellipsoid::WGS84, CubeProjection::Qsc, text.as_bytes(), &mut out, &mut err).unwrap();
        (String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap(), report)
    }

    #[test]
    fn malformed_lines_are_named_and_kept_aligned() {
        let (out, err, report) = run(GeoOperation::ToFace, "10 20\n# comment\nabc 3\n95 0\n\n1\n");
        assert_eq!(report, BatchReport { converted: 1, refused: 3 });
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), 6);
        assert!(lines[0].starts_with("front "));
        assert_eq!(lines[1], "# comment");
        assert_eq!(lines[2], "nan nan nan");
        assert!(err.contains("line 3: 'abc' is not a number"), "{err}");
        assert!(err.contains("line 4: latitude 95 is outside"), "{err}");
        assert!(err.contains("line 6: 1 field(s), need 2"), "{err}");
    }

    #[test]
    fn face_roundtrip_through_text() {
        let (out, _, _) = run(GeoOperation::ToFace, "-33.5 151.25\n89.9999 -180\n");
        let (back, err, report) = run(GeoOperation::FromFace, &out);
        assert_eq!(report.refused, 0, "{err}");
        let values: Vec<Vec<f64>> = back.lines().map(|l| l.split(' ').map(|f| f.parse().unwrap()).collect()).collect();
        assert!((values[0][0] + 33.5).abs() < 1e-12 && (values[0][1] - 151.25).abs() < 1e-12);
        assert!((values[1][0] - 89.9999).abs() < 1e-12 && (values[1][1].abs() - 180.0).abs() < 1e-9);
        let (_, err, report) = run(GeoOperation::FromFace, "top 1.5 0\nside 0 0\n");
        assert_eq!(report.refused, 2);
        assert!(err.contains("outside the face") && err.contains("unknown face 'side'"), "{err}");
    }
}
