//! The `fog` effect: exponential height fog laid over the drawn frame by
//! one full-screen pass that reads the depth buffer (`fog.wgsl` has the
//! model). Built only for a scene that declares fog; independent of any
//! atmosphere.

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Mat4};
use wgpu::util::DeviceExt;

/// Height fog: density at the base height, how fast it thins upwards, and
/// its colour (straight RGB, 0..1) in full daylight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fog {
    /// Extinction per metre at `base_m` (visibility is about 3.9 / density).
    pub density_per_m: f64,
    /// The height over which the density falls by e.
    pub falloff_m: f64,
    /// The height (above the datum) where the density is `density_per_m`.
    pub base_m: f64,
    pub color: [f64; 3],
}

impl Fog {
    /// A light haze: 13 km visibility at sea level, thinning by e every km.
    pub const DEFAULT: Self = Self { density_per_m: 3.0e-4, falloff_m: 1000.0, base_m: 0.0, color: [0.78, 0.80, 0.83] };

    /// Each value in its range, or the field and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(self.density_per_m.is_finite() && (0.0..=1.0).contains(&self.density_per_m)) {
            return Err(("density", format!("{} is not from 0 to 1 per metre", self.density_per_m)));
        }
        if !(self.falloff_m.is_finite() && (1.0..=1.0e6).contains(&self.falloff_m)) {
            return Err(("falloff_m", format!("{} is not from 1 to 1,000,000 m", self.falloff_m)));
        }
        if !(self.base_m.is_finite() && self.base_m.abs() <= 1.0e5) {
            return Err(("base_m", format!("{} is not within 100 km of the datum", self.base_m)));
        }
        Ok(())
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct FogUniform {
    inv_view_proj: [[f32; 4]; 4],
    up: [f32; 4],
    params: [f32; 4],
    color: [f32; 4],
}

/// The fog pass's pipeline and uniform.
pub struct FogPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
}

/// What a frame's fog needs besides the settings: where the eye is.
pub struct FogView {
    /// The eye-relative view-projection the frame was drawn with.
    pub view_proj: Mat4,
    /// Up at the eye, world axes.
    pub up: DVec3,
    /// The eye's height above the datum, metres.
    pub eye_height_m: f64,
    /// The sun's daylight, 0 (night) to 1: the fog is lit by it.
    pub daylight: f64,
}

impl FogPass {
    pub fn new(device: &wgpu::Device, frame_buffer: &wgpu::Buffer) -> Self {
        let shader = super::shader(device, "fog", include_str!("fog.wgsl"));
        let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None };
        let uniform = |min| wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: wgpu::BufferSize::new(min),
        };
        let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("fog"),
            entries: &[
                entry(0, stages, uniform(frame_buffer.size())),
                entry(1, wgpu::ShaderStages::FRAGMENT, uniform(size_of::<FogUniform>() as u64)),
                entry(
                    2,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("fog"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = super::overlay_pipeline(device, "fog", &pipeline_layout, &shader, ("vs_fog", "fs_fog"));
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("fog"),
            contents: bytemuck::bytes_of(&FogUniform::zeroed()),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        Self { pipeline, layout, uniform }
    }

    /// The frame's fog uniform written, and the bind group over this
    /// frame's depth.
    pub fn prepare(
        &self,
        gpu: &crate::gpu::Gpu,
        frame_buffer: &wgpu::Buffer,
        depth: &wgpu::TextureView,
        fog: &Fog,
        at: &FogView,
    ) -> wgpu::BindGroup {
        let light = (0.08 + 0.92 * at.daylight) as f32;
        let u = FogUniform {
            inv_view_proj: at.view_proj.inverse().to_cols_array_2d(),
            up: [at.up.x as f32, at.up.y as f32, at.up.z as f32, at.eye_height_m as f32],
            params: [fog.density_per_m as f32, fog.falloff_m as f32, fog.base_m as f32, 0.0],
            color: [fog.color[0] as f32 * light, fog.color[1] as f32 * light, fog.color[2] as f32 * light, 1.0],
        };
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&u));
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("fog"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(depth) },
            ],
        })
    }

    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>, bind_group: &wgpu::BindGroup) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
