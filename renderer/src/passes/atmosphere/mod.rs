//! The `atmosphere` effect: Rayleigh and Mie single scattering over the
//! drawn frame, giving the sky and aerial perspective on terrain and
//! objects alike (`atmosphere.wgsl` has the model). One full-screen pass
//! that reads the depth; built only for a scene that declares it.

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use wgpu::util::DeviceExt;

use super::overlay::{Eye, Overlay, fullscreen, over_frame};
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::target::Target;

/// The atmosphere's knobs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Atmosphere {
    /// Where the atmosphere ends, metres above the ground.
    pub top_m: f64,
    /// Samples along each view ray (`atmosphere_steps`): an accuracy knob.
    pub steps: u32,
    /// Frame pixels to a side of each ray marched (`atmosphere_downsample`;
    /// the scattering between is interpolated): an accuracy knob.
    pub downsample: u32,
}

impl Atmosphere {
    /// Clasen found 12-36 steps enough, fewer visibly wrong at dawn.
    pub const DEFAULT_STEPS: u32 = 16;
    /// One ray for each 4 x 4 pixels: in the `render` bench's table (against
    /// 256 steps at full resolution) the default steps' RMS error (0-255)
    /// goes from 0.3 to 0.6, the largest errors (at silhouettes against
    /// the sky) from 2 to 23-69 levels, at an eighth of the cost.
    pub const DEFAULT_DOWNSAMPLE: u32 = 4;
    pub const DEFAULT: Self =
        Self { top_m: 50_000.0, steps: Self::DEFAULT_STEPS, downsample: Self::DEFAULT_DOWNSAMPLE };
    /// The most steps a frame may ask for.
    pub const MAX_STEPS: u32 = 256;
    /// The coarsest downsampling a frame may ask for.
    pub const MAX_DOWNSAMPLE: u32 = 8;

    /// Each value in its range, or the field and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(self.top_m.is_finite() && (1_000.0..=200_000.0).contains(&self.top_m)) {
            return Err(("top_m", format!("{} is not from 1,000 to 200,000 m", self.top_m)));
        }
        if !(1..=Self::MAX_STEPS).contains(&self.steps) {
            return Err(("atmosphere_steps", format!("{} is not from 1 to {}", self.steps, Self::MAX_STEPS)));
        }
        if !(1..=Self::MAX_DOWNSAMPLE).contains(&self.downsample) {
            return Err((
                "atmosphere_downsample",
                format!("{} is not from 1 to {}", self.downsample, Self::MAX_DOWNSAMPLE),
            ));
        }
        Ok(())
    }
}

/// Sunlight's intensity in the scattering sums (O'Neil's E_sun).
const SUN_INTENSITY: f32 = 20.0;
/// Exposure of the tone map `1 - exp(-light * exposure)`.
const EXPOSURE: f32 = 1.0;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
struct AtmosphereUniform {
    eye: Eye,
    sun: [f32; 4],
    params: [f32; 4],
    frame_size: [f32; 4],
}

/// Light (tone-mapped to 0..1) and one less the transmittance, as the
/// scattering computes them: 8 bits each, as the frame has, since
/// lavapipe filters 8-bit texels for the composite at 1.5-2.5 ms less
/// than half floats.
const SCATTERED_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// The atmosphere pass: the scattering computed into a texture of its own
/// (`downsample` frame pixels to a side of each texel), then laid over the
/// frame, interpolated.
pub struct AtmospherePass {
    scatter: Overlay,
    /// Bytes the scattering's texture holds.
    scattered_bytes: u64,
    composite: wgpu::RenderPipeline,
    composite_layout: wgpu::BindGroupLayout,
    composite_uniform: wgpu::Buffer,
    sampler: wgpu::Sampler,
    /// The scattering's texture, kept while its size stays.
    scattered: Option<(wgpu::Extent3d, wgpu::TextureView)>,
    /// Built to read the shadow cascades (this many): the sun's light is
    /// taken from the air in shadow, so a hidden sun does not glow.
    pub shadowed: Option<u32>,
}

impl AtmospherePass {
    /// What the pass holds, bytes: its scattering texture.
    pub fn held_bytes(&self) -> u64 {
        self.scattered_bytes
    }
}

/// What a frame's atmosphere needs besides its knobs.
pub struct AtmosphereView<'a> {
    /// The frame's eye (its height is above the ground the atmosphere sits on).
    pub eye: Eye,
    /// The ground's radius under the eye (None over flat ground).
    pub ground_radius_m: Option<f64>,
    /// Towards the sun, world axes.
    pub sun: DVec3,
    /// The shadow cascades' bind group, for a pass built `shadowed`.
    pub shadows: Option<&'a wgpu::BindGroup>,
}

/// The sun's visibility where no shadows are cast: everywhere.
const SUN_EVERYWHERE: &str =
    "fn begin_shadows(input: OverlayIn) {}\nfn sun_visible_texel(p: vec3<f32>) -> f32 { return 1.0; }";

impl AtmospherePass {
    /// The flat inputs of the pass over shadow maps: its own uniform and
    /// the cascades' table (`overlay`).
    pub const SHADOWED_INPUTS: usize =
        size_of::<AtmosphereUniform>() / size_of::<[f32; 4]>() + super::shadows::TABLE_VEC4S;

    /// The pass, reading the shadow cascades through `shadows` (their
    /// bind group's layout and count) when the scene casts shadows.
    pub fn new(
        device: &wgpu::Device,
        frame_buffer: &wgpu::Buffer,
        shadows: Option<(&wgpu::BindGroupLayout, u32)>,
    ) -> Self {
        let visibility = shadows.map_or_else(|| SUN_EVERYWHERE.to_owned(), |(_, n)| super::shadows::lookup(n));
        let shadowed = shadows.map(|(_, n)| n);
        let source = format!("{visibility}\n{}", include_str!("atmosphere.wgsl"));
        let target =
            wgpu::ColorTargetState { format: SCATTERED_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL };
        let shadows = shadows.map(|(layout, _)| (layout, super::shadows::TABLE_VEC4S));
        let scatter = Overlay::new::<AtmosphereUniform>(device, frame_buffer, ("atmosphere", &source), target, shadows);
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("atmosphere composite"),
            source: wgpu::ShaderSource::Wgsl(
                format!("{}\n{}", fullscreen(0, 0), include_str!("composite.wgsl")).into(),
            ),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty,
            count: None,
        };
        let composite_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("atmosphere composite"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                entry(1, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
                // Read by the vertex stage, handed to the pixels flat.
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: crate::passes::pipeline::params_binding(None),
                    count: None,
                },
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("atmosphere composite"),
            bind_group_layouts: &[Some(&composite_layout)],
            immediate_size: 0,
        });
        // In-scattered light added, what was drawn dimmed by the transmittance.
        let blend = wgpu::BlendState {
            color: wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::One,
                dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                operation: wgpu::BlendOperation::Add,
            },
            alpha: wgpu::BlendComponent::OVER,
        };
        let composite = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("atmosphere composite"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_composite"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_composite"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(over_frame(blend))],
            }),
            multiview_mask: None,
            cache: None,
        });
        let composite_uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("atmosphere composite"),
            contents: bytemuck::bytes_of(&[1.0f32; 4]),
            usage: crate::passes::pipeline::PARAMS_USAGE,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("atmosphere composite"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Self {
            scatter,
            scattered_bytes: 0,
            composite,
            composite_layout,
            composite_uniform,
            sampler,
            scattered: None,
            shadowed,
        }
    }

    /// Computes the scattering for this frame into the pass's own texture,
    /// then lays it over `target`'s colour.
    pub fn run(
        &mut self,
        gpu: &Gpu,
        frame_buffer: &wgpu::Buffer,
        target: &Target,
        atmosphere: &Atmosphere,
        at: &AtmosphereView<'_>,
    ) -> Result<(), RenderError> {
        let d = atmosphere.downsample.max(1);
        let size = wgpu::Extent3d {
            width: target.width.div_ceil(d),
            height: target.height.div_ceil(d),
            depth_or_array_layers: 1,
        };
        if self.scattered.as_ref().is_none_or(|(s, _)| *s != size) {
            let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("atmosphere scattering"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: SCATTERED_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            });
            self.scattered_bytes = crate::passes::pipeline::texture_bytes(&texture);
            self.scattered = Some((size, texture.create_view(&wgpu::TextureViewDescriptor::default())));
        }
        let Some((_, scattered)) = &self.scattered else { return Ok(()) };
        let u = AtmosphereUniform {
            eye: at.eye,
            sun: [at.sun.x as f32, at.sun.y as f32, at.sun.z as f32, SUN_INTENSITY],
            params: [
                at.ground_radius_m.unwrap_or(0.0) as f32,
                atmosphere.top_m as f32,
                atmosphere.steps as f32,
                EXPOSURE,
            ],
            frame_size: [d as f32, target.width as f32, target.height as f32, 0.0],
        };
        let bind_group = self.scatter.prepare(gpu, frame_buffer, target.depth_view(), &u);
        let mut encoder =
            gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("atmosphere") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("atmosphere scattering"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: scattered,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            self.scatter.record(&mut pass, &bind_group, at.shadows);
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.queue.write_buffer(&self.composite_uniform, 0, bytemuck::bytes_of(&[d as f32, 0.0, 0.0, 0.0]));
        let composite = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("atmosphere composite"),
            layout: &self.composite_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(scattered) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&self.sampler) },
                wgpu::BindGroupEntry { binding: 2, resource: self.composite_uniform.as_entire_binding() },
            ],
        });
        target.run_overlay(gpu, "atmosphere", |pass| {
            pass.set_pipeline(&self.composite);
            pass.set_bind_group(0, &composite, &[]);
            pass.draw(0..3, 0..1);
        })
    }
}
