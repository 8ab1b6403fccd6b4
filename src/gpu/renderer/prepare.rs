//! A frame's preparation: the quads selected, their data made resident and current (composed
//! where their slot lacks their plan's stamp, loaded where the CPU cache lacks them), each drawn
//! quad's record for the shader (camera-relative values from f64, its slots and those around and
//! above it, its skirt) and its patches' errors, then the patches selected and written.

use super::*;

/// What one drawn quad hands the patch selection: its patch boxes and effective errors.
type QuadPatchData = (crate::scene::quads::PatchBoxes, Vec<[f64; STRIDES.len()]>);

impl Renderer {
    /// Prepares a frame without waiting for anything: takes the data that arrived, selects the
    /// quads, fills GPU slots for the most wanted ones, asks the loader for the rest, and writes
    /// the per-quad values and the frame's uniforms.
    pub fn prepare(&mut self, spec: &CameraSpec, width: u32, height: u32) -> FrameStats {
        let start = Instant::now();
        self.frame += 1;
        let mut stats = FrameStats::default();
        self.take_arrivals(&mut stats.errors);
        self.take_patch_errors();
        self.ensure_overlay();
        let camera = self.camera(spec);
        let params = self.select_params(width, height);
        let t = Instant::now();
        let selection = self.select_quads(&camera, &params);
        stats.select_ms = t.elapsed().as_secs_f64() * 1e3;
        let stale = self.make_resident(&selection, &mut stats);

        // Per-quad values, camera-relative, from f64; each quad's patch boxes and errors.
        self.instances.clear();
        let mut error_jobs = Vec::new();
        let per_quad: Vec<QuadPatchData> = selection
            .quads
            .iter()
            .map(|&quad| self.quad_record(quad, spec.alt, &camera, &mut error_jobs, &mut stats))
            .collect();
        if !self.instances.is_empty() {
            self.queue.write_buffer(&self.quad_buffer, 0, bytemuck::cast_slice(&self.instances));
        }
        for jobs in error_jobs.chunks(MAX_JOBS).take(2) {
            self.error_pass.submit(&self.device, &self.queue, jobs);
        }
        let quads: Vec<QuadPatches> = per_quad.iter().map(|(b, e)| QuadPatches { bounds: b, errors_m: e }).collect();
        let tau = self.scene.detail.max_pixel_error;
        self.patches = select_patches(&camera, &params, &quads, self.adaptive, self.geomorph, tau);
        self.patch_boxes = per_quad.into_iter().map(|(b, _)| b).collect();
        let records: Vec<PatchInstance> = self.patches.patches.iter().map(PatchInstance::of).collect();
        if !records.is_empty() {
            self.queue.write_buffer(&self.patch_buffer, 0, bytemuck::cast_slice(&records));
        }
        self.write_frame(&camera, width, height);
        self.drawn = selection.quads.clone();
        stats.triangles = self.patches.triangles();
        stats.max_error_px = self.patches.max_error_px;
        stats.pixels = u64::from(width) * u64::from(height);
        stats.patches = self.patches.clone();
        stats.pending = selection.wanted.len() + stale + stats.errors_pending;
        stats.gpu_slots = (
            self.heights_pool.slots.len(),
            self.heights_pool.capacity,
            self.maps_pool.slots.len(),
            self.maps_pool.capacity,
        );
        stats.cpu_bytes = self.cpu.used_bytes();
        stats.selection = selection;
        stats.prepare_ms = start.elapsed().as_secs_f64() * 1e3;
        self.camera = Some(camera);
        self.size = (width, height);
        stats
    }

    /// The selection's settings for an image of `width` × `height`.
    fn select_params(&self, width: u32, height: u32) -> SelectParams {
        let lowest = self.scene.range_m.0.min(0.0) * self.scene.visuals.exaggeration;
        let e = self.scene.ellipsoid;
        SelectParams {
            threshold_px: self.scene.detail.lod_threshold_px,
            max_quads: self.scene.detail.max_quads.max(6),
            width,
            height,
            occluder_m: (e.a_m() + lowest, e.b_m() + lowest),
        }
    }

    /// The quads to draw from `camera`.
    fn select_quads(&mut self, camera: &Camera, params: &SelectParams) -> Selection {
        let mut source = Source {
            scene: &self.scene,
            cache: &mut self.cache,
            heights: &self.heights_pool,
            maps: &self.maps_pool,
            flat: &self.flat,
            exaggeration: self.scene.visuals.exaggeration,
        };
        select::select(camera, params, &mut source)
    }

    /// Makes the selection's data resident and current, as far as this frame can, and asks the
    /// loader for the rest; the number of drawn quads still showing an older stack.
    fn make_resident(&mut self, selection: &Selection, stats: &mut FrameStats) -> usize {
        // Keep what is drawn and its ancestors; then, in priority order (coarsest and largest first), take wanted
        // quads while their slots fit in what the drawn ones leave free, keep their slots, fill
        // the missing ones from the CPU cache and ask the loader for the rest. Strict priority
        // and no more than fits means slots are never taken from each other in circles.
        // Ancestors stay too: selection walks down through them every frame, and they stand in
        // at once when the view pulls back (a 4-ary tree has at most a third as many inner
        // quads as leaves).
        // Split quads stay too, also those whose children are all culled (nothing drawn under
        // them), and the six roots, which selection always visits: evicting either made the
        // next frame unable to split them, so the view collapsed and recovered frame after frame
        // once the GPU cache was full.
        let mut kept: std::collections::HashSet<QuadId> = selection.quads.iter().copied().collect();
        kept.extend(selection.split.iter().copied());
        kept.extend(crate::ecm::Face::ALL.map(QuadId::root));
        for q in &selection.quads {
            for a in q.ancestors() {
                if !kept.insert(a) {
                    break;
                }
            }
        }
        let mut maps_counted = std::collections::HashSet::new();
        let mut heights_pinned = 0u32;
        for q in &kept {
            if self.heights_pool.touch(*q, self.frame).is_some() {
                heights_pinned += 1;
            }
            let canonical = MapSymmetry::of(*q).canonical;
            if !self.flat.is_flat(*q) && maps_counted.insert(canonical) {
                self.maps_pool.touch(canonical, self.frame);
            }
        }
        let mut free_heights = self.heights_pool.capacity.saturating_sub(heights_pinned);
        let mut free_maps = self.maps_pool.capacity.saturating_sub(maps_counted.len() as u32);
        let mut requests = Vec::new();
        let mut batch = ComposeBatch::default();
        let on = self.compose_on;
        // Drawn quads whose layers changed are recomposed first (they stay drawn meanwhile, with
        // their old heights, and count as pending until their new ones are composed).
        let mut stale = 0;
        for q in &selection.quads {
            if !self.ensure_heights(*q, on, &mut batch, stats, &mut requests) {
                stale += 1;
            }
        }
        // The ancestors whose data the drawn quads' coarser strides show are kept current too
        // (after a layer changes; until then a quad shows its own data there).
        let mut ancestors: Vec<QuadId> = selection
            .quads
            .iter()
            .flat_map(|q| q.ancestors().take(DATA_LEVELS_UP as usize))
            .filter(|a| self.heights_pool.get(*a).is_some())
            .collect();
        ancestors.sort_unstable();
        ancestors.dedup();
        for a in ancestors {
            self.ensure_heights(a, on, &mut batch, stats, &mut requests);
        }
        for q in &selection.wanted {
            let has = self.cache.plan(&self.scene, *q).has_data(&self.scene.stack);
            let canonical = MapSymmetry::of(*q).canonical;
            let new_map = !self.flat.is_flat(*q) && !maps_counted.contains(&canonical);
            if u32::from(has) > free_heights || u32::from(new_map) > free_maps {
                stats.blocked += 1;
                break;
            }
            free_heights -= u32::from(has);
            if new_map {
                free_maps -= 1;
                maps_counted.insert(canonical);
                self.maps_pool.touch(canonical, self.frame);
            }
            if let Some(key) = self.missing_maps(*q) {
                if !self.cpu.contains(key) {
                    if !requests.contains(&key) {
                        requests.push(key);
                    }
                } else if stats.uploads < UPLOADS_PER_FRAME && self.upload(key) {
                    stats.uploads += 1;
                }
            }
            if has {
                self.heights_pool.touch(*q, self.frame);
                self.ensure_heights(*q, on, &mut batch, stats, &mut requests);
            }
        }
        self.submit_composition(&batch, stats);
        stats.requested = requests.len();
        self.loader.request(&requests);
        if stats.uploads > 0 || !stats.composed.is_empty() {
            // Hand the writes to the GPU now, so that their staging memory is released even when
            // frames are prepared without being drawn.
            self.queue.submit([]);
            let _ = self.device.poll(wgpu::PollType::Poll);
        }
        stale
    }

    /// One drawn quad's record for the shader (pushed onto `instances`), camera-relative from
    /// f64 with the reference height nearest the camera's altitude `alt`, and its patches' boxes
    /// and effective errors (a job for the error pass where they are not known yet).
    fn quad_record(
        &mut self,
        quad: QuadId,
        alt: f64,
        camera: &Camera,
        error_jobs: &mut Vec<(QuadId, ErrorKey, ErrorJob)>,
        stats: &mut FrameStats,
    ) -> QuadPatchData {
        let exaggeration = self.scene.visuals.exaggeration;
        let e = self.scene.ellipsoid;
        let plan = self.cache.plan(&self.scene, quad);
        let has = plan.has_data(&self.scene.stack);
        let range = self.cache.range(&self.scene, &plan, exaggeration);
        let roughness = self.cache.roughness(&self.scene, &plan, spacing_m(&e, quad.level));
        let info = self.cache.infos.get(&quad).map(|i| i.1);
        let g = self.cache.geometry(&self.scene, quad);
        let h0 = alt.clamp(f64::from(range.0), f64::from(range.1));
        let frame = QuadFrame::new(&g.corners_ecef, &g.corner_normals, camera.position, h0);
        let symmetry = MapSymmetry::of(quad);
        let m = symmetry.matrix();
        let map_slot =
            if self.flat.is_flat(quad) { NO_SLOT } else { self.maps_pool.get(symmetry.canonical).unwrap_or(NO_SLOT) };
        let height_slot = if has { self.heights_pool.get(quad).unwrap_or(NO_SLOT) } else { NO_SLOT };
        let flags = u32::from(symmetry.swap) | u32::from(symmetry.flip_x) << 1 | u32::from(symmetry.flip_y) << 2;
        let edge_m = info.map_or(0.0, |i| i.edge_m);
        let bounds = self.cache.patch_bounds(&self.scene, &plan, exaggeration, edge_m);
        let spacing = edge_m / f64::from(SAMPLES - 1);
        let r_min = e.b_m() * e.b_m() / e.a_m();
        let sag = spacing * spacing / (8.0 * r_min);
        let relief = f64::from(range.1 - range.0);
        let skirt = (8.0 * roughness * exaggeration).min(relief + roughness * exaggeration)
            + 64.0 * sag
            + 1e-3 * spacing
            + 0.01;
        if map_slot == NO_SLOT {
            stats.flat_quads += 1;
        }
        let ancestry = self.ancestry(quad);
        let around = self.around(quad);
        let current = height_slot != NO_SLOT && self.composed.get(&quad) == Some(&plan.stamp);
        let key: ErrorKey = plan.stamp;
        let bound = relief + roughness * exaggeration;
        let errors = match self.errors.get(&quad) {
            _ if !has => vec![[0.0; STRIDES.len()]; 64],
            Some((k, e)) if *k == key => {
                e.iter().map(|d| effective_errors(&d.map(|v| f64::from(v) * exaggeration))).collect()
            }
            _ => {
                if current && !self.error_pass.pending().any(|p| *p == (quad, key)) {
                    error_jobs.push((quad, key, ErrorJob { slot: [height_slot, NO_DATA_FILL_M.to_bits(), 0, 0] }));
                }
                stats.errors_pending += 1;
                // Until they come: the mesh stays within the patch's relief at every stride
                // but the finest, which draws every sample.
                let bound = STRIDES.map(|s| if s == 1 { 0.0 } else { bound });
                vec![effective_errors(&bound); 64]
            }
        };
        self.instances.push(QuadInstance {
            anchor: v4(frame.anchor, frame.reference_height_m),
            corners: frame.corners.map(|c| v4(c, 0.0)),
            normals: frame.corner_normals.map(|n| v4(n, 0.0)),
            sym: [m.x_axis, m.y_axis, m.z_axis].map(|c| v4(c.as_vec3(), 0.0)),
            slots: [Split::of(quad).code(), map_slot, height_slot, flags],
            params: [
                skirt as f32,
                f32::from(quad.level),
                NO_DATA_FILL_M,
                (relief + roughness * exaggeration + skirt) as f32,
            ],
            lod: [spacing as f32, 0.0, 0.0, 0.0],
            ancestry,
            around,
        });
        (bounds, errors)
    }
}
