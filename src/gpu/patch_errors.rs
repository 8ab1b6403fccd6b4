//! The patches' geometric errors δ on the GPU (`shaders/render/patch_errors.wgsl`): for each quad
//! given, each of its 64 patches at each stride, the largest vertical miss between its composed
//! heights and the mesh that stride draws. The renderer asks for a quad's errors once its heights
//! are current (and again when it is recomposed); the results
//! come back through a mapped buffer without waiting, a frame or two later, and until then the
//! renderer bounds the error by the patch's height range. CPU reference:
//! [`crate::scene::patch_error::patch_errors`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::compute::{compute_pipeline, readback_buffer, shader_module, storage_layout};
use super::context::GpuError;
use crate::ecm::QuadId;
use crate::scene::patches::{PATCHES_PER_EDGE, STRIDES};

/// Quads whose errors one submission computes at most.
pub(crate) const MAX_JOBS: usize = 32;
/// Errors per quad: one per patch and stride.
const PER_QUAD: usize = (PATCHES_PER_EDGE * PATCHES_PER_EDGE) as usize * STRIDES.len();

/// One quad's record for the kernel (`Job` in patch_errors.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ErrorJob {
    /// The quad's height slot, the fill height drawn where a vertex has no data (f32 bits),
    /// unused ×2.
    pub slot: [u32; 4],
}

/// What a quad's errors were computed from: its composition's stamp (the mesh stands on the
/// quad's own heights at every stride, so nothing else decides them).
pub(crate) type ErrorKey = u64;

/// A quad's δ per patch (row-major from the south) at each of [`STRIDES`], metres.
pub(crate) type QuadErrors = Vec<[f32; STRIDES.len()]>;

struct InFlight {
    read: wgpu::Buffer,
    quads: Vec<(QuadId, ErrorKey)>,
    ready: Arc<AtomicBool>,
}

/// The kernel, its buffers and the readbacks in flight.
pub(crate) struct PatchErrorPass {
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    jobs: wgpu::Buffer,
    out: wgpu::Buffer,
    in_flight: Vec<InFlight>,
}

impl PatchErrorPass {
    /// The pass over the renderer's height pool.
    pub(crate) fn new(device: &wgpu::Device, heights: &wgpu::Buffer) -> Result<PatchErrorPass, GpuError> {
        let module = shader_module(device, "render/patch_errors.wgsl")?;
        let layout = storage_layout(device, "patch errors", &[true, true, false]);
        let pipeline = compute_pipeline(device, "patch errors", &layout, &module, "patch_errors");
        let buffer = |label: &str, size: usize, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let jobs = buffer("patch error jobs", MAX_JOBS * std::mem::size_of::<ErrorJob>(), wgpu::BufferUsages::COPY_DST);
        let out = buffer("patch errors", MAX_JOBS * PER_QUAD * 4, wgpu::BufferUsages::COPY_SRC);
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("patch errors"),
            layout: &layout,
            entries: &[heights, &jobs, &out]
                .iter()
                .enumerate()
                .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.as_entire_binding() })
                .collect::<Vec<_>>(),
        });
        Ok(PatchErrorPass { pipeline, bind_group, jobs, out, in_flight: Vec::new() })
    }

    /// Computes the errors of up to [`MAX_JOBS`] quads and starts reading them back.
    pub(crate) fn submit(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, jobs: &[(QuadId, ErrorKey, ErrorJob)]) {
        let jobs = &jobs[..jobs.len().min(MAX_JOBS)];
        if jobs.is_empty() {
            return;
        }
        let records: Vec<ErrorJob> = jobs.iter().map(|j| j.2).collect();
        queue.write_buffer(&self.jobs, 0, bytemuck::cast_slice(&records));
        let bytes = (jobs.len() * PER_QUAD * 4) as u64;
        let read = readback_buffer(device, "patch errors read", bytes);
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.dispatch_workgroups(PATCHES_PER_EDGE * PATCHES_PER_EDGE, 1, jobs.len() as u32);
        }
        encoder.copy_buffer_to_buffer(&self.out, 0, &read, 0, bytes);
        queue.submit([encoder.finish()]);
        let ready = Arc::new(AtomicBool::new(false));
        let flag = ready.clone();
        read.slice(..).map_async(wgpu::MapMode::Read, move |r| flag.store(r.is_ok(), Ordering::Release));
        self.in_flight.push(InFlight { read, quads: jobs.iter().map(|j| (j.0, j.1)).collect(), ready });
    }

    /// The quads being computed.
    pub(crate) fn pending(&self) -> impl Iterator<Item = &(QuadId, ErrorKey)> {
        self.in_flight.iter().flat_map(|f| f.quads.iter())
    }

    /// The errors that have come back since the last call (never waits; the caller polls the
    /// device).
    pub(crate) fn take_ready(&mut self) -> Vec<(QuadId, ErrorKey, QuadErrors)> {
        let mut out = Vec::new();
        self.in_flight.retain(|f| {
            if !f.ready.load(Ordering::Acquire) {
                return true;
            }
            if let Ok(data) = f.read.slice(..).get_mapped_range() {
                let bits: &[u32] = bytemuck::cast_slice(&data);
                for (n, (quad, key)) in f.quads.iter().enumerate() {
                    let errors = bits[n * PER_QUAD..(n + 1) * PER_QUAD]
                        .chunks(STRIDES.len())
                        .map(|c| std::array::from_fn(|k| f32::from_bits(c[k])))
                        .collect();
                    out.push((*quad, *key, errors));
                }
            }
            false
        });
        out
    }
}
