//! The instances pass's models on the device: each model's triangles, and
//! its billboard, rendered from the model itself (seen from the side, in
//! its own colours) into one layer of the billboard atlas, with mips.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};
use relief_models::Model;
use wgpu::util::DeviceExt;

use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::target::{COLOR_FORMAT, Target};
use crate::uniforms::FrameUniform;

/// Models a scene's instances may use at once (atlas layers).
pub const MAX_MODELS: u32 = 16;
/// A billboard's texels, width by height.
pub const BILLBOARD_SIZE: (u32, u32) = (64, 128);
const MIPS: u32 = 6;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ModelVertex {
    position: [f32; 3],
    normal: [f32; 3],
    color: [f32; 4],
}

/// One instance as the shader reads it (see instances.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuInstance {
    pub pos: [f32; 4],
    pub east: [f32; 4],
    pub up: [f32; 4],
    pub billboard: [f32; 4],
}

pub const MODEL_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4];
pub const INSTANCE_ATTRIBUTES: [wgpu::VertexAttribute; 4] =
    wgpu::vertex_attr_array![4 => Float32x4, 5 => Float32x4, 6 => Float32x4, 7 => Float32x4];

/// A model's buffers and its billboard's layer.
pub struct GpuModel {
    pub model: Arc<Model>,
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub index_count: u32,
    pub layer: u32,
}

impl GpuModel {
    pub fn new(device: &wgpu::Device, model: Arc<Model>, layer: u32) -> Self {
        let vertices: Vec<ModelVertex> = (0..model.positions.len())
            .map(|v| ModelVertex { position: model.positions[v], normal: model.normals[v], color: model.colors[v] })
            .collect();
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("model vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("model triangles"),
            contents: bytemuck::cast_slice(&model.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let index_count = model.indices.len() as u32;
        Self { model, vertices, indices, index_count, layer }
    }

    /// The billboard's quad for this model at `scale`: half width, bottom,
    /// top (metres) and the atlas layer.
    pub fn billboard(&self, scale: f32) -> [f32; 4] {
        let b = self.model.bounds;
        [self.model.radius() * scale, b.min[1] * scale, b.max[1] * scale, self.layer as f32]
    }
}

/// The billboard atlas: one layer per model, with mips.
pub fn atlas(device: &wgpu::Device) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("billboard atlas"),
        size: wgpu::Extent3d { width: BILLBOARD_SIZE.0, height: BILLBOARD_SIZE.1, depth_or_array_layers: MAX_MODELS },
        mip_level_count: MIPS,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: COLOR_FORMAT,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// Renders `model` from the south (looking north, its x axis to the
/// right) with an orthographic camera fitted to its bounds, onto a clear
/// background, once per (pipeline, atlas): its colours unlit, and its
/// normals (the frame lights the billboard with them); each stored with
/// its mips in the model's layer.
pub fn bake(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    model: &GpuModel,
    images: &[(&wgpu::RenderPipeline, &wgpu::Texture)],
) -> Result<(), RenderError> {
    let device = &gpu.device;
    let b = model.model.bounds;
    let r = model.model.radius().max(1e-3);
    let (bottom, top) = (b.min[1], b.max[1].max(b.min[1] + 1e-3));
    let (near, far) = (b.max[2] + 1.0, b.min[2] - 1.0);
    // Reversed-Z like every frame: the nearest (largest z) has depth 1.
    let ortho = Mat4::from_cols(
        Vec4::new(1.0 / r, 0.0, 0.0, 0.0),
        Vec4::new(0.0, 2.0 / (top - bottom), 0.0, 0.0),
        Vec4::new(0.0, 0.0, 1.0 / (near - far), 0.0),
        Vec4::new(0.0, -(top + bottom) / (top - bottom), -far / (near - far), 1.0),
    );
    let frame = FrameUniform {
        view_proj: ortho.to_cols_array_2d(),
        sun: [0.0, 0.0, 1.0, 0.0],
        // Ambient 1, no sun: the model's own colours (the frame lights them).
        light: [1.0, 0.0, 1.0, 0.0],
        centre: [0.0; 4],
        eye_high: [0.0; 4],
        eye_low: [0.0; 4],
    };
    let frame_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("billboard bake frame"),
        contents: bytemuck::bytes_of(&frame),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("billboard bake"),
        layout,
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() }],
    });
    let identity = GpuInstance {
        pos: [0.0, 0.0, 0.0, 1.0],
        east: [1.0, 0.0, 0.0, 0.0],
        up: [0.0, 1.0, 0.0, 1.0],
        billboard: [0.0; 4],
    };
    let instance = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("billboard bake instance"),
        contents: bytemuck::bytes_of(&identity),
        usage: wgpu::BufferUsages::VERTEX,
    });
    let (w, h) = BILLBOARD_SIZE;
    for (pipeline, atlas) in images {
        let target = Target::new(device, w, h);
        target.run_clearing(gpu, "billboard bake", Some(wgpu::Color::TRANSPARENT), |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.set_vertex_buffer(0, model.vertices.slice(..));
            pass.set_vertex_buffer(1, instance.slice(..));
            pass.set_index_buffer(model.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..model.index_count, 0, 0..1);
        })?;
        let (rgba, _) = target.read_back(gpu)?;
        let mut level = premultiplied(&rgba);
        let (mut lw, mut lh) = (w, h);
        for mip in 0..MIPS {
            gpu.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: atlas,
                    mip_level: mip,
                    origin: wgpu::Origin3d { x: 0, y: 0, z: model.layer },
                    aspect: wgpu::TextureAspect::All,
                },
                &level,
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(lw * 4), rows_per_image: Some(lh) },
                wgpu::Extent3d { width: lw, height: lh, depth_or_array_layers: 1 },
            );
            level = half(&level, lw as usize, lh as usize);
            (lw, lh) = ((lw / 2).max(1), (lh / 2).max(1));
        }
    }
    Ok(())
}

/// Colour times alpha, so mips average what is seen, not the background.
fn premultiplied(rgba: &[u8]) -> Vec<u8> {
    rgba.chunks_exact(4)
        .flat_map(|p| {
            let a = u16::from(p[3]);
            [0, 1, 2].map(|c| ((u16::from(p[c]) * a + 127) / 255) as u8).into_iter().chain([p[3]])
        })
        .collect()
}

/// The next mip: each texel the mean of four (premultiplied, so colours
/// stay right), scaled up a quarter so a crown does not thin to nothing
/// far away under the alpha test.
fn half(level: &[u8], w: usize, h: usize) -> Vec<u8> {
    let (hw, hh) = ((w / 2).max(1), (h / 2).max(1));
    let mut out = vec![0u8; hw * hh * 4];
    for y in 0..hh {
        for x in 0..hw {
            for c in 0..4 {
                let mut sum = 0u32;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = ((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1));
                    sum += u32::from(level[(sy * w + sx) * 4 + c]);
                }
                out[(y * hw + x) * 4 + c] = (sum as f32 / 4.0 * 1.25).min(255.0).round() as u8;
            }
        }
    }
    out
}
