//! The passes a frame is drawn in, each in its own module, and what they
//! have cost. A renderer builds a pass (pipelines, buffers, textures) only
//! when the scene calls for it; the counters say which were built, how
//! often each ran and what it took.

pub mod atmosphere;
pub mod buildings;
pub mod casting;
pub mod fog;
pub mod instances;
pub mod overlay;
pub mod shadows;
pub mod terrain;
pub mod water;

use std::time::Instant;

use crate::target::{COLOR_FORMAT, DEPTH_FORMAT};

/// How a pass binds its small buffers (the frame's, its own parameters):
/// as read-only storage, never as uniform buffers. Mesa 22.3's lavapipe,
/// the software Vulkan reliefd renders with where there is no GPU,
/// "inlines" a uniform buffer's values into a shader with a branch or
/// loop bound decided by them alone: it compiles the shader again each
/// time such a pipeline or its bind group is bound, and never frees what
/// it compiled, so every frame kept megabytes for good. It never inlines
/// storage buffers, and they read the same everywhere else. The test below
/// checks that no shader declares a uniform buffer and that no Rust source
/// binds or makes one.
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

/// A lit pass's shader (terrain, buildings, instances): `shader` of its
/// source made to receive the shadows of a frame casting `cascades` maps,
/// or none (`shadows::receiving`).
pub fn lit_shader(device: &wgpu::Device, label: &str, source: &str, cascades: Option<u32>) -> wgpu::ShaderModule {
    shader(device, label, &shadows::receiving(source, cascades))
}

/// One pipeline of a lit pass, as both it and its shadow-receiving twin
/// are made: its label, its own bind group's layout (group 0), its stages
/// and vertex buffers.
pub struct LitPipeline<'a> {
    pub label: &'a str,
    pub group0: &'a wgpu::BindGroupLayout,
    pub stages: (&'a str, &'a str),
    pub buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
}

impl LitPipeline<'_> {
    /// The pipeline from `shader`; with `lookup` (the shadow cascades'
    /// layout, bound as group 1), the twin receiving shadows.
    pub fn build(
        &self,
        device: &wgpu::Device,
        shader: &wgpu::ShaderModule,
        lookup: Option<&wgpu::BindGroupLayout>,
    ) -> wgpu::RenderPipeline {
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(self.label),
            bind_group_layouts: &[Some(self.group0), lookup],
            immediate_size: 0,
        });
        pipeline(device, self.label, &layout, shader, self.stages, self.buffers)
    }
}

/// A lit pass's pipelines for frames that cast shadows: its shader built
/// again to receive the shadows of `cascades` maps (`shadows::receiving`),
/// the cascades' lookup bound as group 1. Made the first time a frame
/// casts shadows, and again when the cascade count changes; gone when the
/// scene casts none.
pub struct Receiving {
    cascades: u32,
    pipelines: Vec<wgpu::RenderPipeline>,
}

impl Receiving {
    /// Brings a pass's twins (`slot`) to `lookup` (the cascades' layout and
    /// count): kept while made for that count, else made anew from the
    /// pass's `source` and `pipelines`; none without a lookup.
    pub fn update(
        slot: &mut Option<Self>,
        device: &wgpu::Device,
        lookup: Option<(&wgpu::BindGroupLayout, u32)>,
        (label, source): (&str, &str),
        pipelines: &[LitPipeline<'_>],
    ) {
        let Some((lookup, cascades)) = lookup else {
            *slot = None;
            return;
        };
        if slot.as_ref().is_some_and(|r| r.cascades == cascades) {
            return;
        }
        let shader = lit_shader(device, label, source, Some(cascades));
        let pipelines = pipelines.iter().map(|p| p.build(device, &shader, Some(lookup))).collect();
        *slot = Some(Self { cascades, pipelines });
    }

    /// The pipelines a pass draws with: the twins in `slot`, with the
    /// cascades' bind group (`shadows`) set as group 1, when the frame
    /// casts shadows; else its `plain` ones.
    pub fn choose<'a, const N: usize>(
        slot: Option<&'a Self>,
        pass: &mut wgpu::RenderPass<'_>,
        shadows: Option<&wgpu::BindGroup>,
        plain: [&'a wgpu::RenderPipeline; N],
    ) -> [&'a wgpu::RenderPipeline; N] {
        match (shadows, slot) {
            (Some(lookup), Some(twins)) if twins.pipelines.len() == N => {
                pass.set_bind_group(1, lookup, &[]);
                std::array::from_fn(|i| &twins.pipelines[i])
            }
            _ => plain,
        }
    }
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

/// Terrain: the clipmap levels over the coarse base, coloured by the
/// colour layer, lit by the `lighting` effect.
pub const TERRAIN: &str = "terrain";
/// Buildings: the `buildings` layer's meshes, lifted onto the drawn
/// terrain. Built only for a scene with that layer.
pub const BUILDINGS: &str = "buildings";
/// Instances: the `instances` layer's models and billboards. Built only
/// for a scene with that layer.
pub const INSTANCES: &str = "instances";
/// Atmosphere: the `atmosphere` effect's sky and aerial perspective, laid
/// over everything drawn. Built only for a scene that declares it.
pub const ATMOSPHERE: &str = "atmosphere";
/// Fog: the `fog` effect, laid over everything drawn (and the atmosphere).
/// Built only for a scene that declares it.
pub const FOG: &str = "fog";
/// Shadows: the `shadows` effect, cascaded shadow maps drawn from the sun
/// (terrain, buildings and instance models cast) before the frame's
/// colour; the lit passes take the sunlight they hide from each pixel
/// they draw (timed in those passes). Built only for a scene that
/// declares it.
pub const SHADOWS: &str = "shadows";
/// Water: the `water` effect, the water layer drawn as a surface at its
/// level or on the terrain. Built only for a scene that declares it.
pub const WATER: &str = "water";
/// Every pass a renderer knows, in the order a frame runs them.
pub const ALL: &[&str] = &[SHADOWS, TERRAIN, BUILDINGS, INSTANCES, WATER, ATMOSPHERE, FOG];

/// One pass's record.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PassStats {
    pub name: &'static str,
    /// Its pipelines and buffers exist.
    pub built: bool,
    /// Frames it ran in.
    pub runs: u64,
    /// Wall time over those runs, milliseconds: preparing (tiles, uploads)
    /// and the device drawing it.
    pub total_ms: f64,
}

/// The record of every pass a renderer knows, built or not.
#[derive(Debug, Clone, PartialEq)]
pub struct PassCounters {
    stats: Vec<PassStats>,
}

impl Default for PassCounters {
    fn default() -> Self {
        Self { stats: ALL.iter().map(|&name| PassStats { name, ..PassStats::default() }).collect() }
    }
}

impl PassCounters {
    fn entry(&mut self, name: &'static str) -> &mut PassStats {
        let at = self.stats.iter().position(|s| s.name == name).unwrap_or_else(|| {
            self.stats.push(PassStats { name, ..PassStats::default() });
            self.stats.len() - 1
        });
        &mut self.stats[at]
    }

    /// A run of `name` that started at `started`; returns its milliseconds.
    pub fn ran(&mut self, name: &'static str, started: Instant) -> f64 {
        let ms = started.elapsed().as_secs_f64() * 1e3;
        self.add_run(name, ms);
        ms
    }

    /// A run of `name` that took `ms`.
    pub fn add_run(&mut self, name: &'static str, ms: f64) {
        let e = self.entry(name);
        e.runs += 1;
        e.total_ms += ms;
    }

    /// Whether `name` is built now.
    pub fn set_built(&mut self, name: &'static str, built: bool) {
        self.entry(name).built = built;
    }

    pub fn is_built(&self, name: &str) -> bool {
        self.stats.iter().any(|s| s.name == name && s.built)
    }

    pub fn stats(&self) -> &[PassStats] {
        &self.stats
    }
}

#[cfg(test)]
mod tests {
    use wgpu::naga;

    /// Every pass's shader put together as its pass does it.
    fn shaders() -> Vec<(String, String)> {
        let framed = |source: &str| format!("{}\n{source}", include_str!("frame.wgsl"));
        let fullscreen = super::overlay::fullscreen;
        let overlay = |own, source: &str| framed(&format!("{}\n{source}", fullscreen(own, 0)));
        let table = super::shadows::TABLE_VEC4S;
        let shadowed = |own, cascades, source: &str| {
            framed(&format!("{}\n{}\n{source}", fullscreen(own, table), super::shadows::lookup(cascades)))
        };
        // The lit passes without shadows and receiving them from 1 and 4 cascades.
        let lit = |source: &str, cascades| framed(&super::shadows::receiving(source, cascades));
        let terrain = format!("const COLOR_DETAIL: i32 = 2;\n{}", include_str!("terrain/terrain.wgsl"));
        let mut all = Vec::new();
        for (cascades, kind) in [(None, ""), (Some(1), " receiving 1 cascade"), (Some(4), " receiving 4 cascades")] {
            all.push(("terrain", kind, lit(&terrain, cascades)));
            all.push(("buildings", kind, lit(include_str!("buildings/buildings.wgsl"), cascades)));
            all.push(("instances", kind, lit(include_str!("instances/instances.wgsl"), cascades)));
        }
        let mut all: Vec<(String, String)> =
            all.into_iter().map(|(name, kind, s)| (format!("{name}{kind}"), s)).collect();
        all.extend([
            ("atmosphere".to_owned(), shadowed(8, 4, include_str!("atmosphere/atmosphere.wgsl"))),
            ("atmosphere over 1 cascade".to_owned(), shadowed(8, 1, include_str!("atmosphere/atmosphere.wgsl"))),
            (
                "atmosphere composite".to_owned(),
                format!("{}\n{}", fullscreen(0, 0), include_str!("atmosphere/composite.wgsl")),
            ),
            ("water".to_owned(), overlay(11, include_str!("water/water.wgsl"))),
            ("fog".to_owned(), overlay(7, include_str!("fog/fog.wgsl"))),
        ]);
        all
    }

    /// Guards the frame time on lavapipe, which loads a storage buffer one
    /// lane at a time: no fragment stage reads one (`params_binding`); what
    /// a pixel needs comes from its vertex stage, flat.
    #[test]
    fn no_fragment_stage_reads_a_storage_buffer() -> Result<(), String> {
        for (name, source) in shaders() {
            let module = naga::front::wgsl::parse_str(&source)
                .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
            let info =
                naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
                    .validate(&module)
                    .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
            for (i, entry) in module.entry_points.iter().enumerate() {
                if entry.stage != naga::ShaderStage::Fragment {
                    continue;
                }
                let uses = info.get_entry_point(i);
                for (handle, global) in module.global_variables.iter() {
                    let storage = matches!(global.space, naga::AddressSpace::Storage { .. });
                    if storage && uses[handle].contains(naga::valid::GlobalUse::READ) {
                        return Err(format!(
                            "shader '{name}': fragment stage '{}' reads storage buffer '{}'",
                            entry.name,
                            global.name.clone().unwrap_or_default()
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Every `.wgsl` file under `dir`, a pass added later's included.
    /// Every file under `dir` whose extension is `ext`.
    fn files_ending(dir: &std::path::Path, ext: &str, found: &mut Vec<std::path::PathBuf>) -> std::io::Result<()> {
        for entry in std::fs::read_dir(dir)? {
            let path = entry?.path();
            if path.is_dir() {
                files_ending(&path, ext, found)?;
            } else if path.extension().is_some_and(|e| e == ext) {
                found.push(path);
            }
        }
        Ok(())
    }

    /// Guards the daemon's memory on lavapipe: a shader that reads a
    /// uniform buffer is compiled again at every bind and never freed
    /// there (`params_binding`). Every shader parses and validates, and
    /// none declares a uniform buffer.
    #[test]
    fn no_shader_reads_a_uniform_buffer() -> Result<(), String> {
        for (name, source) in shaders() {
            let module = naga::front::wgsl::parse_str(&source)
                .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
                .validate(&module)
                .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
            let uniforms: Vec<String> = module
                .global_variables
                .iter()
                .filter(|(_, g)| g.space == naga::AddressSpace::Uniform)
                .map(|(_, g)| g.name.clone().unwrap_or_default())
                .collect();
            if !uniforms.is_empty() {
                return Err(format!(
                    "shader '{name}' reads uniform buffers {uniforms:?}: bind them as read-only storage"
                ));
            }
        }
        let mut files = Vec::new();
        files_ending(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), "wgsl", &mut files)
            .map_err(|e| format!("cannot list the shaders: {e}"))?;
        for path in &files {
            let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            let squeezed: String = text.chars().filter(|c| !c.is_whitespace()).collect();
            if squeezed.contains("var<uniform>") {
                return Err(format!("{} declares a uniform buffer: bind it as read-only storage", path.display()));
            }
        }
        // Nor a binding or a buffer made as one in the Rust sources (this
        // file names them only to forbid them).
        let mut sources = Vec::new();
        files_ending(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), "rs", &mut sources)
            .map_err(|e| format!("cannot list the sources: {e}"))?;
        let forbidden = [concat!("BufferBindingType::", "Uniform"), concat!("BufferUsages::", "UNIFORM")];
        for path in &sources {
            let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            if let Some(what) = forbidden.iter().find(|f| text.contains(**f)) {
                return Err(format!("{} uses {what}: bind it as read-only storage", path.display()));
            }
        }
        if files.len() < 10 {
            return Err(format!("found only {} shaders under src/", files.len()));
        }
        Ok(())
    }
}
