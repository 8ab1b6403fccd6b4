//! The layout contract between the Pod structs the CPU uploads and the WGSL structs the shaders
//! read: the test below reflects every shader with naga and checks, for each Pod struct, its size
//! against the WGSL struct's span and every field's name and offset against the member's, so
//! that a field added, moved or retyped on one side alone fails the suite.

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::super::attributes::AttributeParams;
    use super::super::compose::{ComposeJob, JobLayer, OctaveOrigin};
    use super::super::erosion::{Control, GpuParams};
    use super::super::patch_errors::ErrorJob;
    use super::super::shading::ShadingProbe;
    use super::super::uniforms::{FrameUniform, PatchInstance, QuadInstance};
    use crate::gpu::brush::StrokeTile;

    /// A Rust struct's size and its fields' names and offsets, in declaration order.
    macro_rules! layout {
        ($t:ty { $($f:ident),* $(,)? }) => {
            (size_of::<$t>(), vec![$((stringify!($f), offset_of!($t, $f))),*])
        };
    }

    /// The WGSL struct `name` of shader `file` (composed): its span and its members' names and
    /// offsets.
    fn wgsl_layout(file: &str, name: &str) -> (usize, Vec<(String, usize)>) {
        let source = crate::gpu::shaders::composed(file).unwrap();
        let module = naga::front::wgsl::parse_str(&source).unwrap();
        let ty = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("{file} has no struct {name}"))
            .1;
        match &ty.inner {
            naga::TypeInner::Struct { members, span } => (
                *span as usize,
                members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize)).collect(),
            ),
            other => panic!("{file}: {name} is not a struct: {other:?}"),
        }
    }

    /// A Rust struct's size and its fields' names and offsets.
    type RustLayout = (usize, Vec<(&'static str, usize)>);

    #[test]
    fn every_pod_struct_matches_its_wgsl_struct_field_by_field() {
        let cases: Vec<(&str, &str, &str, RustLayout)> = vec![
            (
                "FrameUniform",
                "terrain.wgsl",
                "Frame",
                layout!(FrameUniform {
                    view_proj,
                    viewport,
                    sun,
                    iso,
                    iso_width,
                    iso_colour,
                    below,
                    above,
                    nodata,
                    difference,
                    brush,
                    morph
                }),
            ),
            (
                "QuadInstance",
                "terrain.wgsl",
                "Quad",
                layout!(QuadInstance { anchor, corners, normals, sym, slots, params, lod, ancestry, around }),
            ),
            (
                "PatchInstance",
                "terrain.wgsl",
                "Patch",
                layout!(PatchInstance { quad, i0, j0, stride, reach, reach_up, pad, edge_owner }),
            ),
            ("ErrorJob", "render/patch_errors.wgsl", "Job", layout!(ErrorJob { slot })),
            (
                "ComposeJob",
                "compose/compose.wgsl",
                "Job",
                layout!(ComposeJob { corners, sym, origin, slots, layers, params }),
            ),
            (
                "JobLayer",
                "compose/compose.wgsl",
                "JobLayer",
                layout!(JobLayer {
                    kind,
                    blend,
                    source,
                    partial,
                    segment_first,
                    segments,
                    ring_first,
                    rings,
                    octave_first,
                    octaves,
                    noise_type,
                    placement,
                    edge_slot,
                    bias_first,
                    biases,
                    pad0,
                    opacity,
                    weight,
                    scale,
                    offset_m,
                    valid_lo_m,
                    valid_hi_m,
                    feather_m,
                    ring_lon_min,
                    height_m,
                    amplitude_m,
                    gain,
                    feather_edge_m,
                    data_spacing_m,
                    orientation,
                    pad1,
                    pad2
                }),
            ),
            ("OctaveOrigin", "compose/compose.wgsl", "Octave", layout!(OctaveOrigin { cell, frac })),
            (
                "StrokeTile",
                "edit/stroke.wgsl",
                "Tile",
                layout!(StrokeTile { window, head, cell, frac, params, ramp_a, ramp_b, lat, diag, origin, ext_grid }),
            ),
            (
                "GpuParams",
                "erosion/erosion.wgsl",
                "Params",
                layout!(GpuParams {
                    width,
                    height,
                    n,
                    groups_x,
                    seed,
                    open_border,
                    groups,
                    chunk_shift,
                    unit_m3,
                    g,
                    friction,
                    tan_talus,
                    thermal,
                    hardness,
                    capacity,
                    capacity_depth_m,
                    min_slope,
                    dissolve,
                    deposit,
                    evaporation,
                    rain_m_s,
                    cfl,
                    dt_asked,
                    weight_sum,
                    weights
                }),
            ),
            (
                "Control",
                "erosion/erosion.wgsl",
                "Control",
                layout!(Control { dt, step, batch_step, _pad, totals, bound, max_speed, max_depth, _pad2 }),
            ),
            ("ShadingProbe", "probe/shading.wgsl", "Probe", layout!(ShadingProbe { normal, up, sun, iso, spacing })),
            ("AttributeParams", "attributes/attributes.wgsl", "Params", layout!(AttributeParams { size, light })),
        ];
        for (rust, file, wgsl, (size, fields)) in &cases {
            let (span, members) = wgsl_layout(file, wgsl);
            assert_eq!(*size, span, "{rust} is {size} bytes, {wgsl} in {file} {span}");
            let members: Vec<(&str, usize)> = members.iter().map(|(n, o)| (n.as_str(), *o)).collect();
            assert_eq!(fields, &members, "{rust} against {wgsl} in {file}: (field, offset) differ");
        }
        // Every Pod struct of the GPU module is listed above (a new one cannot be forgotten).
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/gpu");
        let mut pods = Vec::new();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let text = std::fs::read_to_string(entry.unwrap().path()).unwrap_or_default();
            let mut lines = text.lines();
            while let Some(line) = lines.next() {
                if line.trim_start().starts_with("#[derive(") && line.contains("Pod") {
                    let name = lines.next().and_then(|l| l.split("struct ").nth(1)).map(|r| r.trim_end_matches(" {"));
                    pods.extend(name.map(str::to_string));
                }
            }
        }
        pods.sort();
        let mut listed: Vec<String> = cases.iter().map(|c| c.0.to_string()).collect();
        listed.sort();
        assert_eq!(pods, listed, "Pod structs in src/gpu and the structs checked here");
    }
}
