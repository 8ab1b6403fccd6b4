//! The values a prepared frame hands the shader beside its quads and patches: the frame uniform
//! (camera, visuals, brush, geomorph band) and where each quad's pixels find data beyond its own
//! slot: its ancestry (the slots of the ancestors whose samples window attributes read) and the
//! slots of the quads around it at its level (whose samples a pixel near its edge reads).

use super::*;

impl Renderer {
    /// The height slots of a quad's ancestors 1 … 5 levels up whose composition is current
    /// (NO_SLOT otherwise), and the quad's x and y, for the shader's `data_index`.
    pub(super) fn ancestry(&mut self, quad: QuadId) -> [[u32; 4]; 2] {
        let mut slots = [NO_SLOT; 5];
        for (k, slot) in slots.iter_mut().enumerate() {
            let up = k as u8 + 1;
            if up > quad.level {
                break;
            }
            *slot = self.current_slot(quad.ancestor_at(quad.level - up));
        }
        [[slots[0], slots[1], slots[2], slots[3]], [slots[4], 0, quad.x, quad.y]]
    }

    /// The height slot of `quad` where its composition is current, NO_SLOT otherwise.
    fn current_slot(&mut self, quad: QuadId) -> u32 {
        let plan = self.cache.plan(&self.scene, quad);
        if plan.has_data(&self.scene.stack) && self.composed.get(&quad) == Some(&plan.stamp) {
            self.heights_pool.get(quad).unwrap_or(NO_SLOT)
        } else {
            NO_SLOT
        }
    }

    /// The current height slots of the eight quads around `quad` at its level on its face
    /// (south-west, south, south-east, west, east, north-west, north, north-east), NO_SLOT where
    /// one is not resident, not current, or over the face's edge: the indirection through which
    /// a pixel near the quad's edge reads the samples past it (the shader's `quad_sample`).
    /// Resolved here once per quad rather than per pixel through a page table on the GPU: a CPU
    /// rasteriser runs every branch any lane of a block takes, and a hashed lookup per sample
    /// read cost lavapipe 1.5–2.4× the terrain pass (measured 2026-12-07, BENCHMARKS.md).
    pub(super) fn around(&mut self, quad: QuadId) -> [[u32; 4]; 2] {
        let mut slots = [NO_SLOT; 8];
        let last = quad.quads_per_edge() as i64 - 1;
        let sides = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];
        for (slot, (dx, dy)) in slots.iter_mut().zip(sides) {
            let (x, y) = (i64::from(quad.x) + dx, i64::from(quad.y) + dy);
            if (0..=last).contains(&x) && (0..=last).contains(&y) {
                *slot = self.current_slot(QuadId { x: x as u32, y: y as u32, ..quad });
            }
        }
        [[slots[0], slots[1], slots[2], slots[3]], [slots[4], slots[5], slots[6], slots[7]]]
    }

    pub(super) fn write_frame(&self, camera: &Camera, width: u32, height: u32) {
        let v = &self.scene.visuals;
        let iso = &v.isolines;
        let light = &v.lighting;
        let uniform = FrameUniform {
            view_proj: camera.view_projection_f32(width, height).to_cols_array_2d(),
            viewport: [width as f32, height as f32, v.exaggeration as f32, self.scene.ramp.stops.len() as f32],
            sun: [
                light.sun_azimuth_deg.to_radians() as f32,
                light.sun_elevation_deg.to_radians() as f32,
                light.strength as f32,
                if light.enabled { 1.0 } else { 0.0 },
            ],
            iso: [
                iso.interval_m as f32,
                iso.offset_m as f32,
                iso.major_every as f32,
                if iso.enabled { 1.0 } else { 0.0 },
            ],
            iso_width: [iso.width_px, iso.major_width_px, iso.min_width_px, colour_by_code(v.colour_map.by)],
            iso_colour: rgba(iso.colour),
            below: rgba(self.scene.ramp.below),
            above: rgba(self.scene.ramp.above),
            nodata: rgba(self.scene.ramp.nodata),
            difference: match self.scene.stack.drawn_difference() {
                Some(d) => {
                    let spec = &self.scene.stack.layers[d].spec;
                    let style = spec.difference_style();
                    [self.difference_range_m() as f32, style.isolines_m as f32, spec.opacity as f32, 1.0]
                }
                None => [1.0, 0.0, 0.0, 0.0],
            },
            brush: self.brush.map_or([0.0; 4], |(centre, radius)| {
                let rel = centre - camera.position;
                [rel.x as f32, rel.y as f32, rel.z as f32, radius as f32]
            }),
            morph: [
                (camera.focal_px(height) / self.scene.detail.lod_threshold_px) as f32,
                MORPH_BAND_END as f32,
                if self.geomorph && self.adaptive { 1.0 } else { 0.0 },
                MORPH_BAND_START as f32,
            ],
        };
        self.queue.write_buffer(&self.frame_buffer, 0, bytemuck::bytes_of(&uniform));
    }
}

/// The terrain shader's code of what the ramp colours (`Frame.iso_width.w`): 0 the height, else 1
/// plus the attribute's code.
fn colour_by_code(by: crate::project::ColourBy) -> f32 {
    by.attribute().map_or(0.0, |a| (1 + crate::gpu::attributes::code(a)) as f32)
}
