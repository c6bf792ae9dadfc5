//! Drawing a frame: the clipmap brought to the camera, level textures
//! updated where they changed, the base and the levels drawn with
//! reversed-Z depth, and the image and depth read back.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use relief_source::{Extent, geodesy};
use wgpu::util::DeviceExt;

use crate::camera::{Pose, View};
use crate::clipmap::{COLOR_DETAIL, Clipmap, ClipmapConfig, StorageRect, TerrainSamples, UpdateStats};
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::surface::Surface;

/// Most clipmap levels a frame draws (the shader's uniform array).
pub const MAX_LEVELS: usize = 16;
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    view_proj: [[f32; 4]; 4],
    sun: [f32; 4],
    light: [f32; 4],
    centre: [f32; 4],
    /// The eye in double-single parts (for the base); w of `eye_low` is how
    /// far the base is sunk below the levels, in metres.
    eye_high: [f32; 4],
    eye_low: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct LevelUniform {
    offset: [f32; 4],
    window: [i32; 4],
    coarse: [i32; 4],
    blend: [f32; 4],
}

/// A vertex of the base or of a reference mesh: its position split into
/// two f32s (high and low parts, "double-single"), so the shader subtracts
/// the eye in two steps and keeps centimetres on a planet; w of `high` is
/// the validity.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct BaseVertex {
    high: [f32; 4],
    low: [f32; 4],
    normal: [f32; 4],
    color: [f32; 4],
}

/// `v` as an f32 high part and the f32 remainder.
fn split(v: DVec3) -> ([f32; 3], [f32; 3]) {
    let high = v.as_vec3();
    let low = (v - high.as_dvec3()).as_vec3();
    (high.to_array(), low.to_array())
}

/// What a frame is drawn with besides the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// The scene's `lighting` effect: sun and ambient. Off, colours are
    /// drawn as they are.
    pub lighting: bool,
}

/// A rendered frame.
#[derive(Debug, Clone)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// RGBA8, row-major from the top left.
    pub rgba: Vec<u8>,
    /// Reversed-Z depth per pixel: `NEAR_M / distance along the view axis`, 0 for sky.
    pub depth: Vec<f32>,
    /// Wall time of each pass, milliseconds.
    pub passes: Vec<(&'static str, f64)>,
    pub update: UpdateStats,
    pub view: View,
}

/// The coarse grid of the whole scene under the clipmap: every sample of
/// tile level 0, uploaded once; each frame draws every 1st, 2nd or 4th of
/// them, as the view needs, short of the horizon.
#[derive(Debug)]
struct Base {
    cols: i64,
    rows: i64,
    world: Vec<DVec3>,
    vertices: wgpu::Buffer,
    /// Ground size of one cell, metres (at the equator on the planet).
    cell_m: f64,
}

impl Base {
    /// The vertices of samples `xs` x `ys` of tile level 0 (row-major),
    /// with their world positions.
    fn vertices(
        surface: &Surface,
        source: &dyn TerrainSamples,
        xs: std::ops::Range<i64>,
        ys: std::ops::Range<i64>,
    ) -> Option<(Vec<DVec3>, Vec<BaseVertex>)> {
        let heights = source.heights(0, xs.clone(), ys.clone())?;
        let colors = source.colors(0, xs.clone(), ys.clone())?;
        let (mut world, mut vertices) = (Vec::with_capacity(heights.len()), Vec::with_capacity(heights.len()));
        let samples = ys.flat_map(|gy| xs.clone().map(move |gx| (gx, gy)));
        for (((gx, gy), h), color) in samples.zip(heights).zip(colors) {
            let (x, y) = surface.sample_point(0, gx, gy);
            let p = surface.world(x, y, if h.is_finite() { f64::from(h) } else { 0.0 });
            let up = surface.enu(x, y)[2].as_vec3();
            let (high, low) = split(p);
            let valid = if surface.on_grid(0, gx, gy) { 1.0 } else { crate::clipmap::OFF_GRID };
            vertices.push(BaseVertex {
                high: [high[0], high[1], high[2], valid],
                low: [low[0], low[1], low[2], 0.0],
                normal: [up.x, up.y, up.z, 0.0],
                color: color.map(|v| f32::from(v) / 255.0),
            });
            world.push(p);
        }
        Some((world, vertices))
    }

    fn fill(device: &wgpu::Device, surface: &Surface, source: &dyn TerrainSamples) -> Option<Self> {
        let (cells_x, cells_y) = surface.grid().samples_at(0);
        let (cols, rows) = (cells_x + 1, cells_y + 1);
        let (world, vertices) = Self::vertices(surface, source, 0..cols, 0..rows)?;
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("base vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        });
        Some(Self { cols, rows, world, vertices, cell_m: surface.step(0) * surface.metres_per_unit() })
    }

    /// Fetches again the samples inside `area` (grid units) and writes
    /// only their rows' spans of the vertex buffer. False when not ready.
    fn refresh(&mut self, queue: &wgpu::Queue, surface: &Surface, source: &dyn TerrainSamples, area: &Extent) -> bool {
        let (x0, y0) = surface.sample_coords(0, area.min_x, area.max_y);
        let (x1, y1) = surface.sample_coords(0, area.max_x, area.min_y);
        let xs = (x0.floor() as i64).clamp(0, self.cols)..(x1.ceil() as i64 + 1).clamp(0, self.cols);
        let ys = (y0.floor() as i64).clamp(0, self.rows)..(y1.ceil() as i64 + 1).clamp(0, self.rows);
        if xs.is_empty() || ys.is_empty() {
            return true;
        }
        let Some((world, vertices)) = Self::vertices(surface, source, xs.clone(), ys.clone()) else { return false };
        let width = (xs.end - xs.start) as usize;
        for (k, gy) in ys.enumerate() {
            let first = (gy * self.cols + xs.start) as usize;
            self.world[first..first + width].copy_from_slice(&world[k * width..(k + 1) * width]);
            let offset = (first * size_of::<BaseVertex>()) as u64;
            queue.write_buffer(&self.vertices, offset, bytemuck::cast_slice(&vertices[k * width..(k + 1) * width]));
        }
        true
    }
}

pub struct Renderer {
    gpu: Arc<Gpu>,
    surface: Surface,
    clipmap: Clipmap,
    level_pipeline: wgpu::RenderPipeline,
    base_pipeline: wgpu::RenderPipeline,
    frame_buffer: wgpu::Buffer,
    levels_buffer: wgpu::Buffer,
    positions: wgpu::Texture,
    colors: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    /// Which tile level each texture layer holds now.
    layer_holds: Vec<Option<u8>>,
    /// Index buffers by the finer level's hole (in cells), or none.
    index_cache: HashMap<Option<(i64, i64)>, (wgpu::Buffer, u32)>,
    base: Option<Base>,
}

impl Renderer {
    pub fn new(gpu: Arc<Gpu>, surface: Surface, config: ClipmapConfig) -> Result<Self, RenderError> {
        config.validate().map_err(|message| RenderError::Request { field: "quality", message })?;
        if config.levels > MAX_LEVELS {
            return Err(RenderError::Request { field: "quality", message: format!("at most {MAX_LEVELS} levels") });
        }
        let device = &gpu.device;
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("terrain"),
            source: wgpu::ShaderSource::Wgsl(include_str!("terrain.wgsl").into()),
        });
        let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry { binding, visibility, ty, count: None };
        let both = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let uniform = wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let texture = |filterable| wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("terrain"),
            entries: &[
                entry(0, both, uniform),
                entry(1, wgpu::ShaderStages::VERTEX, uniform),
                entry(2, wgpu::ShaderStages::VERTEX, texture(false)),
                entry(3, wgpu::ShaderStages::FRAGMENT, texture(true)),
                entry(4, wgpu::ShaderStages::FRAGMENT, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("terrain"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let base_attributes = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4, 3 => Float32x4];
        let pipeline = |label, vs, fs, buffers: &[Option<wgpu::VertexBufferLayout<'_>>]| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &shader,
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
                fragment: Some(wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some(fs),
                    compilation_options: wgpu::PipelineCompilationOptions::default(),
                    targets: &[Some(COLOR_FORMAT.into())],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let level_pipeline = pipeline("levels", "vs_level", "fs_level", &[]);
        let base_pipeline = pipeline(
            "base",
            "vs_base",
            "fs_base",
            &[Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<BaseVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &base_attributes,
            })],
        );
        let layers = config.levels as u32;
        let array = |label, side: usize, format| {
            let side = side as u32;
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
        };
        let positions = array("level positions", config.n, wgpu::TextureFormat::Rgba32Float);
        let colors = array("level colours", COLOR_DETAIL as usize * config.n, wgpu::TextureFormat::Rgba8Unorm);
        let frame_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let levels_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("levels"),
            size: (size_of::<LevelUniform>() * MAX_LEVELS) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
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
        let (positions_view, colors_view) = (array_view(&positions), array_view(&colors));
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("terrain"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: levels_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&positions_view) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&colors_view) },
                wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::Sampler(&sampler) },
            ],
        });
        Ok(Self {
            gpu,
            surface,
            clipmap: Clipmap::new(config),
            level_pipeline,
            base_pipeline,
            frame_buffer,
            levels_buffer,
            positions,
            colors,
            bind_group,
            layer_holds: vec![None; config.levels],
            index_cache: HashMap::new(),
            base: None,
        })
    }

    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    pub fn clipmap(&self) -> &Clipmap {
        &self.clipmap
    }

    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// The scene rebuilt tiles in `area`: refresh those samples only, in
    /// the levels and in the base (which is filled anew if not ready).
    pub fn invalidate(&mut self, source: &dyn TerrainSamples, area: &Extent) {
        self.clipmap.invalidate(&self.surface, source, area);
        if let Some(base) = &mut self.base
            && !base.refresh(&self.gpu.queue, &self.surface, source, area)
        {
            self.base = None;
        }
    }

    /// Renders the view from `pose`.
    pub fn render(
        &mut self,
        source: &dyn TerrainSamples,
        pose: &Pose,
        settings: &RenderSettings,
    ) -> Result<Frame, RenderError> {
        pose.validate(self.surface.is_planet())?;
        let max = self.gpu.max_size();
        for (field, v) in [("width", settings.width), ("height", settings.height)] {
            if v == 0 || v > max {
                return Err(RenderError::Request { field, message: format!("{v} is not from 1 to {max} pixels") });
            }
        }
        let mut passes = Vec::new();
        let started = Instant::now();
        let pixel_angle = pose.vertical_fov_deg.to_radians() / f64::from(settings.height);
        let update = self.clipmap.update(&self.surface, source, pose, pixel_angle);
        if self.base.is_none() {
            self.base = Base::fill(&self.gpu.device, &self.surface, source);
        }
        passes.push(("update", started.elapsed().as_secs_f64() * 1e3));

        let started = Instant::now();
        self.upload_levels(&update.active);
        let view = self.surface.view(pose);
        let levels = self.level_uniforms(&update.active, pose, &view);
        self.gpu.queue.write_buffer(&self.levels_buffer, 0, bytemuck::cast_slice(&levels));
        let (base, sink) = self.base_cells(&update.active, &view, pose, pixel_angle).unzip();
        self.write_frame_uniform(pose, &view, settings, Some(sink.unwrap_or(0.0)));
        let draws = self.level_draws(&update.active);
        passes.push(("upload", started.elapsed().as_secs_f64() * 1e3));

        let started = Instant::now();
        let (rgba, depth) = self.draw(settings, base.as_ref(), &draws)?;
        passes.push(("draw and read back", started.elapsed().as_secs_f64() * 1e3));
        Ok(Frame { width: settings.width, height: settings.height, rgba, depth, passes, update, view })
    }

    /// `base_sink`: Some(metres the base is sunk) when the base is drawn
    /// from its double-single positions; None for a mesh already relative
    /// to the eye.
    fn write_frame_uniform(&self, pose: &Pose, view: &View, settings: &RenderSettings, base_sink: Option<f64>) {
        let (eye_high, eye_low) = if base_sink.is_some() { split(view.eye) } else { ([0.0; 3], [0.0; 3]) };
        let frame = FrameUniform {
            view_proj: view.view_projection(f64::from(settings.width) / f64::from(settings.height)).to_cols_array_2d(),
            sun: self.sun(pose),
            light: [0.35, 0.75, if settings.lighting { 1.0 } else { 0.0 }, 0.0],
            centre: {
                let c = (-view.eye).as_vec3();
                [c.x, c.y, c.z, if self.surface.is_planet() { 1.0 } else { 0.0 }]
            },
            eye_high: [eye_high[0], eye_high[1], eye_high[2], 0.0],
            eye_low: [eye_low[0], eye_low[1], eye_low[2], base_sink.unwrap_or(0.0) as f32],
        };
        self.gpu.queue.write_buffer(&self.frame_buffer, 0, bytemuck::bytes_of(&frame));
    }

    /// One pass: the mesh (base or reference) and the clipmap levels, then
    /// colour and depth read back.
    fn draw(
        &self,
        settings: &RenderSettings,
        base: Option<&(wgpu::Buffer, wgpu::Buffer, u32)>,
        draws: &[Option<(i64, i64)>],
    ) -> Result<(Vec<u8>, Vec<f32>), RenderError> {
        let device = &self.gpu.device;
        let target = |format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: None,
                size: wgpu::Extent3d { width: settings.width, height: settings.height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: usage | wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let color = target(COLOR_FORMAT, wgpu::TextureUsages::empty());
        let depth = target(DEPTH_FORMAT, wgpu::TextureUsages::empty());
        let (color_view, depth_view) = (
            color.create_view(&wgpu::TextureViewDescriptor::default()),
            depth.create_view(&wgpu::TextureViewDescriptor::default()),
        );
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("terrain"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r: 0.02, g: 0.03, b: 0.07, a: 1.0 }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            if let Some((vertices, indices, count)) = base {
                pass.set_pipeline(&self.base_pipeline);
                pass.set_vertex_buffer(0, vertices.slice(..));
                pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*count, 0, 0..1);
            }
            pass.set_pipeline(&self.level_pipeline);
            for (slot, key) in draws.iter().enumerate() {
                let (indices, count) = &self.index_cache[key];
                pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*count, 0, slot as u32..slot as u32 + 1);
            }
        }
        self.read_back(encoder, &color, &depth, settings)
    }

    /// The brute-force reference: every sample of `area` (grid units) at
    /// tile level `level` as one mesh, f64 positions made eye-relative on
    /// the CPU, drawn without the clipmap. For benchmarks and accuracy
    /// comparisons; None when the data is not ready.
    pub fn render_full_mesh(
        &self,
        source: &dyn TerrainSamples,
        level: u8,
        area: &Extent,
        pose: &Pose,
        settings: &RenderSettings,
    ) -> Result<Option<Frame>, RenderError> {
        pose.validate(self.surface.is_planet())?;
        let mut passes = Vec::new();
        let started = Instant::now();
        let (x0, y0) = self.surface.sample_coords(level, area.min_x, area.max_y);
        let (x1, y1) = self.surface.sample_coords(level, area.max_x, area.min_y);
        let (xs, ys) = (x0.floor() as i64..x1.ceil() as i64 + 1, y0.floor() as i64..y1.ceil() as i64 + 1);
        let (Some(heights), Some(colors)) =
            (source.heights(level, xs.clone(), ys.clone()), source.colors(level, xs.clone(), ys.clone()))
        else {
            return Ok(None);
        };
        let view = self.surface.view(pose);
        let (cols, rows) = ((xs.end - xs.start) as usize, (ys.end - ys.start) as usize);
        let mut world = Vec::with_capacity(cols * rows);
        for (j, gy) in ys.clone().enumerate() {
            for (i, gx) in xs.clone().enumerate() {
                let (x, y) = self.surface.sample_point(level, gx, gy);
                let h = heights[j * cols + i];
                world.push(self.surface.world(x, y, if h.is_finite() { f64::from(h) } else { 0.0 }));
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
                    color: colors[k].map(|v| f32::from(v) / 255.0),
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
        let device = &self.gpu.device;
        let mesh = (
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
        );
        self.write_frame_uniform(pose, &view, settings, None);
        passes.push(("mesh", started.elapsed().as_secs_f64() * 1e3));
        let started = Instant::now();
        let (rgba, depth) = self.draw(settings, Some(&mesh), &[])?;
        passes.push(("draw and read back", started.elapsed().as_secs_f64() * 1e3));
        let update = UpdateStats::default();
        Ok(Some(Frame { width: settings.width, height: settings.height, rgba, depth, passes, update, view }))
    }

    /// The sun in the camera's local sky: from the north-west, 45 degrees up.
    fn sun(&self, pose: &Pose) -> [f32; 4] {
        let [e, n, u] = self.surface.enu(pose.position[0], pose.position[1]);
        let (az, el) = (315f64.to_radians(), 45f64.to_radians());
        let d = (az.sin() * e + az.cos() * n) * el.cos() + u * el.sin();
        [d.x as f32, d.y as f32, d.z as f32, 0.0]
    }

    /// Brings each active level's texture layers up to date: whole when the
    /// layer held another level, else only the rectangles written.
    fn upload_levels(&mut self, active: &[u8]) {
        let layers = self.clipmap.config.levels;
        for &t in active {
            let layer = usize::from(t) % layers;
            let Some(level) = self.clipmap.level_mut(t) else { continue };
            let (n, side) = (level.n, COLOR_DETAIL as usize * level.n);
            let (mut positions, mut colors) = level.take_dirty();
            if self.layer_holds[layer] != Some(t) {
                self.layer_holds[layer] = Some(t);
                positions = vec![StorageRect { x: 0, y: 0, width: n, height: n }];
                colors = vec![StorageRect { x: 0, y: 0, width: side, height: side }];
            }
            for r in positions {
                write_rect(&self.gpu.queue, &self.positions, layer, &r, n, &level.positions);
            }
            for r in colors {
                write_rect(&self.gpu.queue, &self.colors, layer, &r, side, &level.colors);
            }
        }
    }

    fn level_uniforms(&self, active: &[u8], pose: &Pose, view: &View) -> Vec<LevelUniform> {
        let mut out = vec![LevelUniform::zeroed(); MAX_LEVELS];
        let layers = self.clipmap.config.levels;
        let mut coarser: Option<[i32; 4]> = None;
        for (slot, &t) in active.iter().enumerate() {
            let Some(level) = self.clipmap.level(t) else { continue };
            let layer = (usize::from(t) % layers) as i32;
            let offset = (level.anchor - view.eye).as_vec3();
            let (mut fx, fy) = self.surface.sample_coords(t, pose.position[0], pose.position[1]);
            if self.surface.is_planet() {
                let total = self.surface.revolution(t) as f64;
                let centre = level.origin.0 as f64 + (level.n / 2) as f64;
                fx += total * ((centre - fx) / total).round();
            }
            let window = [level.origin.0 as i32, level.origin.1 as i32, layer, level.n as i32];
            out[slot] = LevelUniform {
                offset: [offset.x, offset.y, offset.z, 0.0],
                window,
                coarse: coarser.map_or([0, 0, layer, 0], |c| [c[0], c[1], c[2], 1]),
                blend: [
                    (fx - level.origin.0 as f64) as f32,
                    (fy - level.origin.1 as f64) as f32,
                    (level.n as f32 / 10.0).max(2.0),
                    0.0,
                ],
            };
            coarser = Some(window);
        }
        out
    }

    /// The index buffer of each active level: every cell but the hole the
    /// next finer level fills.
    fn level_draws(&mut self, active: &[u8]) -> Vec<Option<(i64, i64)>> {
        let n = self.clipmap.config.n;
        let mut keys = Vec::new();
        for (k, &t) in active.iter().enumerate() {
            let Some(level) = self.clipmap.level(t) else { continue };
            let hole = active.get(k + 1).and_then(|&f| self.clipmap.level(f)).map(|finer| {
                let mut hx = finer.origin.0 / 2 - level.origin.0;
                if self.surface.is_planet() {
                    let total = self.surface.revolution(t);
                    hx -= total * ((hx as f64) / total as f64).round() as i64;
                }
                (hx, finer.origin.1 / 2 - level.origin.1)
            });
            if !self.index_cache.contains_key(&hole) {
                let indices = cell_indices(n, hole);
                let buffer = self.gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("level cells"),
                    contents: bytemuck::cast_slice(&indices),
                    usage: wgpu::BufferUsages::INDEX,
                });
                self.index_cache.insert(hole, (buffer, indices.len() as u32));
            }
            keys.push(hole);
        }
        keys
    }

    /// The base's cells for this frame, and how far it is sunk. On the
    /// planet the stride is the coarsest whose flat cells sag (chord below
    /// the arc) less than a pixel at the horizon, and cells past the horizon
    /// are left out; cells under the coarsest level are left out too.
    fn base_cells(
        &self,
        active: &[u8],
        view: &View,
        pose: &Pose,
        pixel_angle: f64,
    ) -> Option<((wgpu::Buffer, wgpu::Buffer, u32), f64)> {
        let base = self.base.as_ref()?;
        let planet = self.surface.is_planet();
        let radius = geodesy::WGS84_A;
        let height = pose.position[2].max(1.0);
        let horizon = (2.0 * radius * height + height * height).sqrt();
        // The nearest base cell is about where the coarsest level ends.
        let nearest = active.first().and_then(|&t| self.clipmap.level(t)).map_or(height, |level| {
            let reach = (level.n / 2) as f64 * self.surface.step(level.tile_level) * self.surface.metres_per_unit();
            reach.hypot(height)
        });
        let stride: i64 = if planet {
            [4, 2, 1]
                .into_iter()
                .find(|&s| (s as f64 * base.cell_m).powi(2) / (8.0 * radius) / nearest < pixel_angle)
                .unwrap_or(1)
        } else {
            4
        };
        let cell = stride as f64 * base.cell_m;
        // The coarsest level's window in tile-level-0 samples.
        let covered = active.first().and_then(|&t| self.clipmap.level(t)).map(|level| {
            let scale = f64::from(1u32 << level.tile_level);
            (level.origin.0 as f64 / scale, level.origin.1 as f64 / scale, (level.n - 1) as f64 / scale)
        });
        let total_x = (base.cols - 1) as f64;
        let shifts: &[f64] = if planet { &[-1.0, 0.0, 1.0] } else { &[0.0] };
        let mut indices = Vec::new();
        for j in (0..base.rows - 1).step_by(stride as usize) {
            for i in (0..base.cols - 1).step_by(stride as usize) {
                let (i1, j1) = ((i + stride).min(base.cols - 1), (j + stride).min(base.rows - 1));
                if planet {
                    let centre = base.world[(i64::midpoint(j, j1) * base.cols + i64::midpoint(i, i1)) as usize];
                    if (centre - view.eye).length() > horizon + cell {
                        continue;
                    }
                }
                let (cx, cy, size) = (i as f64, j as f64, stride as f64);
                let inside = covered.is_some_and(|(x0, y0, side)| {
                    shifts.iter().any(|s| {
                        let x = cx + s * total_x;
                        x >= x0 && x + size <= x0 + side && cy >= y0 && cy + size <= y0 + side
                    })
                });
                if inside {
                    continue;
                }
                let corner = |i: i64, j: i64| (j * base.cols + i) as u32;
                let (a, b, c, d) = (corner(i, j), corner(i1, j), corner(i, j1), corner(i1, j1));
                indices.extend([a, c, d, a, d, b]);
            }
        }
        if indices.is_empty() {
            return None;
        }
        let index_buffer = self.gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("base cells"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        // Sunk a little below the levels, so where both are drawn the
        // clipmap is on top: 0.3% of a drawn cell.
        Some(((base.vertices.clone(), index_buffer, indices.len() as u32), 0.003 * cell))
    }

    fn read_back(
        &self,
        mut encoder: wgpu::CommandEncoder,
        color: &wgpu::Texture,
        depth: &wgpu::Texture,
        settings: &RenderSettings,
    ) -> Result<(Vec<u8>, Vec<f32>), RenderError> {
        let device = &self.gpu.device;
        let (w, h) = (settings.width, settings.height);
        let row = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: u64::from(row * h),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let (color_buffer, depth_buffer) = (buffer("colour read-back"), buffer("depth read-back"));
        for (texture, target, aspect) in
            [(color, &color_buffer, wgpu::TextureAspect::All), (depth, &depth_buffer, wgpu::TextureAspect::DepthOnly)]
        {
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
        self.gpu.queue.submit([encoder.finish()]);
        for b in [&color_buffer, &depth_buffer] {
            b.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        }
        device
            .poll(wgpu::PollType::Wait { submission_index: None, timeout: None })
            .map_err(|e| RenderError::Device(e.to_string()))?;
        let unpad = |b: &wgpu::Buffer| -> Result<Vec<u8>, RenderError> {
            let view = b.slice(..).get_mapped_range().map_err(|e| RenderError::Device(e.to_string()))?;
            let mut out = Vec::with_capacity((w * h * 4) as usize);
            for y in 0..h as usize {
                out.extend_from_slice(&view[y * row as usize..y * row as usize + (w * 4) as usize]);
            }
            Ok(out)
        };
        let rgba = unpad(&color_buffer)?;
        let depth = bytemuck::cast_slice::<u8, f32>(&unpad(&depth_buffer)?).to_vec();
        Ok((rgba, depth))
    }
}

/// Two triangles per cell of an n x n vertex grid (diagonal north-west to
/// south-east, as the shader's coarse midpoints assume), leaving out the
/// `hole` of side (n - 1) / 2 cells at cell (hx, hy) but for its outer ring
/// of cells: there the finer level has blended onto this level's surface,
/// and the overlap covers the pinholes f32 rounding leaves at T-junctions.
fn cell_indices(n: usize, hole: Option<(i64, i64)>) -> Vec<u32> {
    let side = ((n - 1) / 2) as i64;
    let mut out = Vec::with_capacity((n - 1) * (n - 1) * 6);
    for j in 0..n as i64 - 1 {
        for i in 0..n as i64 - 1 {
            if hole.is_some_and(|(hx, hy)| (hx + 1..hx + side - 1).contains(&i) && (hy + 1..hy + side - 1).contains(&j))
            {
                continue;
            }
            let a = (j * n as i64 + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            out.extend([a, c, d, a, d, b]);
        }
    }
    out
}

/// Writes rectangle `r` of a toroidal `side` x `side` array into `layer` of
/// `texture`.
fn write_rect<T: Pod>(
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    layer: usize,
    r: &StorageRect,
    side: usize,
    data: &[T],
) {
    let texels: Vec<T> =
        (r.y..r.y + r.height).flat_map(|y| data[y * side + r.x..y * side + r.x + r.width].iter().copied()).collect();
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d { x: r.x as u32, y: r.y as u32, z: layer as u32 },
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(&texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some((r.width * size_of::<T>()) as u32),
            rows_per_image: Some(r.height as u32),
        },
        wgpu::Extent3d { width: r.width as u32, height: r.height as u32, depth_or_array_layers: 1 },
    );
}
