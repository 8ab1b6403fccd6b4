//! Drawing the prepared frame: into a render pass (one instanced draw per stride), into targets
//! with the background cleared, or into an image read back.

use super::Renderer;
use crate::gpu::context::GpuError;
use crate::gpu::targets::{DrawMode, FrameTargets, RenderedImage};
use crate::scene::patches::PATCH_CELLS;

impl Renderer {
    /// Draws the prepared frame into a render pass.
    pub fn draw<'a>(&'a self, pass: &mut wgpu::RenderPass<'a>, mode: DrawMode) {
        if self.instances.is_empty() || self.patches.patches.is_empty() {
            return;
        }
        pass.set_bind_group(0, &self.bind_group, &[]);
        let groups = self.patches.groups();
        for (stride, skirts, morphs, first, count) in groups {
            match mode {
                DrawMode::Colour | DrawMode::Probe => {
                    pass.set_pipeline(self.terrain.pipeline(mode, morphs));
                    pass.set_index_buffer(self.terrain.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(self.terrain.indices_of(stride, skirts), 0, first..first + count);
                }
                DrawMode::Points => {
                    pass.set_pipeline(self.terrain.pipeline(mode, morphs));
                    let nv = PATCH_CELLS / stride + 1;
                    pass.draw(0..nv * nv, first..first + count);
                }
            }
        }
    }

    /// Records the prepared frame into `targets`: the colour target cleared to the background,
    /// the probe targets (for [`DrawMode::Probe`] and [`DrawMode::Points`]) to zero, depth to 0
    /// (reversed Z). `timestamps` gets the pass's start and end.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &FrameTargets,
        mode: DrawMode,
        timestamps: Option<&wgpu::QuerySet>,
    ) -> Result<(), GpuError> {
        let probe = mode != DrawMode::Colour;
        if probe && targets.surface.is_none() {
            return Err(GpuError::Targets("a probe pass needs probe targets (FrameTargets::new with probe = true)"));
        }
        let bg = self.scene.visuals.background.map(|c| crate::colour::srgb_to_linear(f64::from(c)));
        // The colour image is cleared to the background (the shader's output is already
        // sRGB-encoded, and so is the stored clear value of a unorm target).
        let clear = wgpu::Color {
            r: crate::colour::linear_to_srgb(bg[0]),
            g: crate::colour::linear_to_srgb(bg[1]),
            b: crate::colour::linear_to_srgb(bg[2]),
            a: f64::from(self.scene.visuals.background[3]) / 255.0,
        };
        let mut views = vec![(&targets.views[0], clear)];
        if probe {
            views.extend(targets.views[1..].iter().map(|v| (v, wgpu::Color::TRANSPARENT)));
        }
        let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = views
            .into_iter()
            .map(|(view, clear)| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
                })
            })
            .collect();
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("terrain"),
            color_attachments: &attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps.map(|q| wgpu::RenderPassTimestampWrites {
                query_set: q,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            }),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        self.draw(&mut pass, mode);
        Ok(())
    }

    /// Draws the prepared frame into an image and reads it back.
    pub fn render_image(&self, mode: DrawMode) -> Result<RenderedImage, GpuError> {
        let (width, height) = self.size;
        let probe = mode != DrawMode::Colour;
        let frame = FrameTargets::new(&self.device, width, height, probe, wgpu::TextureUsages::COPY_SRC);
        let queries = self.timestamps.then(|| {
            self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass time"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            })
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.encode(&mut encoder, &frame, mode, queries.as_ref())?;
        frame.read_back(&self.device, &self.queue, encoder, queries.as_ref())
    }
}
