//! What every pass builds its pipelines from: how small buffers are bound
//! (read-only storage, never uniform buffers), reversed-Z pipelines and
//! their depth-only twins, sampled textures, a pass's shader over the
//! frame's prelude, and the digest passes key kept work by.

pub use crate::target::texture_bytes;
use crate::target::{COLOR_FORMAT, DEPTH_FORMAT};

/// How a pass binds its small buffers (the frame's, its own parameters):
/// as read-only storage, never as uniform buffers. Mesa 22.3's lavapipe,
/// the software Vulkan reliefd renders with where there is no GPU,
/// "inlines" a uniform buffer's values into a shader with a branch or
/// loop bound decided by them alone: it compiles the shader again each
/// time such a pipeline or its bind group is bound, and never frees what
/// it compiled, so every frame kept megabytes for good. It never inlines
/// storage buffers, and they read the same everywhere else. The shaders'
/// test (`shaders.rs`) checks that no shader declares a uniform buffer and
/// that no Rust source binds or makes one.
///
/// The price: that lavapipe loads a storage buffer one lane at a time, so
/// fragments read none. What a pixel needs of them comes from its vertex
/// stage as flat inputs: the sun and light terms (`frame.wgsl`'s
/// `sunlight`), and a full-screen pass's whole uniform and the shadow
/// cascades (`overlay::fullscreen`).
pub fn params_binding(min_binding_size: Option<wgpu::BufferSize>) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size,
    }
}

/// The usage of a buffer bound by [`params_binding`] and written by the
/// CPU.
pub const PARAMS_USAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_DST);

/// A pass's pipeline drawing into the frame's target: reversed-Z depth
/// (nearer is greater), no culling, `vs` and `fs` of `shader`.
pub fn pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    shader: &wgpu::ShaderModule,
    (vs, fs): (&str, &str),
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
) -> wgpu::RenderPipeline {
    reversed_z(device, label, (layout, shader), (vs, Some(fs)), buffers)
}

/// The attributes of a vertex of four vec4s: position (high and low
/// parts), normal and colour, as the terrain's base and the buildings have.
const VEC4_ATTRIBUTES: [wgpu::VertexAttribute; 4] =
    wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4, 3 => Float32x4];
/// The vertex buffer of vertices of four vec4s.
pub const VEC4_VERTICES: [Option<wgpu::VertexBufferLayout<'static>>; 1] = [Some(wgpu::VertexBufferLayout {
    array_stride: 4 * 16,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &VEC4_ATTRIBUTES,
})];

/// The depth-only twin of a pass's pipeline that draws what it draws into
/// a shadow map: the same layout and vertex stage `vs` of `shader`, no
/// fragment stage, reversed-Z depth (nearer the sun is greater).
pub fn caster_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    shader: &wgpu::ShaderModule,
    vs: &str,
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
) -> wgpu::RenderPipeline {
    reversed_z(device, label, (layout, shader), (vs, None), buffers)
}

/// A pipeline with reversed-Z depth and no culling: `vs`, and `fs` into
/// the frame's colour when given (else depth only).
fn reversed_z(
    device: &wgpu::Device,
    label: &str,
    (layout, shader): (&wgpu::PipelineLayout, &wgpu::ShaderModule),
    (vs, fs): (&str, Option<&str>),
    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
) -> wgpu::RenderPipeline {
    let targets = [Some(COLOR_FORMAT.into())];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some(vs),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers,
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: fs.map(|fs| wgpu::FragmentState {
            module: shader,
            entry_point: Some(fs),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            targets: &targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A square texture `side` texels a side with `layers` layers, sampled by
/// a pass and written from the CPU.
pub fn sampled_texture(
    device: &wgpu::Device,
    label: &str,
    side: u32,
    layers: u32,
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width: side, height: side, depth_or_array_layers: layers },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// A pass's shader: the frame's uniform and lighting (`frame.wgsl`), then
/// the pass's own source.
pub fn shader(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    let text = format!("{}\n{source}", include_str!("frame.wgsl"));
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(text.into()),
    })
}

/// A 64-bit digest of what a pass drew, for telling whether two frames
/// drew the same (a collision would keep a stale shadow map one frame:
/// one in 2^64).
pub fn key_of(value: &impl std::hash::Hash) -> u64 {
    use std::hash::Hasher;
    let mut hasher = std::hash::DefaultHasher::new();
    value.hash(&mut hasher);
    hasher.finish()
}
