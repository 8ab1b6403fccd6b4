//! The field reference of `docs/project-format.md`, generated from the JSON Schema (so that the
//! page lists every field the code reads, with the doc comments' units and meanings): one table
//! per type, the project first, then the types it uses by name.

use std::fmt::Write as _;

use serde_json::Value;

/// The reference, Markdown.
pub fn markdown() -> String {
    let schema: Value = serde_json::from_str(&super::Project::schema()).unwrap_or_default();
    let mut out = String::new();
    type_section(&mut out, "Project", &schema);
    if let Some(defs) = schema.get("$defs").and_then(Value::as_object) {
        for (name, def) in defs {
            type_section(&mut out, name, def);
        }
    }
    out
}

fn one_line(text: &str) -> String {
    text.split("\n\n").next().unwrap_or("").replace('\n', " ").replace('|', "\\|")
}

fn type_section(out: &mut String, name: &str, def: &Value) {
    let _ = writeln!(out, "### {name}\n");
    if let Some(d) = def.get("description").and_then(Value::as_str) {
        let _ = writeln!(out, "{}\n", d.replace("[`", "`").replace("`]", "`"));
    }
    if let Some(props) = def.get("properties").and_then(Value::as_object) {
        let required: Vec<&str> = def
            .get("required")
            .and_then(Value::as_array)
            .map(|r| r.iter().filter_map(Value::as_str).collect())
            .unwrap_or_default();
        let _ = writeln!(out, "| field | type | default | meaning |\n|---|---|---|---|");
        for (field, spec) in props {
            let default = match spec.get("default") {
                Some(v) => format!("`{}`", compact(v)),
                None if required.contains(&field.as_str()) => "required".into(),
                None => "absent".into(),
            };
            let meaning = spec.get("description").and_then(Value::as_str).map(one_line).unwrap_or_default();
            let _ = writeln!(out, "| `{field}` | {} | {default} | {meaning} |", type_of(spec));
        }
        out.push('\n');
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(variants) = def.get(key).and_then(Value::as_array) {
            let _ = writeln!(out, "| value | meaning |\n|---|---|");
            for v in variants {
                let meaning = v.get("description").and_then(Value::as_str).map(one_line).unwrap_or_default();
                let _ = writeln!(out, "| {} | {meaning} |", type_of(v));
            }
            out.push('\n');
        }
    }
    if let Some(values) = def.get("enum").and_then(Value::as_array) {
        let names: Vec<String> = values.iter().map(|v| format!("`{}`", compact(v))).collect();
        let _ = writeln!(out, "One of {}.\n", names.join(", "));
    }
}

fn compact(v: &Value) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// A field's type in words: a named type links to its table.
fn type_of(spec: &Value) -> String {
    if let Some(r) = spec.get("$ref").and_then(Value::as_str) {
        let name = r.rsplit('/').next().unwrap_or(r);
        return format!("[{name}](#{})", name.to_lowercase());
    }
    if let Some(c) = spec.get("const") {
        return format!("`{}`", compact(c));
    }
    if let Some(values) = spec.get("enum").and_then(Value::as_array) {
        return values.iter().map(|v| format!("`{}`", compact(v))).collect::<Vec<_>>().join(" or ");
    }
    for key in ["anyOf", "oneOf"] {
        if let Some(variants) = spec.get(key).and_then(Value::as_array) {
            let parts: Vec<String> = variants.iter().map(type_of).filter(|t| t != "null").collect();
            return parts.join(" or ");
        }
    }
    let kinds: Vec<&str> = match spec.get("type") {
        Some(Value::String(t)) => vec![t.as_str()],
        Some(Value::Array(ts)) => ts.iter().filter_map(Value::as_str).filter(|t| *t != "null").collect(),
        _ => vec![],
    };
    let word = |kind: &str| -> String {
        match kind {
            "array" => {
                let item = spec.get("items").map(type_of).unwrap_or_else(|| "value".into());
                match (spec.get("minItems"), spec.get("maxItems")) {
                    (Some(a), Some(b)) if a == b => format!("{a} × {item}"),
                    _ => format!("list of {item}"),
                }
            }
            "object" => match spec.get("additionalProperties") {
                Some(v) if v.is_object() => format!("map of name → {}", type_of(v)),
                _ => "object".into(),
            },
            "integer" => match spec.get("format").and_then(Value::as_str) {
                Some(f) => format!("integer ({f})"),
                None => "integer".into(),
            },
            "number" => "number".into(),
            other => other.to_string(),
        }
    };
    kinds.iter().map(|k| word(k)).collect::<Vec<_>>().join(" or ")
}
