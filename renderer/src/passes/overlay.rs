//! What the full-screen effect passes share: a pipeline laid over the
//! frame (blended by its alpha, no depth attachment), and one bind group
//! of the frame uniform, the effect's own uniform and the frame's depth.
//!
//! The effect's uniform (and a second group's table, the shadow cascades)
//! reaches the fragments as flat inputs: the vertex stage reads it for the
//! triangle's three corners and every pixel gets it from the triangle's
//! setup. A fragment shader that read it from its buffer would load it
//! again in every pixel, and lavapipe loads a storage buffer one lane at a
//! time (with the Eye's matrix, 46 of the fog's 92 ms a frame here).

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Mat4};
use wgpu::util::DeviceExt;

use crate::gpu::Gpu;

/// One full-screen effect: its pipeline and uniform.
pub struct Overlay {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
}

impl Overlay {
    /// The effect `label` drawn by `source` (after `frame.wgsl` and
    /// `fullscreen`): fragment entry `fs` taking an `OverlayIn`, its
    /// uniform a `U` at binding 1 (read as `own_of(in)`) and the depth at
    /// binding 2, drawn into `target` (the frame's colour with a blend that
    /// lays it over, or a texture of the effect's own); `group1`, when
    /// given, the layout of a second bind group (the shadow cascades) and
    /// the vec4s of its table at binding 0 (`table_of(in)`), if any.
    pub fn new<U: Pod + Default>(
        device: &wgpu::Device,
        frame_buffer: &wgpu::Buffer,
        (label, source): (&str, &str),
        target: wgpu::ColorTargetState,
        group1: Option<(&wgpu::BindGroupLayout, usize)>,
    ) -> Self {
        let own = size_of::<U>() / size_of::<[f32; 4]>();
        let table = group1.map_or(0, |(_, n)| n);
        let shader = crate::passes::pipeline::shader(device, label, &format!("{}\n{source}", fullscreen(own, table)));
        let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None };
        let uniform = |min| crate::passes::pipeline::params_binding(wgpu::BufferSize::new(min));
        let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &[
                entry(0, stages, uniform(frame_buffer.size())),
                entry(1, wgpu::ShaderStages::VERTEX, uniform(size_of::<U>() as u64)),
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
            label: Some(label),
            bind_group_layouts: &[Some(&layout), group1.map(|(layout, _)| layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_fullscreen"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(target)],
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::bytes_of(&U::default()),
            usage: crate::passes::pipeline::PARAMS_USAGE,
        });
        Self { pipeline, layout, uniform }
    }

    /// Writes this frame's uniform; the bind group over this frame's depth.
    pub fn prepare<U: Pod>(
        &self,
        gpu: &Gpu,
        frame_buffer: &wgpu::Buffer,
        depth: &wgpu::TextureView,
        uniform: &U,
    ) -> wgpu::BindGroup {
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(uniform));
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(depth) },
            ],
        })
    }

    /// Draws the effect with `bind_group`, and `group1` where it was
    /// built with a second group.
    pub fn record(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        bind_group: &wgpu::BindGroup,
        group1: Option<&wgpu::BindGroup>,
    ) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        if let Some(group) = group1 {
            pass.set_bind_group(1, group, &[]);
        }
        pass.draw(0..3, 0..1);
    }
}

/// Laid over the frame's colour with `blend`.
pub fn over_frame(blend: wgpu::BlendState) -> wgpu::ColorTargetState {
    wgpu::ColorTargetState {
        format: crate::target::COLOR_FORMAT,
        blend: Some(blend),
        write_mask: wgpu::ColorWrites::COLOR,
    }
}

/// Where the frame's eye is, as every full-screen effect reads it (the
/// first member of each one's uniform): the inverse of the eye-relative
/// view-projection the frame was drawn with, up at the eye (xyz, world
/// axes) and the eye's height above the datum (w, metres). Worked out once
/// per frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
pub struct Eye {
    inv_view_proj: [[f32; 4]; 4],
    up: [f32; 4],
}

impl Eye {
    /// The eye's height above the datum, metres.
    pub fn height_m(&self) -> f64 {
        f64::from(self.up[3])
    }

    pub fn new(view_proj: Mat4, up: DVec3, height_m: f64) -> Self {
        Self {
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            up: [up.x as f32, up.y as f32, up.z as f32, height_m as f32],
        }
    }
}

/// The shared part of every full-screen pass: one triangle over the whole
/// screen whose corners carry the effect's uniform (`own` vec4s) and a
/// second group's table (`table` vec4s) to every pixel as flat inputs, the
/// eye, and a pixel's view ray.
pub fn fullscreen(own: usize, table: usize) -> String {
    use std::fmt::Write;
    let mut s = String::from("struct OverlayIn {\n    @builtin(position) position: vec4<f32>,\n");
    for i in 0..own {
        let _ = writeln!(s, "    @location({i}) @interpolate(flat) own{i}: vec4<f32>,");
    }
    for i in 0..table {
        let _ = writeln!(s, "    @location({}) @interpolate(flat) table{i}: vec4<f32>,", own + i);
    }
    s.push_str("}\n");
    if own > 0 {
        let _ = writeln!(s, "@group(0) @binding(1) var<storage, read> overlay_own: array<vec4<f32>, {own}>;");
    }
    if table > 0 {
        let _ = writeln!(s, "@group(1) @binding(0) var<storage, read> overlay_table: array<vec4<f32>, {table}>;");
    }
    s.push_str("@vertex\nfn vs_fullscreen(@builtin(vertex_index) vi: u32) -> OverlayIn {\n    var out: OverlayIn;\n");
    s.push_str("    out.position = fullscreen_corner(vi);\n");
    for i in 0..own {
        let _ = writeln!(s, "    out.own{i} = overlay_own[{i}];");
    }
    for i in 0..table {
        let _ = writeln!(s, "    out.table{i} = overlay_table[{i}];");
    }
    s.push_str("    return out;\n}\n");
    let list = |prefix: &str, n: usize| (0..n).map(|i| format!("input.{prefix}{i}")).collect::<Vec<_>>().join(", ");
    if own > 0 {
        let _ = writeln!(
            s,
            "fn own_of(input: OverlayIn) -> array<vec4<f32>, {own}> {{ return array<vec4<f32>, {own}>({}); }}",
            list("own", own)
        );
    }
    if table > 0 {
        let _ = writeln!(
            s,
            "fn table_of(input: OverlayIn) -> array<vec4<f32>, {table}> {{ return array<vec4<f32>, {table}>({}); }}",
            list("table", table)
        );
    }
    format!("{s}{FULLSCREEN}")
}

/// The eye, the full-screen triangle's corners, and a pixel's view ray.
pub const FULLSCREEN: &str = r"
struct Eye {
    inv_view_proj: mat4x4<f32>,
    up: vec4<f32>,
}

// The eye from the first five vec4s of `v` (an overlay's own inputs).
fn eye_of(v0: vec4<f32>, v1: vec4<f32>, v2: vec4<f32>, v3: vec4<f32>, v4: vec4<f32>) -> Eye {
    return Eye(mat4x4<f32>(v0, v1, v2, v3), v4);
}

fn fullscreen_corner(vi: u32) -> vec4<f32> {
    let x = f32(i32(vi & 1u) * 4 - 1);
    let y = f32(i32(vi >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

// Normalised device coordinates of a fragment in a target `size` pixels.
fn ndc_of(frag: vec2<f32>, size: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(frag.x / size.x * 2.0 - 1.0, 1.0 - frag.y / size.y * 2.0);
}

// The point at `ndc` and depth `z` through `inv` (an inverse
// view-projection), relative to the eye.
fn unproject(inv: mat4x4<f32>, ndc: vec2<f32>, z: f32) -> vec3<f32> {
    let p = inv * vec4<f32>(ndc, z, 1.0);
    return p.xyz / p.w;
}

// The view ray through `ndc` where the frame's depth is `z`: its direction
// (xyz) and the distance to what was drawn there (w), `far` for the sky.
fn view_ray(inv: mat4x4<f32>, ndc: vec2<f32>, z: f32, far: f32) -> vec4<f32> {
    if z > 0.0 {
        let p = unproject(inv, ndc, z);
        let d = length(p);
        return vec4<f32>(p / d, d);
    }
    return vec4<f32>(normalize(unproject(inv, ndc, 1.0)), far);
}
";
