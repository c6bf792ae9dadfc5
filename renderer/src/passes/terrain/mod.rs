//! The terrain pass: geometry clipmaps (the levels, `levels.rs`) over the
//! coarse base (`base.rs`), coloured by the colour layer and lit by the
//! `lighting` effect, drawn with reversed-Z depth.

mod base;
mod ground;
mod levels;

use relief_source::Extent;
use wgpu::util::DeviceExt;

use self::base::{Base, BaseVertex};
pub use self::levels::MAX_LEVELS;
use self::levels::{Cull, LEVEL_RECORDS, LevelDraw, LevelRecord, Levels};
use super::casting::{Area, CastInto, Changes, ShadowCaster};
use crate::camera::{Frustum, Pose, Sees, View};
use crate::clipmap::{Clipmap, ClipmapConfig, TerrainSamples, UpdateStats};
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::horizon::Horizon;
use crate::surface::Surface;
use crate::uniforms::FrameUniform;

/// The terrain's lit pipelines, the levels' and the base's (`group0`
/// the terrain's bind group layout), as the pass makes them and their
/// twins receiving shadows.
fn lit_pipelines(group0: &wgpu::BindGroupLayout) -> [crate::passes::lit::LitPipeline<'_>; 2] {
    [
        crate::passes::lit::LitPipeline {
            label: "levels",
            group0,
            stages: ("vs_level", "fs_level"),
            buffers: &LEVEL_RECORDS,
        },
        crate::passes::lit::LitPipeline {
            label: "base",
            group0,
            stages: ("vs_base", "fs_base"),
            buffers: &crate::passes::pipeline::VEC4_VERTICES,
        },
    ]
}

/// Vertices, indices and their count.
type Mesh = (wgpu::Buffer, wgpu::Buffer, u32);

pub struct TerrainPass {
    clipmap: Clipmap,
    level_pipeline: wgpu::RenderPipeline,
    base_pipeline: wgpu::RenderPipeline,
    levels_buffer: wgpu::Buffer,
    levels: Levels,
    bind_group: wgpu::BindGroup,
    base: Option<Base>,
    /// What the `shadows` effect's depth-only twin of the levels' pipeline
    /// is made from, and that twin once a frame casts shadows.
    layout: wgpu::PipelineLayout,
    shader: wgpu::ShaderModule,
    /// What the twins receiving shadows are made from (the bind group's
    /// layout and the shader's source), and those twins (levels, base)
    /// while the scene casts shadows.
    group0: wgpu::BindGroupLayout,
    source: String,
    shadowed: Option<crate::passes::lit::Receiving>,
    /// The levels' and the base's.
    caster: Option<(wgpu::RenderPipeline, wgpu::RenderPipeline)>,
    /// Where the scene's samples changed under the levels or the base
    /// since the shadow maps last took the terrain in (a rebuild; the base
    /// filled is everything): a map drawn before shows the same surface
    /// elsewhere, whichever windows the levels have rolled to since.
    cast_changes: Changes,
    /// Whether every level the frame wanted was ready when the maps last
    /// took the terrain in (finer levels arriving change everything).
    cast_complete: Option<bool>,
}

/// What a shadow cascade draws of the terrain: the base's cells in its
/// box, and each level's blocks.
pub struct TerrainCasters {
    base: Option<Mesh>,
    levels: Vec<LevelDraw>,
}

/// What a frame of the terrain draws: the base's cells (and how far the
/// base is sunk) and each active level's cells.
pub struct TerrainDraw {
    base: Option<Mesh>,
    pub base_sink: f64,
    levels: Vec<LevelDraw>,
    pub update: UpdateStats,
    /// The levels' records, the frame's part yet to come (`write_records`).
    records: Vec<LevelRecord>,
}

impl TerrainDraw {
    /// Blocks of the levels' cells, those drawn, and those left out though
    /// inside the view's frustum: beyond the planet's horizon.
    pub fn blocks(&self) -> (usize, usize, usize) {
        self.levels.iter().fold((0, 0, 0), |(all, drawn, beyond), l| {
            (all + l.blocks, drawn + l.blocks_drawn, beyond + l.blocks_beyond_horizon)
        })
    }
}

impl TerrainPass {
    /// Builds the pass: pipelines, level textures and their bind group
    /// (reading the renderer's `frame` uniform).
    pub fn new(device: &wgpu::Device, frame_buffer: &wgpu::Buffer, config: ClipmapConfig) -> Result<Self, RenderError> {
        config.validate().map_err(|message| RenderError::Request { field: "quality", message })?;
        if config.levels > MAX_LEVELS {
            return Err(RenderError::Request { field: "quality", message: format!("at most {MAX_LEVELS} levels") });
        }
        // The colour detail is a constant of the shader: a renderer serves one configuration.
        let source = format!("const COLOR_DETAIL: i32 = {};\n{}", config.color_detail, include_str!("terrain.wgsl"));
        let shader = crate::passes::lit::lit_shader(device, "terrain", &source, None);
        let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None };
        let both = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let uniform = crate::passes::pipeline::params_binding(None);
        let texture = |filterable| wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("terrain"),
            entries: &[
                entry(0, both, uniform),
                entry(2, wgpu::ShaderStages::VERTEX, texture(false)),
                entry(3, wgpu::ShaderStages::FRAGMENT, texture(true)),
                entry(5, wgpu::ShaderStages::VERTEX, texture(false)),
                entry(4, wgpu::ShaderStages::FRAGMENT, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("terrain"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let [level_pipeline, base_pipeline] = lit_pipelines(&layout).map(|p| p.build(device, &shader, None));
        let layers = config.levels as u32;
        let array = |label, side: usize, format| {
            crate::passes::pipeline::sampled_texture(device, label, side as u32, layers, format)
        };
        let positions = array("level positions", config.n, wgpu::TextureFormat::Rgba32Float);
        let normals = array("level normals", config.n, wgpu::TextureFormat::Rgba32Float);
        let colors = array("level colours", config.color_detail * config.n, wgpu::TextureFormat::Rgba8Unorm);
        let levels_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("levels"),
            size: (size_of::<LevelRecord>() * MAX_LEVELS) as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Repeat: the colour textures are toroidal.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("colours"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let array_view = |t: &wgpu::Texture| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            })
        };
        let (positions_view, normals_view, colors_view) =
            (array_view(&positions), array_view(&normals), array_view(&colors));
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("terrain"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&positions_view) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&colors_view) },
                wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::Sampler(&sampler) },
                wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::TextureView(&normals_view) },
            ],
        });
        Ok(Self {
            clipmap: Clipmap::new(config),
            level_pipeline,
            base_pipeline,
            levels_buffer,
            levels: Levels::new(positions, normals, colors, config.levels),
            bind_group,
            base: None,
            layout: pipeline_layout,
            shader,
            group0: layout,
            source,
            shadowed: None,
            caster: None,
            cast_changes: Changes::Everything,
            cast_complete: None,
        })
    }

    pub fn clipmap(&self) -> &Clipmap {
        &self.clipmap
    }

    /// What the pass holds, bytes: the level textures and index buffers,
    /// the levels' samples on the CPU, the base.
    pub fn held_bytes(&self) -> u64 {
        self.levels.held_bytes()
            + self.levels_buffer.size()
            + self.clipmap.held_bytes()
            + self.base.as_ref().map_or(0, Base::held_bytes)
    }

    /// The height of the terrain as a frame drawing levels `active` from
    /// `pose` draws it over grid point (x, y); None off the levels.
    pub fn drawn_height(&self, surface: &Surface, active: &[u8], pose: &Pose, x: f64, y: f64) -> Option<f64> {
        ground::drawn_height(surface, &self.clipmap, active, pose, x, y)
    }

    /// The scene rebuilt tiles in `area`: refresh those samples only, in
    /// the levels and in the base (which is filled anew if not ready). The
    /// ground there, between the heights it had and has, is a change for
    /// the shadow maps.
    pub fn invalidate(&mut self, gpu: &Gpu, surface: &Surface, source: &dyn TerrainSamples, area: &Extent) {
        if let Some(range) = self.clipmap.invalidate(surface, source, area) {
            self.cast_changes.add(Area::ground(surface, area, range));
        }
        match self.base.as_mut().map(|base| base.refresh(&gpu.queue, surface, source, area)) {
            Some(Some(points)) if !points.is_empty() => self.cast_changes.add(Area { points }),
            Some(None) => self.base = None,
            _ => {}
        }
    }

    /// What the levels finer than tile level `level` draw changed
    /// everywhere (the detail's synthesis): they are read again whole, and
    /// the terrain is cast anew.
    pub fn invalidate_finer_than(&mut self, level: u8) {
        self.clipmap.invalidate_finer_than(level);
        self.cast_changes = Changes::Everything;
    }

    /// Brings the clipmap to the camera and the device up to date; what to
    /// draw: with `cull`, only the level blocks inside that frustum and,
    /// on the planet, short of the horizon (`horizon`).
    #[expect(clippy::too_many_arguments, reason = "the frame's parts, each used once")]
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        surface: &Surface,
        source: &dyn TerrainSamples,
        pose: &Pose,
        view: &View,
        pixel_angle: f64,
        cull: Option<&Frustum>,
    ) -> TerrainDraw {
        let update = self.clipmap.update(surface, source, pose, pixel_angle);
        if self.base.is_none() {
            self.base = Base::fill(&gpu.device, surface, source);
            if self.base.is_some() {
                self.cast_changes = Changes::Everything;
            }
        }
        self.levels.upload(&gpu.queue, &mut self.clipmap, &update.active);
        let records: Vec<LevelRecord> = Levels::records(surface, &self.clipmap, &update.active, pose, view);
        let (base, sink) = self
            .base
            .as_ref()
            .and_then(|b| {
                let cull = cull.map(|f| f as &dyn Sees);
                b.cells(&gpu.device, surface, &self.clipmap, &update.active, view, pose, pixel_angle, cull)
            })
            .unzip();
        let horizon = cull.and_then(|_| self.horizon(surface, &update.active, pose, view));
        let cull = cull.map(|frustum| Cull { volume: frustum, eye: view.eye, horizon: horizon.as_ref() });
        let levels = self.levels.draws(&gpu.device, surface, &self.clipmap, &update.active, cull, 0.0);
        TerrainDraw { base, base_sink: sink.unwrap_or(0.0), levels, update, records }
    }

    /// The planet's horizon the levels' blocks are culled by, where that is
    /// exact: the eye at least ten near-plane distances above the drawn
    /// ground (so the ground a sight line first meets is drawn), and every
    /// sight line meeting the occluder inside the coarsest level's window
    /// (so the ground that hides a block is the levels' own). The occluder
    /// lies under every drawn point: under the lowest height the levels
    /// hold, by the most a flat cell sags below its samples (the coarsest
    /// level's diagonal squared over twice the radius; a morphed vertex
    /// lies within such a cell) and a metre for f32 positions.
    fn horizon(&self, surface: &Surface, active: &[u8], pose: &Pose, view: &View) -> Option<Horizon> {
        if !surface.is_planet() {
            return None;
        }
        let coarsest = self.clipmap.level(*active.first()?)?;
        let [x, y, _] = pose.position;
        let ground = ground::drawn_point(surface, &self.clipmap, active, pose, x, y)?;
        if (view.eye - ground).dot(surface.enu(x, y)[2]) < 10.0 * crate::camera::NEAR_M {
            return None;
        }
        let cell = surface.spacing_m(coarsest.tile_level) * std::f64::consts::SQRT_2;
        let sag = cell * cell / (2.0 * relief_source::geodesy::WGS84_B);
        let horizon = Horizon::new(view.eye, self.clipmap.lowest_m(active) - sag - 1.0)?;
        (horizon.reach_m * 1.01 < ground::reach_m(surface, coarsest, x, y)).then_some(horizon)
    }

    /// Writes the levels' records for `draw` drawn with `frame` (the
    /// frame's uniform, or a shadow cascade's): before the draws that read
    /// them.
    pub fn write_records(&self, queue: &wgpu::Queue, draw: &TerrainDraw, frame: &FrameUniform) {
        queue.write_buffer(&self.levels_buffer, 0, bytemuck::cast_slice(&levels::with_frame(&draw.records, frame)));
    }

    /// Makes (or drops) the pipelines receiving shadows from the maps
    /// `lookup` describes (their layout and count), as the frame casts them.
    pub fn receive_shadows(&mut self, device: &wgpu::Device, lookup: Option<(&wgpu::BindGroupLayout, u32)>) {
        let pipelines = lit_pipelines(&self.group0);
        crate::passes::lit::Receiving::update(
            &mut self.shadowed,
            device,
            lookup,
            ("terrain", &self.source),
            &pipelines,
        );
    }

    /// Draws the base, then the levels; with `shadows` (the cascades'
    /// lookup, after `receive_shadows`), receiving them.
    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>, draw: &TerrainDraw, shadows: Option<&wgpu::BindGroup>) {
        let plain = [&self.level_pipeline, &self.base_pipeline];
        let [levels, base] = crate::passes::lit::Receiving::choose(self.shadowed.as_ref(), pass, shadows, plain);
        if let Some(mesh) = &draw.base {
            self.record_mesh_with(pass, base, mesh);
        }
        self.record_levels(pass, levels, &draw.levels);
    }

    fn record_levels(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, levels: &[LevelDraw]) {
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(pipeline);
        pass.set_vertex_buffer(0, self.levels_buffer.slice(..));
        for level in levels {
            pass.set_index_buffer(self.levels.cells(level).slice(..), wgpu::IndexFormat::Uint32);
            for range in &level.ranges {
                pass.draw_indexed(range.clone(), 0, level.slot..level.slot + 1);
            }
        }
    }

    /// What a shadow cascade sees (`cull`) of the terrain this frame draws
    /// (`draw`, from `pose` with `view`): the base's cells and the levels'
    /// blocks, down to the finest level whose samples are at least
    /// `finest_m` apart. The depth-only pipelines are built the first time.
    pub fn casters(
        &mut self,
        device: &wgpu::Device,
        surface: &Surface,
        draw: &TerrainDraw,
        cull: &dyn Sees,
        finest_m: f64,
        (view, pose, pixel_angle): (&View, &Pose, f64),
    ) -> TerrainCasters {
        if self.caster.is_none() {
            let (layout, shader) = (&self.layout, &self.shader);
            self.caster = Some((
                crate::passes::pipeline::caster_pipeline(
                    device,
                    "terrain casters",
                    layout,
                    shader,
                    "vs_level_depth",
                    &LEVEL_RECORDS,
                ),
                crate::passes::pipeline::caster_pipeline(
                    device,
                    "terrain base casters",
                    layout,
                    shader,
                    "vs_base",
                    &crate::passes::pipeline::VEC4_VERTICES,
                ),
            ));
        }
        let active = &draw.update.active;
        let base = self
            .base
            .as_ref()
            .and_then(|b| b.cells(device, surface, &self.clipmap, active, view, pose, pixel_angle, Some(cull)))
            .map(|(mesh, _)| mesh);
        let cull = Cull { volume: cull, eye: view.eye, horizon: None };
        let levels = self.levels.draws(device, surface, &self.clipmap, active, Some(cull), finest_m);
        TerrainCasters { base, levels }
    }

    /// Draws what `casters` chose into a shadow map.
    pub fn record_casters(&self, pass: &mut wgpu::RenderPass<'_>, casters: &TerrainCasters) {
        let Some((levels, base)) = &self.caster else { return };
        if let Some(mesh) = &casters.base {
            self.record_mesh_with(pass, base, mesh);
        }
        self.record_levels(pass, levels, &casters.levels);
    }

    /// The scene no longer casts shadows: the depth-only pipeline goes.
    pub fn drop_casters(&mut self) {
        self.caster = None;
    }

    /// Draws a mesh of base vertices (the base, or the full reference mesh).
    pub fn record_mesh(&self, pass: &mut wgpu::RenderPass<'_>, mesh: &Mesh) {
        self.record_mesh_with(pass, &self.base_pipeline, mesh);
    }

    fn record_mesh_with(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipeline: &wgpu::RenderPipeline,
        (vertices, indices, count): &Mesh,
    ) {
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(pipeline);
        pass.set_vertex_buffer(0, vertices.slice(..));
        pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..*count, 0, 0..1);
    }

    /// The brute-force reference: every sample of `area` (grid units) at
    /// tile level `level` as one mesh, f64 positions made eye-relative on
    /// the CPU, to draw without the clipmap. None when the data is not
    /// ready.
    pub fn full_mesh(
        device: &wgpu::Device,
        surface: &Surface,
        source: &dyn TerrainSamples,
        level: u8,
        area: &Extent,
        view: &View,
    ) -> Option<Mesh> {
        let (x0, y0) = surface.sample_coords(level, area.min_x, area.max_y);
        let (x1, y1) = surface.sample_coords(level, area.max_x, area.min_y);
        let (xs, ys) = (x0.floor() as i64..x1.ceil() as i64 + 1, y0.floor() as i64..y1.ceil() as i64 + 1);
        let (Some(heights), Some(colors)) =
            (source.heights(level, xs.clone(), ys.clone()), source.colors(level, xs.clone(), ys.clone()))
        else {
            return None;
        };
        let (cols, rows) = ((xs.end - xs.start) as usize, (ys.end - ys.start) as usize);
        let mut world = Vec::with_capacity(cols * rows);
        for (j, gy) in ys.clone().enumerate() {
            for (i, gx) in xs.clone().enumerate() {
                let (x, y) = surface.sample_point(level, gx, gy);
                let h = heights[j * cols + i];
                world.push(surface.world(x, y, f64::from(crate::clipmap::drawn_height(h))));
            }
        }
        let at = |i: usize, j: usize| world[j.min(rows - 1) * cols + i.min(cols - 1)];
        let vertices: Vec<BaseVertex> = (0..rows * cols)
            .map(|k| {
                let (i, j) = (k % cols, k / cols);
                let east = at(i + 1, j) - at(i.saturating_sub(1), j);
                let south = at(i, j + 1) - at(i, j.saturating_sub(1));
                let n = south.cross(east).normalize_or_zero().as_vec3();
                let p = (world[k] - view.eye).as_vec3();
                BaseVertex {
                    high: [p.x, p.y, p.z, 1.0],
                    low: [0.0; 4],
                    normal: [n.x, n.y, n.z, 0.0],
                    color: crate::clipmap::premultiplied(colors[k]).map(|v| f32::from(v) / 255.0),
                }
            })
            .collect();
        let mut indices = Vec::with_capacity((cols - 1) * (rows - 1) * 6);
        for j in 0..rows - 1 {
            for i in 0..cols - 1 {
                let a = (j * cols + i) as u32;
                let (b, c, d) = (a + 1, a + cols as u32, a + cols as u32 + 1);
                indices.extend([a, c, d, a, d, b]);
            }
        }
        Some((
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("full mesh vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            }),
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("full mesh cells"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            }),
            indices.len() as u32,
        ))
    }
}

/// The terrain as the shadow maps take it in: what `draw` (this frame,
/// seen with `view`) draws of it.
pub struct TerrainCasting<'a> {
    pub pass: &'a mut TerrainPass,
    pub surface: &'a Surface,
    pub draw: &'a TerrainDraw,
    /// The frame's view, pose and the angle a pixel spans.
    pub view: (&'a View, &'a Pose, f64),
    pub chosen: Option<TerrainCasters>,
}

impl ShadowCaster for TerrainCasting<'_> {
    fn changes(&self) -> Changes {
        let complete = self.draw.update.not_ready.is_empty();
        if self.pass.cast_complete == Some(complete) { self.pass.cast_changes.clone() } else { Changes::Everything }
    }

    fn ready(&mut self, gpu: &Gpu, into: &CastInto<'_>) {
        let chosen = self.pass.casters(&gpu.device, self.surface, self.draw, into.volume, into.finest_m, self.view);
        self.pass.write_records(&gpu.queue, self.draw, into.frame);
        self.chosen = Some(chosen);
    }

    fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        if let Some(chosen) = &self.chosen {
            self.pass.record_casters(pass, chosen);
        }
    }

    fn cast(&mut self) {
        self.pass.cast_changes = Changes::Nothing;
        self.pass.cast_complete = Some(self.draw.update.not_ready.is_empty());
    }
}
