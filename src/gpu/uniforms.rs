//! The Pod twins of the terrain shader's uniform and storage structs. Keep in sync with
//! `shaders/terrain.wgsl` (`Frame`, `Quad`): same fields, same order, explicit padding; the
//! size assertions below fail the build when one side changes alone.

use bytemuck::{Pod, Zeroable};

pub(crate) use super::codes::NO_SLOT;

/// Per-frame values (`Frame` in terrain.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct FrameUniform {
    pub(crate) view_proj: [[f32; 4]; 4],
    pub(crate) viewport: [f32; 4],
    pub(crate) sun: [f32; 4],
    pub(crate) iso: [f32; 4],
    pub(crate) iso_width: [f32; 4],
    pub(crate) iso_colour: [f32; 4],
    pub(crate) below: [f32; 4],
    pub(crate) above: [f32; 4],
    pub(crate) nodata: [f32; 4],
    pub(crate) difference: [f32; 4],
    pub(crate) brush: [f32; 4],
    pub(crate) morph: [f32; 4],
}

/// One quad's record for the shader (`Quad` in terrain.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct QuadInstance {
    pub(crate) anchor: [f32; 4],
    pub(crate) corners: [[f32; 4]; 4],
    pub(crate) normals: [[f32; 4]; 4],
    pub(crate) sym: [[f32; 4]; 3],
    pub(crate) slots: [u32; 4],
    pub(crate) params: [f32; 4],
    pub(crate) lod: [f32; 4],
    pub(crate) ancestry: [[u32; 4]; 2],
    pub(crate) around: [[u32; 4]; 2],
}

impl QuadInstance {
    /// The reference height h₀ the quad was placed with (exaggerated metres).
    pub fn reference_height_m(&self) -> f32 {
        self.anchor[3]
    }

    /// The skirt depth, metres.
    pub fn skirt_m(&self) -> f32 {
        self.params[0]
    }

    /// Whether the quad was drawn with static maps.
    pub fn has_maps(&self) -> bool {
        self.slots[1] != NO_SLOT
    }
}
/// One patch's record for the shader (`Patch` in terrain.wgsl; keep in sync): the quad's index
/// in the quad records, the sample (i, j) of its first corner, its stride in samples, and its
/// reach (metres: where its vertices morph toward twice the stride), and per side the index of the
/// neighbour that owns the edge (`Patch::edge_owner`), 48 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PatchInstance {
    pub(crate) quad: u32,
    pub(crate) i0: u32,
    pub(crate) j0: u32,
    pub(crate) stride: u32,
    pub(crate) reach: f32,
    pub(crate) reach_up: f32,
    pub(crate) pad: [f32; 2],
    pub(crate) edge_owner: [u32; 4],
}

impl PatchInstance {
    /// The record of a selected patch.
    pub(crate) fn of(p: &crate::scene::patches::Patch) -> PatchInstance {
        let (i0, j0) = p.origin();
        PatchInstance {
            quad: p.quad,
            i0,
            j0,
            stride: p.stride,
            reach: p.reach_m,
            reach_up: p.reach_up_m,
            pad: [0.0; 2],
            edge_owner: p.edge_owner,
        }
    }
}

pub(crate) fn v4(v: glam::Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

pub(crate) fn rgba(c: [u8; 4]) -> [f32; 4] {
    c.map(|v| f32::from(v) / 255.0)
}

const _: () = assert!(std::mem::size_of::<FrameUniform>() == 64 + 11 * 16);
const _: () = assert!(std::mem::size_of::<QuadInstance>() == 16 * (1 + 4 + 4 + 3 + 1 + 1 + 1 + 2 + 2));
const _: () = assert!(std::mem::size_of::<PatchInstance>() == 48);
