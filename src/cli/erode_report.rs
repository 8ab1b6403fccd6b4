//! The JSON report of an erosion run, the fields both models share written once (`erode`'s
//! hydraulic model and `erode_landscape`'s stream power add their own figures).

use crate::erosion::layer::Outcome;

/// The JSON report of an erosion run of either model: the fields every run has (steps, seconds,
/// the region's cells, level and quads, the change's range, the device, the cache and the
/// project) with the model's own `figures` (a JSON object) merged in; pretty, one line feed.
pub fn report_json(
    o: &Outcome,
    device: &str,
    cached: Option<&std::path::Path>,
    path: &std::path::Path,
    figures: serde_json::Value,
) -> String {
    let r = &o.region;
    let mut value = serde_json::json!({
        "steps": o.steps,
        "seconds": o.seconds,
        "cells": [r.width, r.height],
        "level": r.level,
        "quads": o.quads.len(),
        "delta_min_m": o.range_m.0,
        "delta_max_m": o.range_m.1,
        "device": device,
        "cache": cached.map(|c| c.display().to_string()),
        "project": path.display().to_string(),
    });
    if let (Some(all), serde_json::Value::Object(own)) = (value.as_object_mut(), figures) {
        all.extend(own);
    }
    serde_json::to_string_pretty(&value).unwrap_or_default() + "\n"
}
