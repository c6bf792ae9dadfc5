//! The `shadows` effect: cascaded shadow maps from the sun. The view is
//! split by distance (`cascades.rs`); each slice's box, seen from the sun,
//! gets a depth map into which the terrain's levels, the buildings and the
//! instances' models are drawn by depth-only twins of their own pipelines
//! (the frame uniform carrying the cascade's matrix), each through the
//! [`ShadowCaster`] trait (`casting.rs`): this pass knows no other pass.
//! A map is kept, not drawn again, while its cascade and everything drawn
//! into it are unchanged (a still camera under a still sun); where the
//! casters changed in part (an edit), only the texels their changed areas
//! cover are cleared and drawn again, under a scissor (`regions.rs`). The
//! maps are drawn before the frame's colour: the lit passes, built again
//! to receive them (`receiving`, `receive.wgsl`), take from each pixel they draw the
//! sunlight the maps say is hidden, and the atmosphere, when declared,
//! reads the same maps for its in-scattering (`lookup`, `air.wgsl`).
//! Built only for a scene that declares it.

pub mod cascades;

mod regions;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use wgpu::util::DeviceExt;

use self::regions::TexelRect;
use super::casting::{CastInto, Changes, ShadowCaster};
use crate::camera::View;
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::target::{DEPTH_FORMAT, wait};
use crate::uniforms::FrameUniform;

/// The shadows' knobs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shadows {
    /// Maps the view is split into by distance (`shadow_cascades`): an
    /// accuracy knob.
    pub cascades: u32,
    /// Texels to a side of each map (`shadow_map_size`): an accuracy knob.
    pub map_size: u32,
    /// How far from the eye shadows are cast, metres (`distance_m`).
    pub distance_m: f64,
}

impl Shadows {
    pub const MAX_CASCADES: u32 = 4;
    /// Two maps of 1,024: in the `shadows` bench (against a ray-cast) 0.2%
    /// of the ground misclassified, against 0.1% for three of 2,048 at
    /// half again the cost on lavapipe.
    pub const DEFAULT: Self = Self { cascades: 2, map_size: 1024, distance_m: 20_000.0 };

    /// Each value in its range, or the field and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(1..=Self::MAX_CASCADES).contains(&self.cascades) {
            return Err(("shadow_cascades", format!("{} is not from 1 to {}", self.cascades, Self::MAX_CASCADES)));
        }
        if !(256..=8192).contains(&self.map_size) || !self.map_size.is_power_of_two() {
            return Err(("shadow_map_size", format!("{} is not a power of two from 256 to 8192", self.map_size)));
        }
        // At most a quarter of a gibibyte of maps (4 x 4,096^2 x 4 bytes).
        if u64::from(self.cascades) * u64::from(self.map_size).pow(2) > 4 * 4096 * 4096 {
            return Err((
                "shadow_map_size",
                format!("{} maps of {} texels are more than 4 of 4,096", self.cascades, self.map_size),
            ));
        }
        if !(self.distance_m.is_finite() && (100.0..=1_000_000.0).contains(&self.distance_m)) {
            return Err(("distance_m", format!("{} is not from 100 to 1,000,000 m", self.distance_m)));
        }
        Ok(())
    }
}

/// The lookup a full-screen pass reading the maps prepends (group 1, the
/// table among its flat inputs), for maps of `cascades` (the count it
/// places points in): the atmosphere's.
pub fn lookup(cascades: u32) -> String {
    format!("const CASCADES: u32 = {cascades}u;\n{}\n{}", include_str!("lookup.wgsl"), include_str!("air.wgsl"))
}

/// A lit pass's shader `source` made to receive the shadows of a frame
/// casting `cascades` maps, or none: the lookup (`receive.wgsl`, group 1)
/// prepended, and the source's three lines that carry a point's place in
/// the cascades from its vertex to its pixels written out for that many:
/// `#sun_at_fields L` (the vertex output's fields, from location L),
/// `#sun_at_out P N` (placing point P with normal N, into `out`) and
/// `#sun_at_in` (`let at`, the places from `in`, for `sunlit`). Without
/// shadows the fields are not there at all: unread outputs still cost
/// lavapipe's terrain pass 3-6 ms.
pub fn receiving(source: &str, cascades: Option<u32>) -> String {
    use std::fmt::Write;
    let n = cascades.unwrap_or(0);
    let mut out = match cascades {
        Some(n) => {
            format!("const CASCADES: u32 = {n}u;\n{}\n{}\n", include_str!("lookup.wgsl"), include_str!("receive.wgsl"))
        }
        None => format!("{UNSHADOWED}\n"),
    };
    for line in source.lines() {
        let indent = &line[..line.len() - line.trim_start().len()];
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["#sun_at_fields", first] => {
                let first: u32 = first.parse().unwrap_or(0);
                for i in 0..n {
                    let _ = writeln!(out, "{indent}@location({}) sun_at{i}: vec4<f32>,", first + i);
                }
            }
            ["#sun_at_out", point, normal] if n > 0 => {
                let _ = writeln!(out, "{indent}let sun_at = sun_coords({point}, {normal});");
                for i in 0..n {
                    let _ = writeln!(out, "{indent}out.sun_at{i} = sun_at[{i}];");
                }
            }
            ["#sun_at_out", ..] => {}
            ["#sun_at_in"] => {
                let places: Vec<String> = (0..Shadows::MAX_CASCADES)
                    .map(|i| if i < n { format!("in.sun_at{i}") } else { "vec4<f32>(0.0)".to_owned() })
                    .collect();
                let _ = writeln!(out, "{indent}let at = array<vec4<f32>, 4>({});", places.join(", "));
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    out
}

/// What a lit pass prepends without shadows: the sunlight whole.
const UNSHADOWED: &str = "fn sunlit(sun: vec4<f32>, light: vec4<f32>, normal: vec3<f32>, c: array<vec4<f32>, 4>) -> f32 { return sunlight(sun, light, normal); }";

/// The finest terrain level drawn into a map has samples at least this
/// many of its texels apart.
const CASTER_DETAIL: f64 = 0.5;

/// How far the sun may turn before the cascades follow it, radians: the
/// direction of a sun given by azimuth and elevation turns with the local
/// up as the camera moves (4 microradians for 25 m), which would make new
/// boxes every frame; 0.1 milliradian moves a shadow 2 m at 20 km, a
/// tenth of the default maps' finest texel there.
const SUN_HELD_RAD: f64 = 1e-4;

/// A sun lower than this (sine of its elevation) casts no maps: its
/// shadows would stretch past any box, and the lighting's twilight has
/// already taken its light.
const LOWEST_SUN: f64 = 0.01;

/// The cascades as the lookup reads them (`lookup.wgsl`'s table, flat
/// inputs of the passes reading the maps): the sun's axes with the count,
/// texel and map size, then each cascade's box across the sun's rays, its
/// metres per texel, and its near end and depth scale along them.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
struct CascadeTable {
    right: [f32; 4],
    up: [f32; 4],
    toward: [f32; 4],
    boxes: [[f32; 4]; Shadows::MAX_CASCADES as usize],
    near: [f32; 4],
    depth_per_m: [f32; 4],
}

/// The table's vec4s.
pub const TABLE_VEC4S: usize = size_of::<CascadeTable>() / size_of::<[f32; 4]>();

impl CascadeTable {
    fn new(fitted: &[cascades::Cascade], map_size: u32) -> Self {
        let mut t = Self::default();
        if let Some(first) = fitted.first() {
            let (right, up, toward) = first.bounds.axes();
            let v = |a: glam::DVec3, w: f64| [a.x as f32, a.y as f32, a.z as f32, w as f32];
            t.right = v(right, fitted.len() as f64);
            t.up = v(up, 1.0 / f64::from(map_size));
            t.toward = v(toward, f64::from(map_size));
        }
        for (i, c) in fitted.iter().enumerate() {
            let b = &c.bounds;
            t.boxes[i] = [b.x as f32, b.y as f32, (1.0 / b.half) as f32, c.texel_m as f32];
            t.near[i] = b.z_lo as f32;
            t.depth_per_m[i] = c.depth_per_m as f32;
        }
        t
    }
}

/// The maps of one size and count, and the lookup's bind group over them.
struct Maps {
    size: u32,
    layers: Vec<wgpu::TextureView>,
    lookup: wgpu::BindGroup,
    /// What each cascade's map was last drawn for (`key_of` its box, the
    /// sun's axes and the size), none before the first.
    drawn: Vec<Option<u64>>,
}

/// What the last frame did to the maps: drawn whole, redrawn in part
/// (scissored regions over what changed), kept as they were; the regions
/// and the texels drawn in all.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MapWork {
    pub drawn: usize,
    pub redrawn_in_part: usize,
    pub kept: usize,
    pub regions: usize,
    pub texels: u64,
}

/// What casts shadows in this frame: the passes drawn into the maps.
pub type Casters<'a, 'b> = &'a mut [&'b mut dyn ShadowCaster];

/// Where the frame is seen from and lit.
pub struct ShadowView<'a> {
    pub view: &'a View,
    pub aspect: f64,
    /// Towards the sun (world axes), and the sine of its elevation.
    pub sun: DVec3,
    pub sin_elevation: f64,
    /// Distance from the eye to the ground under it, metres.
    pub above_ground_m: f64,
    /// The frame's uniform, each cascade's drawn with its own matrix.
    pub frame: FrameUniform,
}

/// The shadows pass: the maps, and the layout and table of the lookup
/// the passes reading them bind.
pub struct ShadowsPass {
    lookup_layout: wgpu::BindGroupLayout,
    cascades_buffer: wgpu::Buffer,
    sampler: wgpu::Sampler,
    maps: Option<Maps>,
    /// Clears a region of a map (depth 0, scissored): made the first time
    /// a map is redrawn in part.
    clear: Option<wgpu::RenderPipeline>,
    /// The last frame's work on the maps.
    pub work: MapWork,
    /// The cascade count the lookup was built for (`lookup`).
    pub cascades: u32,
    /// The sun's direction the cascades were last fitted to (`SUN_HELD_RAD`).
    sun_held: Option<DVec3>,
}

impl ShadowsPass {
    /// The pass for `cascades` maps (a pass for another count is built
    /// anew: the lookup places points in that many).
    pub fn new(device: &wgpu::Device, cascades: u32) -> Self {
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            // The table is read by the vertex stage (flat inputs), the maps
            // by the fragments.
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty,
            count: None,
        };
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow lookup"),
            entries: &[
                entry(
                    0,
                    crate::passes::pipeline::params_binding(wgpu::BufferSize::new(size_of::<CascadeTable>() as u64)),
                ),
                entry(
                    1,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
                entry(2, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison)),
            ],
        });
        let cascades_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("shadow cascades"),
            contents: bytemuck::bytes_of(&CascadeTable::default()),
            usage: crate::passes::pipeline::PARAMS_USAGE,
        });
        // Lit where the point is at least as near the sun as the map's.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow test"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::GreaterEqual),
            ..Default::default()
        });
        Self {
            lookup_layout,
            cascades_buffer,
            sampler,
            maps: None,
            clear: None,
            work: MapWork::default(),
            cascades,
            sun_held: None,
        }
    }

    /// What the maps hold, bytes.
    pub fn held_bytes(&self) -> u64 {
        self.maps.as_ref().map_or(0, |m| {
            m.layers.len() as u64
                * u64::from(m.size).pow(2)
                * u64::from(DEPTH_FORMAT.block_copy_size(None).unwrap_or(4))
        })
    }

    /// The layout of the cascades' bind group, for passes that read them.
    pub fn lookup_layout(&self) -> &wgpu::BindGroupLayout {
        &self.lookup_layout
    }

    /// The cascades' bind group (after `run`).
    pub fn lookup(&self) -> Option<&wgpu::BindGroup> {
        self.maps.as_ref().map(|m| &m.lookup)
    }

    /// The frame's shadow maps: the cascades fitted to the view, and the
    /// casters drawn into each map where it needs them: whole when its
    /// box (or the sun, or its size) moved or everything changed, else
    /// only over the texels the casters' changed areas cover (each region
    /// cleared and drawn again under a scissor, from the casters that
    /// region sees), else not at all. Before the frame's colour is drawn;
    /// the frame uniform is the camera's again afterwards (the casters'
    /// own buffers are theirs to restore).
    pub fn run(
        &mut self,
        gpu: &Gpu,
        frame_buffer: &wgpu::Buffer,
        shadows: &Shadows,
        at: &ShadowView<'_>,
        casters: Casters<'_, '_>,
    ) -> Result<(), RenderError> {
        let fitted = if at.sin_elevation < LOWEST_SUN {
            Vec::new()
        } else {
            let near = (at.above_ground_m * 0.5).max(1.0);
            // Far enough past the ground under a high eye to take in the
            // ground round it.
            let far = shadows.distance_m.max(near * 4.0);
            let sun = match self.sun_held {
                Some(held) if held.angle_between(at.sun) < SUN_HELD_RAD => held,
                _ => at.sun,
            };
            self.sun_held = Some(sun);
            cascades::fit(at.view, at.aspect, sun, at.sin_elevation, (near, far), shadows.cascades, shadows.map_size)
        };
        let mut changes = Changes::Nothing;
        for caster in casters.iter() {
            changes.merge(caster.changes());
        }
        if self.clear.is_none() && matches!(changes, Changes::Areas(_)) {
            self.clear = Some(clear_pipeline(&gpu.device));
        }
        let maps =
            self.maps.take().filter(|m| m.size == shadows.map_size && m.layers.len() == shadows.cascades as usize);
        let mut maps = match maps {
            Some(maps) => maps,
            None => Maps::new(gpu, shadows, &self.lookup_layout, &self.cascades_buffer, &self.sampler),
        };
        // The boxes are fixed in the world (`cascades`): a camera that
        // moved a little finds the same ones, and their depths, measured in
        // the world, still hold. The terrain's samples count by their data
        // (a level rolling with the camera draws the same surface), what
        // changed in them by the casters' areas.
        let sun = fitted.first().map(|c| {
            let (r, u, t) = c.bounds.axes();
            [r, u, t].map(|a| a.to_array().map(f64::to_bits))
        });
        let mut work = MapWork::default();
        if fitted.is_empty() {
            maps.drawn.iter_mut().for_each(|d| *d = None);
        }
        for (k, cascade) in fitted.iter().enumerate() {
            let key = crate::passes::pipeline::key_of(&(cascade.anchored.map(f64::to_bits), sun, shadows.map_size));
            let size = shadows.map_size;
            let regions: Option<Vec<TexelRect>> = match &changes {
                _ if maps.drawn[k] != Some(key) => None,
                Changes::Everything => None,
                Changes::Nothing => Some(Vec::new()),
                Changes::Areas(areas) => {
                    let rects = areas.iter().filter_map(|a| regions::texels(cascade, at.view.eye, a, size)).collect();
                    let rects = regions::merged(rects);
                    // Past half the map, one whole draw costs less.
                    let texels: u64 = rects.iter().map(TexelRect::texels).sum();
                    (texels * 2 < u64::from(size).pow(2)).then_some(rects)
                }
            };
            let frame = FrameUniform { view_proj: cascade.clip.as_mat4().to_cols_array_2d(), ..at.frame };
            let finest_m = cascade.texel_m * CASTER_DETAIL;
            match regions {
                None => {
                    let into = CastInto { volume: &cascade.bounds, finest_m, frame: &frame };
                    let target = Region { layer: &maps.layers[k], rect: None, clear: None };
                    draw_region(gpu, frame_buffer, &target, &into, casters);
                    work.drawn += 1;
                    work.texels += u64::from(size).pow(2);
                }
                Some(rects) if rects.is_empty() => work.kept += 1,
                Some(rects) => {
                    work.redrawn_in_part += 1;
                    for rect in rects {
                        let region = cascade.bounds.region((rect.x0, rect.y0, rect.x1, rect.y1), size);
                        let into = CastInto { volume: &region, finest_m, frame: &frame };
                        let target = Region { layer: &maps.layers[k], rect: Some(rect), clear: self.clear.as_ref() };
                        draw_region(gpu, frame_buffer, &target, &into, casters);
                        work.regions += 1;
                        work.texels += rect.texels();
                    }
                }
            }
            maps.drawn[k] = Some(key);
        }
        for caster in casters.iter_mut() {
            caster.cast();
        }
        self.maps = Some(maps);
        self.work = work;
        gpu.queue.write_buffer(frame_buffer, 0, bytemuck::bytes_of(&at.frame));
        let u = CascadeTable::new(&fitted, shadows.map_size);
        gpu.queue.write_buffer(&self.cascades_buffer, 0, bytemuck::bytes_of(&u));
        wait(gpu)
    }
}

/// Where one draw into a map goes: its layer, and the region of it (the
/// whole map, cleared by the pass, when None; else cleared by `clear`).
struct Region<'a> {
    layer: &'a wgpu::TextureView,
    rect: Option<TexelRect>,
    clear: Option<&'a wgpu::RenderPipeline>,
}

/// Draws what every caster chooses for `into` into `region`.
fn draw_region(
    gpu: &Gpu,
    frame_buffer: &wgpu::Buffer,
    region: &Region<'_>,
    into: &CastInto<'_>,
    casters: &mut [&mut dyn ShadowCaster],
) {
    for caster in casters.iter_mut() {
        caster.ready(gpu, into);
    }
    gpu.queue.write_buffer(frame_buffer, 0, bytemuck::bytes_of(into.frame));
    let mut encoder =
        gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("shadow casters") });
    {
        let load = if region.rect.is_some() { wgpu::LoadOp::Load } else { wgpu::LoadOp::Clear(0.0) };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow casters"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: region.layer,
                depth_ops: Some(wgpu::Operations { load, store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some(rect) = region.rect {
            let [x, y, w, h] = rect.scissor();
            pass.set_scissor_rect(x, y, w, h);
            if let Some(clear) = region.clear {
                pass.set_pipeline(clear);
                pass.draw(0..3, 0..1);
            }
        }
        for caster in casters.iter() {
            caster.record(&mut pass);
        }
    }
    gpu.queue.submit([encoder.finish()]);
}

/// A depth-only pipeline that writes the cleared depth (0: nothing nearer
/// the sun) over the whole target, within the pass's scissor.
fn clear_pipeline(device: &wgpu::Device) -> wgpu::RenderPipeline {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("shadow region clear"),
        source: wgpu::ShaderSource::Wgsl(CLEAR.into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("shadow region clear"),
        bind_group_layouts: &[],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("shadow region clear"),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &shader,
            entry_point: Some("vs_clear"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: None,
        multiview_mask: None,
        cache: None,
    })
}

/// A triangle over the whole target at depth 0.
pub const CLEAR: &str = "@vertex
fn vs_clear(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(i & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}
";

impl Maps {
    fn new(
        gpu: &Gpu,
        shadows: &Shadows,
        layout: &wgpu::BindGroupLayout,
        cascades: &wgpu::Buffer,
        sampler: &wgpu::Sampler,
    ) -> Self {
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow maps"),
            size: wgpu::Extent3d {
                width: shadows.map_size,
                height: shadows.map_size,
                depth_or_array_layers: shadows.cascades,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let layers = (0..shadows.cascades)
            .map(|layer| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: layer,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let all = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let lookup = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow lookup"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: cascades.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&all) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(sampler) },
            ],
        });
        Self { size: shadows.map_size, layers, lookup, drawn: vec![None; shadows.cascades as usize] }
    }
}
