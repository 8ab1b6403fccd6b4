//! `pop_px`: how far the drawn terrain jumps on screen when the density changes between two
//! frames (a patch's stride, or a quad split or merged), measured on the CPU in f64 from the
//! heights the GPU drew. Both frames' densities are evaluated with the new frame's camera, so the
//! camera's own motion is not counted: at each vertex of every patch that one frame draws and the
//! other does not, the surface each frame shows there (the vertex, morphed and stood on the edge a
//! neighbour owns as the shader places it, or the point of the other frame's triangle under
//! it) is projected, and the largest distance between the two in pixels is the frame's pop. With
//! geomorphing it is 0 up to the rounding of f64 where the morph band hides every change.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use glam::DVec3;

use super::context::GpuError;
use super::renderer::Renderer;
use crate::ecm::geometry::surface_and_normal;
use crate::ecm::{CubeProjection, FacePoint, QuadId};
use crate::scene::patches::{PATCH_CELLS, PATCHES_PER_EDGE, PatchMorph, stand_on_edge, vertex_weights};

/// Where a frame drew which density: per drawn quad, each patch's stride (0 where the patch was
/// culled), reaches (where its vertices morph, and where the coarser stride's do) and the
/// neighbours (patch indices in the quad) that own its sides' edges.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DensityLayout {
    quads: HashMap<QuadId, [Drawn; 64]>,
}

/// How one patch was drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Drawn {
    stride: u32,
    reach: f64,
    reach_up: f64,
    owners: [Option<u32>; 4],
}

impl DensityLayout {
    /// The layout of the renderer's prepared frame.
    pub fn of(renderer: &Renderer) -> DensityLayout {
        let mut quads: HashMap<QuadId, [Drawn; 64]> =
            renderer.drawn().iter().map(|q| (*q, [Drawn::default(); 64])).collect();
        let patches = &renderer.patches().patches;
        for p in patches {
            if let Some(q) = renderer.drawn().get(p.quad as usize)
                && let Some(entry) = quads.get_mut(q)
            {
                let owners = p.edge_owner.map(|k| patches.get(k as usize).map(|o| o.py * PATCHES_PER_EDGE + o.px));
                entry[(p.py * PATCHES_PER_EDGE + p.px) as usize] =
                    Drawn { stride: p.stride, reach: f64::from(p.reach_m), reach_up: f64::from(p.reach_up_m), owners };
            }
        }
        DensityLayout { quads }
    }

    /// The patches drawn, as (quad, patch index, stride).
    fn patches(&self) -> HashSet<(QuadId, usize, u32)> {
        self.quads
            .iter()
            .flat_map(|(q, patches)| {
                patches.iter().enumerate().filter(|(_, p)| p.stride > 0).map(move |(k, p)| (*q, k, p.stride))
            })
            .collect()
    }

    /// The drawn quad that covers sample coordinates (x, y) of `quad` (0 … 256 each), and the
    /// coordinates there: the quad itself, an ancestor or a descendant.
    fn locate(&self, quad: QuadId, x: f64, y: f64) -> Option<(QuadId, f64, f64)> {
        if self.quads.contains_key(&quad) {
            return Some((quad, x, y));
        }
        let (mut a, mut ax, mut ay) = (quad, x, y);
        while let Some(p) = a.parent() {
            ax = (ax + 256.0 * f64::from(a.x % 2)) / 2.0;
            ay = (ay + 256.0 * f64::from(a.y % 2)) / 2.0;
            a = p;
            if self.quads.contains_key(&a) {
                return Some((a, ax, ay));
            }
        }
        let (mut d, mut dx, mut dy) = (quad, x, y);
        for _ in 0..8 {
            let (cx, cy) = (u32::from(dx >= 128.0), u32::from(dy >= 128.0));
            let children = d.children()?;
            d = children[(cy * 2 + cx) as usize];
            dx = dx * 2.0 - 256.0 * f64::from(cx);
            dy = dy * 2.0 - 256.0 * f64::from(cy);
            if self.quads.contains_key(&d) {
                return Some((d, dx, dy));
            }
        }
        None
    }
}

/// The f64 evaluation of what a layout draws, from the renderer's composed heights.
struct Surfaces<'a> {
    renderer: &'a Renderer,
    camera: DVec3,
    morph: bool,
    exaggeration: f64,
    heights: HashMap<QuadId, Option<Arc<Vec<f32>>>>,
    positions: HashMap<(QuadId, u32, u32), Option<DVec3>>,
}

impl Surfaces<'_> {
    /// A quad's composed heights as the GPU holds them (empty: none, no data).
    fn heights(&mut self, quad: QuadId) -> Option<Arc<Vec<f32>>> {
        self.heights
            .entry(quad)
            .or_insert_with(|| match self.renderer.read_heights(quad) {
                Ok(Some(h)) => Some(Arc::new(h)),
                Ok(None) => Some(Arc::new(Vec::new())),
                Err(_) => None,
            })
            .clone()
    }

    /// The exact camera-relative position of sample (i, j) of a quad at its own height (the mesh
    /// stands on the quad's own samples at every stride).
    fn position(&mut self, quad: QuadId, i: u32, j: u32) -> Option<DVec3> {
        if let Some(p) = self.positions.get(&(quad, i, j)) {
            return *p;
        }
        let own = self.heights(quad)?;
        let raw = own.get((j * 257 + i) as usize).copied().unwrap_or(0.0);
        let height = if raw.is_nan() { 0.0 } else { f64::from(raw) * self.exaggeration };
        let (x, y) = quad.sample_xy(257, i, j);
        let (s, n) = surface_and_normal(
            &self.renderer.scene().ellipsoid,
            CubeProjection::Qsc,
            FacePoint { face: quad.face, x, y },
        );
        let p = Some((s - self.camera) + n * height);
        self.positions.insert((quad, i, j), p);
        p
    }

    /// The vertex (a, b) of a quad's patch (`patches`: the quad's layout), morphed and standing
    /// on the edge its neighbour owns as the shader places it ([`vertex_weights`]).
    fn vertex(&mut self, quad: QuadId, patches: &[Drawn; 64], patch: (u32, u32), a: u32, b: u32) -> Option<DVec3> {
        let index = patch.1 * PATCHES_PER_EDGE + patch.0;
        // Without geomorphing no vertex morphs (infinite reaches), but T-junctions still stand on
        // the coarser edge.
        let morph_of = |k: u32| {
            let d = patches[k as usize];
            let (reach_m, reach_up_m) = if self.morph { (d.reach, d.reach_up) } else { (f64::INFINITY, f64::INFINITY) };
            let origin = ((k % PATCHES_PER_EDGE) * PATCH_CELLS, (k / PATCHES_PER_EDGE) * PATCH_CELLS);
            PatchMorph { stride: d.stride, reach_m, reach_up_m, origin }
        };
        let own = morph_of(index);
        let sides = patches[index as usize].owners.map(|o| o.map(morph_of));
        // A sample without a position (no data read back) is among the weights, so none is drawn.
        let weights =
            vertex_weights(own, (a, b), sides, |i, j| self.position(quad, i, j).map_or(f64::NAN, |p| p.length()));
        let mut blend = |weights: &[((u32, u32), f64)]| -> Option<DVec3> {
            let mut sum = DVec3::ZERO;
            for &((i, j), w) in weights {
                sum += self.position(quad, i, j)? * w;
            }
            Some(sum)
        };
        let placed = blend(&weights.own)?;
        let edge = match &weights.edge {
            Some(e) => Some(blend(e)?),
            None => None,
        };
        let (i, j) = (own.origin.0 + a * own.stride, own.origin.1 + b * own.stride);
        Some(stand_on_edge(placed, edge, self.normal(quad, i, j)))
    }

    /// The ellipsoid's unit normal at sample (i, j) of a quad.
    fn normal(&self, quad: QuadId, i: u32, j: u32) -> DVec3 {
        let (x, y) = quad.sample_xy(257, i, j);
        let (_, n) = surface_and_normal(
            &self.renderer.scene().ellipsoid,
            CubeProjection::Qsc,
            FacePoint { face: quad.face, x, y },
        );
        n
    }

    /// The point a layout draws at sample coordinates (x, y) of `quad`: on the triangle of the
    /// patch mesh that covers it.
    fn surface(&mut self, layout: &DensityLayout, quad: QuadId, x: f64, y: f64) -> Option<DVec3> {
        let (q, x, y) = layout.locate(quad, x, y)?;
        let patches = layout.quads[&q];
        let cells = f64::from(PATCH_CELLS);
        let (px, py) = (((x / cells) as u32).min(7), ((y / cells) as u32).min(7));
        let stride = patches[(py * PATCHES_PER_EDGE + px) as usize].stride;
        if stride == 0 {
            return None;
        }
        let n = PATCH_CELLS / stride;
        let (u, v) = ((x - f64::from(px) * cells) / f64::from(stride), (y - f64::from(py) * cells) / f64::from(stride));
        let (a, b) = ((u.floor() as u32).min(n - 1), (v.floor() as u32).min(n - 1));
        let (fu, fv) = (u - f64::from(a), v - f64::from(b));
        let mut corner = |da: u32, db: u32| self.vertex(q, &patches, (px, py), a + da, b + db);
        let (v00, v11) = (corner(0, 0)?, corner(1, 1)?);
        // The cell's cut runs from (a, b) to (a+1, b+1), as the index buffers cut it.
        Some(if fu >= fv {
            let v10 = corner(1, 0)?;
            v00 + (v10 - v00) * fu + (v11 - v10) * fv
        } else {
            let v01 = corner(0, 1)?;
            v00 + (v11 - v01) * fu + (v01 - v00) * fv
        })
    }
}

/// The largest on-screen displacement (pixels) between what `old` and `new` draw where they
/// differ, both seen from the renderer's prepared camera (`new` being its prepared frame).
pub fn pop_px(renderer: &Renderer, old: &DensityLayout, new: &DensityLayout) -> Result<f64, GpuError> {
    let Some(camera) = renderer.last_camera() else { return Ok(0.0) };
    let (width, height) = renderer.size();
    let mut surfaces = Surfaces {
        renderer,
        camera: camera.position,
        morph: renderer.geomorphs(),
        exaggeration: renderer.scene().visuals.exaggeration,
        heights: HashMap::new(),
        positions: HashMap::new(),
    };
    let (before, after) = (old.patches(), new.patches());
    let mut worst = 0.0f64;
    for (changed, this, other) in [(after.difference(&before), new, old), (before.difference(&after), old, new)] {
        for &(quad, k, stride) in changed {
            let (px, py) = (k as u32 % PATCHES_PER_EDGE, k as u32 / PATCHES_PER_EDGE);
            let n = PATCH_CELLS / stride;
            for b in 0..=n {
                for a in 0..=n {
                    let x = f64::from(px * PATCH_CELLS + a * stride);
                    let y = f64::from(py * PATCH_CELLS + b * stride);
                    let (Some(p), Some(q)) = (surfaces.surface(this, quad, x, y), surfaces.surface(other, quad, x, y))
                    else {
                        continue;
                    };
                    if let (Some(sp), Some(sq)) = (camera.project(p, width, height), camera.project(q, width, height)) {
                        let on_screen = |s: (f64, f64, f64)| {
                            (0.0..=f64::from(width)).contains(&s.0) && (0.0..=f64::from(height)).contains(&s.1)
                        };
                        if on_screen(sp) || on_screen(sq) {
                            worst = worst.max(((sp.0 - sq.0).powi(2) + (sp.1 - sq.1).powi(2)).sqrt());
                        }
                    }
                }
            }
        }
    }
    Ok(worst)
}
