//! The WGSL sources, embedded at build time, and their composition: a line
//! `//!include shared/NAME.wgsl` is replaced by that file, whose own includes are expanded in
//! turn; a file already included is not included again.

use super::context::GpuError;

/// Every WGSL file in `shaders/`, by path relative to it.
pub const FILES: &[(&str, &str)] = &[
    ("terrain.wgsl", include_str!("../../shaders/terrain.wgsl")),
    ("shared/ecm.wgsl", include_str!("../../shaders/shared/ecm.wgsl")),
    ("shared/shading.wgsl", include_str!("../../shaders/shared/shading.wgsl")),
    ("shared/noise.wgsl", include_str!("../../shaders/shared/noise.wgsl")),
    ("shared/hash.wgsl", include_str!("../../shaders/shared/hash.wgsl")),
    ("shared/attributes.wgsl", include_str!("../../shaders/shared/attributes.wgsl")),
    ("compose/compose.wgsl", include_str!("../../shaders/compose/compose.wgsl")),
    ("edit/stroke.wgsl", include_str!("../../shaders/edit/stroke.wgsl")),
    ("erosion/erosion.wgsl", include_str!("../../shaders/erosion/erosion.wgsl")),
    ("probe/shading.wgsl", include_str!("../../shaders/probe/shading.wgsl")),
    ("attributes/attributes.wgsl", include_str!("../../shaders/attributes/attributes.wgsl")),
    ("render/patch_errors.wgsl", include_str!("../../shaders/render/patch_errors.wgsl")),
];

/// The include that [`super::codes::wgsl`] generates: the codes shared with the CPU.
const GENERATED_CODES: &str = "generated/codes.wgsl";

/// A shader with its includes expanded; an error names a file or include that is not one of
/// [`FILES`] (the naga test expands every shipped file).
pub fn composed(name: &str) -> Result<String, GpuError> {
    let mut out = String::new();
    expand(name, &mut vec![name.to_string()], &mut out)?;
    Ok(out)
}

/// Appends file `name` to `out` with its includes expanded; `seen` holds the files already in.
fn expand(name: &str, seen: &mut Vec<String>, out: &mut String) -> Result<(), GpuError> {
    if name == GENERATED_CODES {
        out.push_str(&super::codes::wgsl());
        return Ok(());
    }
    for line in file(name)?.lines() {
        match line.trim().strip_prefix("//!include ") {
            Some(include) => {
                let include = include.trim();
                if !seen.iter().any(|s| s == include) {
                    seen.push(include.to_string());
                    expand(include, seen, out)?;
                }
            }
            None => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    Ok(())
}

fn file(name: &str) -> Result<&'static str, GpuError> {
    FILES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
        .ok_or_else(|| GpuError::Shader(format!("no shader file '{name}'")))
}

/// Parses and validates WGSL with naga (all capabilities the renderer may use), returning the
/// module's entry points or the error, formatted with the source.
pub fn validate(name: &str, source: &str) -> Result<Vec<String>, GpuError> {
    let module =
        naga::front::wgsl::parse_str(source).map_err(|e| GpuError::Shader(e.emit_to_string_with_path(source, name)))?;
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all());
    validator.validate(&module).map_err(|e| GpuError::Shader(e.emit_to_string_with_path(source, name)))?;
    Ok(module.entry_points.iter().map(|e| e.name.clone()).collect())
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_wgsl_file_is_listed_and_valid() {
        // Every file on disk is embedded (none forgotten) ...
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
        let mut on_disk = Vec::new();
        for sub in ["", "shared", "compose", "edit", "erosion", "probe", "attributes", "render"] {
            for entry in std::fs::read_dir(dir.join(sub)).unwrap() {
                let path = entry.unwrap().path();
                if path.extension().is_some_and(|e| e == "wgsl") {
                    on_disk.push(path.strip_prefix(&dir).unwrap().to_string_lossy().replace('\\', "/"));
                }
            }
        }
        on_disk.sort();
        let mut listed: Vec<String> = super::FILES.iter().map(|(n, _)| n.to_string()).collect();
        listed.sort();
        assert_eq!(on_disk, listed);
        // ... and each validates alone (the shared modules) or composed (the pipelines).
        for (name, _) in super::FILES {
            let source = super::composed(name).unwrap();
            let entries = super::validate(name, &source).unwrap_or_else(|e| panic!("{e}"));
            if *name == "terrain.wgsl" {
                assert_eq!(entries, ["vs_main", "fs_main", "fs_probe", "fs_points"]);
            }
            if *name == "compose/compose.wgsl" {
                assert_eq!(entries, ["compose", "compose_difference"]);
            }
            if *name == "edit/stroke.wgsl" {
                assert_eq!(entries, ["apply_stroke"]);
            }
            if *name == "erosion/erosion.wgsl" {
                assert_eq!(entries, ["outflow", "update", "reduce"]);
            }
        }
        // The validator does catch errors.
        assert!(super::validate("bad.wgsl", "fn f() -> f32 { return 1u; }").is_err());
    }
}
