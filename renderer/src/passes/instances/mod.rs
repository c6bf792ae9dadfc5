//! The instances pass: the scene's `instances` layer (trees, shrubs,
//! houses placed by `scatter` or `instances`), drawn with GPU instancing.
//! Instance tiles round the camera are asked for at the layer's level, as
//! far as the last distance band reaches. Each frame sorts the instances
//! on the CPU (f64): thinned by distance band (Savelli et al.), culled to
//! the view, models near and billboards far, cross-faded by dithering so
//! nothing pops (`bands.rs`). A model is drawn in one instanced call for
//! all its instances; every billboard in one more, from the atlas each
//! model's billboard was rendered into (`models.rs`).

mod bands;
mod models;
mod reach;
mod sort;
mod view;

use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;

use glam::DVec3;
use relief_models::Model;
use relief_source::{InstanceKind, Payload, TileKey};
use wgpu::util::DeviceExt;

pub use bands::InstanceBands;
use models::{GpuInstance, GpuModel, INSTANCE_ATTRIBUTES, MAX_MODELS, MODEL_ATTRIBUTES, ModelVertex};
use sort::{Placed, PlacedTile};
pub use view::InstancesView;

use super::casting::{CastInto, Changes, ShadowCaster, TileCast, tile_changes};
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::surface::Surface;

/// The scene's instance tiles and models, as the renderer asks for them.
pub trait InstanceTiles {
    /// The tile level instance tiles are asked for at (up to three levels
    /// coarser near the poles, where tiles narrow: a coarser tile must hold
    /// the instances of the finer tiles it covers).
    fn level(&self) -> u8;
    /// The instance tiles `keys` (built when needed); None for one not ready.
    fn instances(&self, keys: &[TileKey]) -> Vec<Option<Arc<Payload>>>;
    /// The model an instance names; None for a name the scene does not know.
    fn model(&self, name: &str) -> Option<Arc<Model>>;
}

/// What a frame draws: one buffer of instances, models first (a range per
/// model), then the billboards.
pub struct InstancesDraw {
    buffer: Option<wgpu::Buffer>,
    models: Vec<(u32, Range<u32>)>,
    billboards: Range<u32>,
    /// Instances within reach and in the view, before the bands thin them.
    pub in_view: usize,
    pub models_drawn: usize,
    pub billboards_drawn: usize,
    /// Instance tiles asked for but not ready, and instances whose model
    /// the scene does not have.
    pub not_ready: usize,
    pub unknown_models: usize,
    /// Per tile in reach, what the shadow maps take in of it (the models
    /// it places; billboards cast none).
    cast: HashMap<TileKey, TileCast>,
}

const INSTANCE_BUFFER: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: size_of::<GpuInstance>() as u64,
    step_mode: wgpu::VertexStepMode::Instance,
    attributes: &INSTANCE_ATTRIBUTES,
};

/// A model's vertices, then the instances placing it.
const MODEL_BUFFERS: [Option<wgpu::VertexBufferLayout<'static>>; 2] = [
    Some(wgpu::VertexBufferLayout {
        array_stride: size_of::<ModelVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &MODEL_ATTRIBUTES,
    }),
    Some(INSTANCE_BUFFER),
];

/// The instances' lit pipelines, the models' and the billboards' (each
/// with its bind group layout), as the pass makes them and their twins
/// receiving shadows.
fn lit_pipelines<'a>(
    models: &'a wgpu::BindGroupLayout,
    billboards: &'a wgpu::BindGroupLayout,
) -> [crate::passes::lit::LitPipeline<'a>; 2] {
    [
        crate::passes::lit::LitPipeline {
            label: "instance models",
            group0: models,
            stages: ("vs_model", "fs_model"),
            buffers: &MODEL_BUFFERS,
        },
        crate::passes::lit::LitPipeline {
            label: "instance billboards",
            group0: billboards,
            stages: ("vs_billboard", "fs_billboard"),
            buffers: &[Some(INSTANCE_BUFFER)],
        },
    ]
}

/// The instances' shader.
const SOURCE: &str = include_str!("instances.wgsl");

pub struct InstancesPass {
    model_pipeline: wgpu::RenderPipeline,
    /// What the `shadows` effect's depth-only twin of the models' pipeline
    /// is made from, and that twin once a frame casts shadows (billboards
    /// cast none).
    model_pipeline_layout: wgpu::PipelineLayout,
    shader: wgpu::ShaderModule,
    caster: Option<wgpu::RenderPipeline>,
    model_layout: wgpu::BindGroupLayout,
    model_bind_group: wgpu::BindGroup,
    billboard_pipeline: wgpu::RenderPipeline,
    billboard_layout: wgpu::BindGroupLayout,
    billboard_bind_group: wgpu::BindGroup,
    /// The models' and billboards' twins receiving shadows, while the
    /// scene casts them.
    shadowed: Option<crate::passes::lit::Receiving>,
    /// Bakes a model's normals for its billboard.
    normal_pipeline: wgpu::RenderPipeline,
    /// Billboards' colours and normals, a layer per model.
    atlas: wgpu::Texture,
    normals: wgpu::Texture,
    models: Vec<GpuModel>,
    by_name: HashMap<String, u32>,
    tiles: HashMap<TileKey, PlacedTile>,
    /// Instance tiles sorted for drawing since the pass was built.
    pub tiles_built: u64,
    /// What the shadow maps hold of each tile.
    cast: HashMap<TileKey, TileCast>,
}

impl InstancesPass {
    pub fn new(device: &wgpu::Device, frame_buffer: &wgpu::Buffer) -> Self {
        let shader = crate::passes::lit::lit_shader(device, "instances", SOURCE, None);
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty,
            count: None,
        };
        let uniform = crate::passes::pipeline::params_binding(None);
        let model_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("instance models"),
            entries: &[entry(0, uniform)],
        });
        let billboard_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("instance billboards"),
            entries: &[
                entry(0, uniform),
                entry(
                    1,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
                entry(2, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
                entry(
                    3,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
            ],
        });
        let layout = |label, bind: &wgpu::BindGroupLayout| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(bind)],
                immediate_size: 0,
            })
        };
        let model_pipeline_layout = layout("instance models", &model_layout);
        let [model_pipeline, billboard_pipeline] =
            lit_pipelines(&model_layout, &billboard_layout).map(|p| p.build(device, &shader, None));
        let normal_pipeline = crate::passes::pipeline::pipeline(
            device,
            "billboard normals",
            &model_pipeline_layout,
            &shader,
            ("vs_model", "fs_model_normal"),
            &MODEL_BUFFERS,
        );
        let (atlas, normals) = (models::atlas(device), models::atlas(device));
        let array = |t: &wgpu::Texture| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            })
        };
        let (atlas_view, normals_view) = (array(&atlas), array(&normals));
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("billboards"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        let model_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("instance models"),
            layout: &model_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() }],
        });
        let billboard_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("instance billboards"),
            layout: &billboard_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&atlas_view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&sampler) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&normals_view) },
            ],
        });
        Self {
            model_pipeline,
            model_pipeline_layout,
            shader,
            caster: None,
            model_layout,
            model_bind_group,
            billboard_pipeline,
            billboard_layout,
            billboard_bind_group,
            shadowed: None,
            normal_pipeline,
            atlas,
            normals,
            models: Vec::new(),
            by_name: HashMap::new(),
            tiles: HashMap::new(),
            tiles_built: 0,
            cast: HashMap::new(),
        }
    }

    /// What the pass holds, bytes: the billboard atlases, the models'
    /// buffers, and each tile's placed instances.
    pub fn held_bytes(&self) -> u64 {
        let atlases =
            crate::passes::pipeline::texture_bytes(&self.atlas) + crate::passes::pipeline::texture_bytes(&self.normals);
        let models: u64 = self.models.iter().map(|m| m.vertices.size() + m.indices.size()).sum();
        let placed: usize = self.tiles.values().map(|t| t.placed.len() * size_of::<sort::Placed>()).sum();
        atlases + models + placed as u64
    }

    /// Fetches the instance tiles within the last band's reach, brings new
    /// ones (and their models) to the device, and sorts every instance in
    /// reach into models and billboards.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        at: &InstancesView<'_>,
        source: &dyn InstanceTiles,
    ) -> Result<InstancesDraw, RenderError> {
        let mut draw = InstancesDraw {
            buffer: None,
            models: Vec::new(),
            billboards: 0..0,
            in_view: 0,
            models_drawn: 0,
            billboards_drawn: 0,
            not_ready: 0,
            unknown_models: 0,
            cast: HashMap::new(),
        };
        let reach = at.bands.reach_m();
        let keys = reach::keys(at, source.level(), reach);
        let fetched = if keys.is_empty() { Vec::new() } else { source.instances(&keys) };
        for (key, payload) in keys.iter().zip(fetched) {
            let Some(payload) = payload else {
                draw.not_ready += 1;
                continue;
            };
            if self.tiles.get(key).is_none_or(|t| !Arc::ptr_eq(&t.payload, &payload)) {
                let tile = self.place(gpu, at.surface, payload, source, &mut draw.unknown_models)?;
                self.tiles.insert(*key, tile);
                self.tiles_built += 1;
            }
        }
        self.tiles.retain(|k, _| keys.contains(k));

        let (keys, tiles): (Vec<TileKey>, Vec<&PlacedTile>) =
            keys.iter().filter_map(|k| self.tiles.get(k).map(|t| (*k, t))).unzip();
        let shapes: Vec<sort::Shape> = self.models.iter().map(sort::Shape::of).collect();
        let per_tile = sort::sort(&tiles, at, &shapes);
        // What a tile casts: which of its instances are models (in the
        // world, whichever way the camera moved).
        for ((key, tile), sorted) in keys.iter().zip(&tiles).zip(&per_tile) {
            let content = Arc::as_ptr(&tile.payload) as usize;
            let cast_key = crate::passes::pipeline::key_of(&(content, &sorted.cast));
            draw.cast.insert(*key, TileCast { key: cast_key, centre: tile.centre, radius: tile.radius });
        }
        let sorted = per_tile.into_iter().fold(sort::Sorted::default(), sort::Sorted::merge);
        draw.in_view = sorted.in_view;
        let (per_model, mut billboards) = (sorted.models, sorted.billboards);
        // At most one device buffer of them (knobs reaching tens of
        // kilometres could ask for more): models first, then billboards.
        let most = (gpu.device.limits().max_buffer_size / size_of::<GpuInstance>() as u64) as usize;
        let mut all: Vec<GpuInstance> = Vec::new();
        for (slot, mut list) in per_model.into_iter().enumerate() {
            list.truncate(most - all.len());
            if !list.is_empty() {
                let start = all.len() as u32;
                draw.models_drawn += list.len();
                all.extend(list);
                draw.models.push((slot as u32, start..all.len() as u32));
            }
        }
        billboards.truncate(most - all.len());
        draw.billboards_drawn = billboards.len();
        draw.billboards = all.len() as u32..(all.len() + billboards.len()) as u32;
        all.extend(billboards);
        if !all.is_empty() {
            draw.buffer = Some(gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("instances"),
                contents: bytemuck::cast_slice(&all),
                usage: wgpu::BufferUsages::VERTEX,
            }));
        }
        Ok(draw)
    }

    /// Makes (or drops) the pipelines receiving shadows from the maps
    /// `lookup` describes (their layout and count), as the frame casts them.
    pub fn receive_shadows(&mut self, device: &wgpu::Device, lookup: Option<(&wgpu::BindGroupLayout, u32)>) {
        let pipelines = lit_pipelines(&self.model_layout, &self.billboard_layout);
        crate::passes::lit::Receiving::update(&mut self.shadowed, device, lookup, ("instances", SOURCE), &pipelines);
    }

    /// Draws the models, then the billboards; with `shadows` (the
    /// cascades' lookup, after `receive_shadows`), receiving them.
    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>, draw: &InstancesDraw, shadows: Option<&wgpu::BindGroup>) {
        let Some(buffer) = &draw.buffer else { return };
        let plain = [&self.model_pipeline, &self.billboard_pipeline];
        let [models, billboards] = crate::passes::lit::Receiving::choose(self.shadowed.as_ref(), pass, shadows, plain);
        self.record_models(pass, models, draw);
        if !draw.billboards.is_empty() {
            pass.set_pipeline(billboards);
            pass.set_bind_group(0, &self.billboard_bind_group, &[]);
            pass.set_vertex_buffer(0, buffer.slice(..));
            pass.draw(0..6, draw.billboards.clone());
        }
    }

    fn record_models(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, draw: &InstancesDraw) {
        let Some(buffer) = &draw.buffer else { return };
        if draw.models.is_empty() {
            return;
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.model_bind_group, &[]);
        pass.set_vertex_buffer(1, buffer.slice(..));
        for (slot, range) in &draw.models {
            let model = &self.models[*slot as usize];
            pass.set_vertex_buffer(0, model.vertices.slice(..));
            pass.set_index_buffer(model.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..model.index_count, 0, range.clone());
        }
    }

    /// The scene no longer casts shadows: the depth-only pipeline goes.
    pub fn drop_casters(&mut self) {
        self.caster = None;
    }

    /// Builds the depth-only pipeline the first time a frame casts shadows.
    pub fn prepare_casters(&mut self, device: &wgpu::Device) {
        if self.caster.is_none() {
            let (layout, shader) = (&self.model_pipeline_layout, &self.shader);
            self.caster = Some(crate::passes::pipeline::caster_pipeline(
                device,
                "instance casters",
                layout,
                shader,
                "vs_model",
                &MODEL_BUFFERS,
            ));
        }
    }

    /// A tile's instances in world positions with their axes, each with
    /// its model's slot (uploaded and its billboard rendered on first use).
    fn place(
        &mut self,
        gpu: &Gpu,
        surface: &Surface,
        payload: Arc<Payload>,
        source: &dyn InstanceTiles,
        unknown: &mut usize,
    ) -> Result<PlacedTile, RenderError> {
        let mut placed = Vec::new();
        if let Payload::Instances(tile) = payload.as_ref() {
            let mut slots: HashMap<&str, Option<u32>> = HashMap::new();
            for instance in &tile.instances {
                let slot = match slots.get(instance.model.as_str()) {
                    Some(slot) => *slot,
                    None => {
                        let slot = self.slot(gpu, &instance.model, source)?;
                        slots.insert(&instance.model, slot);
                        slot
                    }
                };
                let Some(slot) = slot else {
                    *unknown += 1;
                    continue;
                };
                let [x, y, z] = instance.position;
                let [e, n, u] = surface.enu(x, y);
                let (sin, cos) = instance.rotation_deg.to_radians().sin_cos();
                placed.push(Placed {
                    world: surface.world(x, y, z),
                    east: (cos * e - sin * n).as_vec3(),
                    up: u.as_vec3(),
                    scale: instance.scale as f32,
                    random: unit_random(instance.feature_id),
                    slot,
                    billboard_only: instance.kind == InstanceKind::Billboard,
                });
            }
        }
        let n = placed.len().max(1) as f64;
        let centre = placed.iter().fold(DVec3::ZERO, |c, p| c + p.world / n);
        let size = |p: &Placed| {
            let m = &self.models[p.slot as usize].model;
            f64::from(p.scale * (m.radius() + m.height()))
        };
        let radius = placed.iter().map(|p| (p.world - centre).length() + size(p)).fold(0.0, f64::max);
        Ok(PlacedTile { payload, placed, centre, radius })
    }

    /// The slot of model `name`: uploaded and baked the first time, again
    /// when the scene's model changed; None for a model the scene does not
    /// have (or past the atlas's layers).
    fn slot(&mut self, gpu: &Gpu, name: &str, source: &dyn InstanceTiles) -> Result<Option<u32>, RenderError> {
        let Some(model) = source.model(name) else { return Ok(None) };
        let slot = match self.by_name.get(name) {
            Some(&slot) if Arc::ptr_eq(&self.models[slot as usize].model, &model) => return Ok(Some(slot)),
            Some(&slot) => slot,
            None if self.models.len() as u32 >= MAX_MODELS => {
                tracing::warn!(model = name, "more models than the billboard atlas holds: not drawn");
                return Ok(None);
            }
            None => self.models.len() as u32,
        };
        let gpu_model = GpuModel::new(&gpu.device, model, slot);
        let images = [(&self.model_pipeline, &self.atlas), (&self.normal_pipeline, &self.normals)];
        models::bake(gpu, &self.model_layout, &gpu_model, &images)?;
        if (slot as usize) < self.models.len() {
            self.models[slot as usize] = gpu_model;
        } else {
            self.models.push(gpu_model);
        }
        self.by_name.insert(name.to_owned(), slot);
        Ok(Some(slot))
    }
}

/// The instances' models as the shadow maps take them in: what `draw`
/// (this frame) places.
pub struct InstancesCasting<'a> {
    pub pass: &'a mut InstancesPass,
    pub draw: &'a InstancesDraw,
}

impl ShadowCaster for InstancesCasting<'_> {
    /// Each tile whose models differ from what the maps hold (an edit, or
    /// a camera that moved them in their bands), where it was and is.
    fn changes(&self) -> Changes {
        tile_changes(&self.pass.cast, &self.draw.cast)
    }

    fn ready(&mut self, gpu: &Gpu, _: &CastInto<'_>) {
        self.pass.prepare_casters(&gpu.device);
    }

    /// Every model this frame places (one instanced draw a model: the
    /// region's scissor keeps what lies outside it out of the map).
    fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        if let Some(caster) = &self.pass.caster {
            self.pass.record_models(pass, caster, self.draw);
        }
    }

    fn cast(&mut self) {
        self.pass.cast.clone_from(&self.draw.cast);
    }
}

/// A number in 0..1 from a feature id, well mixed (splitmix64).
fn unit_random(id: u64) -> f64 {
    let mut z = id.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_numbers_are_uniform_over_small_ids() {
        let n = 100_000;
        let below: usize = (0..n).filter(|&id| unit_random(id) < 0.3).count();
        let share = below as f64 / n as f64;
        assert!((share - 0.3).abs() < 0.01, "{share}");
    }
}
