//! What a layer's type cannot check: ranges, limits, and the blend mode a kind needs
//! ([`LayerSpec::check`]), field by field.

use super::*;
use crate::errors::FieldProblem;

impl LayerSpec {
    /// Checks the values that the type cannot: ranges, limits, the blend mode a kind needs.
    /// `radius_m` is the body's semi-major axis (it bounds the finest noise wavelength). Which
    /// fields a kind has is the type's business ([`file`] refuses a misplaced field by name).
    pub fn check(&self, radius_m: f64) -> Result<(), LayerError> {
        let bad = |field: &str, problem: String| Err(LayerError::field(&self.name, field, problem));
        if self.name.trim().is_empty() {
            return bad("name", "must not be empty".into());
        }
        if !(0.0..=1.0).contains(&self.opacity) {
            return bad("opacity", format!("{} must lie in [0, 1]", self.opacity));
        }
        if !(self.weight.is_finite() && self.weight >= 0.0) {
            return bad("weight", format!("{} must be a finite number ≥ 0", self.weight));
        }
        if !self.scale.is_finite() {
            return bad("scale", format!("{} must be finite", self.scale));
        }
        if !self.offset_m.is_finite() {
            return bad("offset_m", format!("{} must be finite", self.offset_m));
        }
        if let Some([lo, hi]) = self.valid_range_m
            && !(lo <= hi && !lo.is_nan() && !hi.is_nan())
        {
            return bad("valid_range_m", format!("[{lo}, {hi}] must be increasing"));
        }
        if !(self.feather_m.is_finite() && self.feather_m >= 0.0) {
            return bad("feather_m", format!("{} must be a distance ≥ 0 in metres", self.feather_m));
        }
        if self.feather_m > 0.0 && self.extent.is_none() {
            return bad("feather_m", "feathers the extent's edge, but the layer has no extent".into());
        }
        if let Some(extent) = &self.extent {
            check_extent(extent).map_err(|p| LayerError::field(&self.name, "extent", p.0))?;
        }
        let needs_add = |what: &str| {
            if self.blend == BlendMode::Add {
                Ok(())
            } else {
                bad("blend", format!("{}: an {what} layer holds height deltas and blends with add", self.blend.name()))
            }
        };
        match &self.payload {
            LayerPayload::Dataset(d) => check_dataset(d, radius_m).map_err(|e| LayerError::of_field(&self.name, e)),
            LayerPayload::Constant(c) if !c.height_m.is_finite() => {
                bad("height_m", format!("{} must be finite", c.height_m))
            }
            LayerPayload::Constant(_) => Ok(()),
            LayerPayload::Procedural(p) => {
                check_noise(&p.noise, radius_m).map_err(|e| LayerError::of_field(&self.name, e.under("noise")))
            }
            LayerPayload::Edit(e) => {
                needs_add("edit")?;
                if e.strokes.len() > MAX_STROKES {
                    return bad(
                        "strokes",
                        format!("{} strokes; an edit layer holds at most {MAX_STROKES}", e.strokes.len()),
                    );
                }
                if let Some(k) = e.applied
                    && k > e.strokes.len()
                {
                    return bad("applied", format!("{k} is past the {} strokes", e.strokes.len()));
                }
                for (k, stroke) in e.strokes.iter().enumerate() {
                    stroke
                        .check(radius_m)
                        .map_err(|e| LayerError::of_field(&self.name, e.under(format_args!("strokes[{k}]"))))?;
                }
                Ok(())
            }
            LayerPayload::Erosion(e) => {
                needs_add("erosion")?;
                if e.runs.len() > MAX_RUNS {
                    return bad("runs", format!("{} runs; an erosion layer holds at most {MAX_RUNS}", e.runs.len()));
                }
                if let Some(k) = e.applied
                    && k > e.runs.len()
                {
                    return bad("applied", format!("{k} is past the {} runs", e.runs.len()));
                }
                for (k, run) in e.runs.iter().enumerate() {
                    run.check().map_err(|e| LayerError::of_field(&self.name, e.under(format_args!("runs[{k}]"))))?;
                    if run.level != e.runs[0].level {
                        return bad(
                            &format!("runs[{k}].level"),
                            format!(
                                "{} differs from runs[0]'s {} (one erosion layer erodes at one level)",
                                run.level, e.runs[0].level
                            ),
                        );
                    }
                }
                Ok(())
            }
            LayerPayload::Difference(d) => self.check_difference(d),
        }
    }

    /// A difference changes no height: the common fields that shape one stay at their defaults.
    fn check_difference(&self, d: &DifferenceLayer) -> Result<(), LayerError> {
        let unused = [
            ("blend", self.blend != BlendMode::Over),
            ("weight", self.weight != 1.0),
            ("scale", self.scale != 1.0),
            ("offset_m", self.offset_m != 0.0),
            ("valid_range_m", self.valid_range_m.is_some()),
            ("extent", self.extent.is_some()),
        ];
        if let Some((field, _)) = unused.iter().find(|(_, set)| *set) {
            return Err(LayerError::field(&self.name, field, "is not a field of a difference layer".into()));
        }
        let bad = |field: &str, problem: String| Err(LayerError::field(&self.name, field, problem));
        for (side, operand) in ["A", "B"].iter().zip(&d.of) {
            let names = operand.names();
            if names.is_empty() || names.iter().any(|n| n.trim().is_empty()) {
                return bad("of", format!("operand {side} '{operand}' names no layer"));
            }
        }
        if d.of[0] == d.of[1] {
            return bad("of", format!("A and B are both '{}': the difference would be 0", d.of[0]));
        }
        let style = &d.style;
        if let Some(r) = style.range_m
            && !(r.is_finite() && r > 0.0)
        {
            return bad("style.range_m", format!("{r} must be a positive height in metres"));
        }
        if !(style.percentile > 0.0 && style.percentile <= 100.0) {
            return bad("style.percentile", format!("{} must lie in (0, 100]", style.percentile));
        }
        if !(style.isolines_m.is_finite() && style.isolines_m >= 0.0) {
            return bad("style.isolines_m", format!("{} must be an interval ≥ 0 in metres", style.isolines_m));
        }
        Ok(())
    }
}

fn check_dataset(d: &DatasetLayer, radius_m: f64) -> Result<(), FieldProblem> {
    let widest = crate::layers::edge::quad_width_m(radius_m, 0);
    if !(d.feather_edge_m.is_finite() && d.feather_edge_m >= 0.0 && d.feather_edge_m <= widest) {
        return Err(FieldProblem::new(
            "feather_edge_m",
            format!("{} must be a distance in metres from 0 to {widest:.0} (a level-0 quad's width)", d.feather_edge_m),
        ));
    }
    if !(d.shift_m.iter().all(|v| v.is_finite() && v.abs() <= MAX_SHIFT_M)) {
        return Err(FieldProblem::new(
            "shift_m",
            format!("{:?} must be [east, north] in metres, each within ±{MAX_SHIFT_M}", d.shift_m),
        ));
    }
    for bias in &d.correction {
        bias.check().map_err(|problem| FieldProblem::new("correction", problem.to_string()))?;
    }
    Ok(())
}

fn check_extent(extent: &ExtentSpec) -> Result<(), crate::Invalid> {
    let lat_ok = |lat: f64| (-90.0..=90.0).contains(&lat);
    match extent {
        ExtentSpec::Box([w, s, e, n]) => {
            if ![w, s, e, n].iter().all(|v| v.is_finite()) {
                return Err("box values must be finite".into());
            }
            if !(lat_ok(*s) && lat_ok(*n) && s < n) {
                return Err(format!("box south {s} and north {n} must lie in [-90, 90] with south < north").into());
            }
            if !((-360.0..=360.0).contains(w) && (-360.0..=360.0).contains(e)) || w == e {
                return Err(format!("box west {w} and east {e} must be distinct longitudes in degrees").into());
            }
            Ok(())
        }
        ExtentSpec::Polygon(ring) => {
            if ring.len() < 3 {
                return Err(format!("a polygon needs at least 3 vertices, not {}", ring.len()).into());
            }
            for (k, [lon, lat]) in ring.iter().enumerate() {
                if !(lon.is_finite() && lat_ok(*lat) && (-540.0..=540.0).contains(lon)) {
                    return Err(format!("vertex {k} [{lon}, {lat}] is not a [lon, lat] pair in degrees").into());
                }
            }
            Ok(())
        }
    }
}

fn check_noise(n: &NoiseSpec, radius_m: f64) -> Result<(), FieldProblem> {
    if !(n.amplitude_m.is_finite() && n.amplitude_m >= 0.0) {
        return Err(FieldProblem::new("amplitude_m", format!("{} must be a height ≥ 0 in metres", n.amplitude_m)));
    }
    if !(n.wavelength_m.is_finite() && n.wavelength_m > 0.0) {
        return Err(FieldProblem::new(
            "wavelength_m",
            format!("{} must be a positive length in metres", n.wavelength_m),
        ));
    }
    if !(1..=MAX_OCTAVES).contains(&n.octaves) {
        return Err(FieldProblem::new("octaves", format!("{} must lie in 1..={MAX_OCTAVES}", n.octaves)));
    }
    if !(n.lacunarity.is_finite() && n.lacunarity > 1.0 && n.lacunarity <= 16.0) {
        return Err(FieldProblem::new("lacunarity", format!("{} must lie in (1, 16]", n.lacunarity)));
    }
    if !(n.gain.is_finite() && n.gain > 0.0 && n.gain < 1.0) {
        return Err(FieldProblem::new("gain", format!("{} must lie in (0, 1)", n.gain)));
    }
    let finest = n.wavelength_m / n.lacunarity.powi(n.octaves as i32 - 1);
    if finest < radius_m * MIN_WAVELENGTH_OF_RADIUS {
        return Err(FieldProblem::new(
            "octaves",
            format!(
                "the finest octave's wavelength {finest:.3e} m is below {:.3e} m (the body's radius / 2³⁰)",
                radius_m * MIN_WAVELENGTH_OF_RADIUS
            ),
        ));
    }
    Ok(())
}
