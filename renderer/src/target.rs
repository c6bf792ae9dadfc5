//! Where a frame is drawn: a colour and a reversed-Z depth texture the
//! passes draw into in turn, then read back.

use crate::error::RenderError;
use crate::gpu::Gpu;

pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The sky: what no pass draws over.
const CLEAR: wgpu::Color = wgpu::Color { r: 0.02, g: 0.03, b: 0.07, a: 1.0 };

/// Kept by the renderer from frame to frame while the size stays, with its
/// read-back buffers: the profile of the default frame on lavapipe showed
/// the render thread faulting in fresh textures and buffers every frame.
pub struct Target {
    pub width: u32,
    pub height: u32,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    /// Bytes per row of the read-back buffers (aligned as copies ask).
    row: u32,
    color_buffer: wgpu::Buffer,
    depth_buffer: wgpu::Buffer,
}

impl Target {
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        let texture = |format, extra| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: None,
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | extra,
                view_formats: &[],
            })
        };
        // Effects laid over the frame read its depth.
        let (color, depth) = (
            texture(COLOR_FORMAT, wgpu::TextureUsages::empty()),
            texture(DEPTH_FORMAT, wgpu::TextureUsages::TEXTURE_BINDING),
        );
        let color_view = color.create_view(&wgpu::TextureViewDescriptor::default());
        let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
        let row = (width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: u64::from(row * height),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let (color_buffer, depth_buffer) = (buffer("colour read-back"), buffer("depth read-back"));
        Self { width, height, color, depth, color_view, depth_view, row, color_buffer, depth_buffer }
    }

    /// What the target holds, bytes: colour and depth, and their read-back
    /// buffers.
    pub fn held_bytes(&self) -> u64 {
        texture_bytes(&self.color) + texture_bytes(&self.depth) + self.color_buffer.size() + self.depth_buffer.size()
    }

    /// Whether this target is `width` x `height`.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.width == width && self.height == height
    }

    /// The frame's depth, for a pass laid over it to read.
    pub fn depth_view(&self) -> &wgpu::TextureView {
        &self.depth_view
    }

    /// One full-screen pass laid over the colour (no depth attachment: it
    /// may read the depth), submitted and waited for.
    pub fn run_overlay(
        &self,
        gpu: &Gpu,
        label: &str,
        record: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) -> Result<(), RenderError> {
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some(label),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &self.color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Load, store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            record(&mut pass);
        }
        gpu.queue.submit([encoder.finish()]);
        wait(gpu)
    }

    /// A render pass over the target, first cleared to `clear` (and the
    /// far plane) when given, else drawing over what is there.
    fn begin<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        clear: Option<wgpu::Color>,
    ) -> wgpu::RenderPass<'e> {
        let (color, depth) = if let Some(clear) = clear {
            (wgpu::LoadOp::Clear(clear), wgpu::LoadOp::Clear(0.0))
        } else {
            (wgpu::LoadOp::Load, wgpu::LoadOp::Load)
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: color, store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations { load: depth, store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// One pass into the target, submitted and waited for (so its time is
    /// its own): the first pass of a frame clears it to the sky and the far
    /// plane, later ones draw over what is there.
    pub fn run(
        &self,
        gpu: &Gpu,
        label: &str,
        first: bool,
        record: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) -> Result<(), RenderError> {
        self.run_clearing(gpu, label, first.then_some(CLEAR), record)
    }

    /// `run`, first clearing to `clear` when given.
    pub fn run_clearing(
        &self,
        gpu: &Gpu,
        label: &str,
        clear: Option<wgpu::Color>,
        record: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) -> Result<(), RenderError> {
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        {
            let mut pass = self.begin(&mut encoder, label, clear);
            record(&mut pass);
        }
        gpu.queue.submit([encoder.finish()]);
        wait(gpu)
    }

    /// Colour (RGBA8, rows from the top) and depth, copied back.
    pub fn read_back(&self, gpu: &Gpu) -> Result<(Vec<u8>, Vec<f32>), RenderError> {
        let (w, h, row) = (self.width, self.height, self.row);
        let (color_buffer, depth_buffer) = (&self.color_buffer, &self.depth_buffer);
        let mut encoder =
            gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read back") });
        for (texture, target, aspect) in [
            (&self.color, color_buffer, wgpu::TextureAspect::All),
            (&self.depth, depth_buffer, wgpu::TextureAspect::DepthOnly),
        ] {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo { texture, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect },
                wgpu::TexelCopyBufferInfo {
                    buffer: target,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
            );
        }
        gpu.queue.submit([encoder.finish()]);
        for b in [color_buffer, depth_buffer] {
            b.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        }
        let row_bytes = (w * 4) as usize;
        let read = wait(gpu).and_then(|()| {
            Ok((copy_rows(color_buffer, h, row, row_bytes)?, copy_rows(depth_buffer, h, row, row_bytes)?))
        });
        // Unmapped for the next frame's copy, whatever happened.
        color_buffer.unmap();
        depth_buffer.unmap();
        read
    }
}

/// The `height` rows of a mapped read-back buffer, `row_bytes` of each
/// padded `row`, copied once into values of `T`.
fn copy_rows<T: bytemuck::Pod>(
    buffer: &wgpu::Buffer,
    height: u32,
    row: u32,
    row_bytes: usize,
) -> Result<Vec<T>, RenderError> {
    let view = buffer.slice(..).get_mapped_range().map_err(|e| RenderError::Device(e.to_string()))?;
    let mut out = vec![T::zeroed(); height as usize * row_bytes / size_of::<T>()];
    let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut out);
    for (y, dst) in bytes.chunks_exact_mut(row_bytes).enumerate() {
        dst.copy_from_slice(&view[y * row as usize..y * row as usize + row_bytes]);
    }
    Ok(out)
}

/// Waits until the device has done all it was given.
pub fn wait(gpu: &Gpu) -> Result<(), RenderError> {
    gpu.device
        .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
        .map(|_| ())
        .map_err(|e| RenderError::Device(e.to_string()))
}

/// What a texture holds, bytes (every layer, one mip level).
pub fn texture_bytes(texture: &wgpu::Texture) -> u64 {
    let s = texture.size();
    let texel = u64::from(texture.format().block_copy_size(None).unwrap_or(4));
    u64::from(s.width) * u64::from(s.height) * u64::from(s.depth_or_array_layers) * texel
}
