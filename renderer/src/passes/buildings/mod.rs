//! The buildings pass: the scene's `buildings` layer (meshes from
//! `extrude`), lit, each building in its own colour. Mesh tiles are asked
//! for where the clipmap is, coarse to fine: each active level at or past
//! the layer's `min_level` shows the buildings whose centre lies in its
//! ring (its window less the next finer level's), so every building is
//! drawn once, from the tile of the level that shows the terrain there.
//! Each building is lifted onto the terrain as the frame draws it (its
//! lowest footprint corner on the drawn surface) and its walls reach down
//! past the drawn surface's lowest point under it, so it neither floats nor
//! sinks at any level of detail; a part with absolute heights (MultiPatch,
//! `z = "absolute"`) is drawn where its heights say. Surfaces are lit on the
//! side the camera sees (MultiPatch rings come in either winding).

use std::collections::HashMap;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use rayon::prelude::*;
use relief_source::{Extent, MeshTile, Payload, TileKey};
use wgpu::util::DeviceExt;

use super::casting::{CastInto, Changes, ShadowCaster, TileCast, tile_changes};
use crate::clipmap::Clipmap;
use crate::gpu::Gpu;
use crate::surface::Surface;
use crate::uniforms::split;

/// Footprint corners sampled per building for its lift (evenly spread).
const LIFT_SAMPLES: usize = 16;
/// How far walls always reach below the lowest drawn ground, metres.
const MIN_SKIRT_M: f64 = 0.5;

/// The scene's building meshes, as the renderer asks for them.
pub trait MeshTiles {
    /// The coarsest tile level whose tiles hold buildings.
    fn min_level(&self) -> u8;
    /// The mesh tiles `keys` (built when needed); None for one not ready.
    fn meshes(&self, keys: &[TileKey]) -> Vec<Option<Arc<Payload>>>;
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Vertex {
    /// World position, high part; w: the building's index in its tile.
    high: [f32; 4],
    /// Low part; w: 1 at the foot of a wall.
    low: [f32; 4],
    normal: [f32; 4],
    color: [f32; 4],
}

const _: () = assert!(size_of::<Vertex>() == 64, "the layout of crate::passes::pipeline::VEC4_VERTICES");

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Lift {
    offset: [f32; 4],
    skirt: [f32; 4],
}

/// One building of a tile: its triangles and what its lift needs.
struct Building {
    first_index: u32,
    index_count: u32,
    /// The mean of its footprint (grid units): which ring shows it.
    centre: (f64, f64),
    /// Footprint corners (grid units), at most LIFT_SAMPLES.
    corners: Vec<(f64, f64)>,
    /// Its base in the data (metres).
    base_m: f64,
    up: DVec3,
    /// Set on the drawn terrain (false: heights as written, no lift).
    on_ground: bool,
}

/// A mesh tile on the device.
struct TileMesh {
    payload: Arc<Payload>,
    /// A digest of the mesh: a tile built again the same keeps its buffers.
    content: u64,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    buildings: Vec<Building>,
    /// A sphere (world) holding every building of the tile as stored.
    centre: DVec3,
    radius: f64,
}

/// The terrain a frame draws: where its levels are, and its height over a
/// grid point (what buildings are lifted onto).
#[derive(Clone, Copy)]
pub struct DrawnTerrain<'a> {
    pub surface: &'a Surface,
    pub clipmap: &'a Clipmap,
    /// Tile levels drawn, coarse to fine.
    pub active: &'a [u8],
    pub ground: &'a dyn Fn(f64, f64) -> Option<f64>,
    /// The camera's grid point.
    pub camera: (f64, f64),
}

/// What a frame draws: per tile, its first lift and the index ranges of
/// the buildings shown (neighbours merged: one draw for a run of them).
pub struct BuildingsDraw {
    tiles: Vec<(TileKey, u32, Vec<std::ops::Range<u32>>)>,
    bind_group: Option<wgpu::BindGroup>,
    /// Buildings drawn, and mesh tiles asked for but not ready.
    pub drawn: usize,
    pub not_ready: usize,
    /// Per tile drawn, what the shadow maps take in of it (its mesh, the
    /// buildings shown and their lifts).
    cast: HashMap<TileKey, TileCast>,
}

/// The buildings' shader.
const SOURCE: &str = include_str!("buildings.wgsl");

/// The buildings' lit pipeline (`group0` the pass's bind group layout), as
/// the pass makes it and its twin receiving shadows.
fn lit_pipeline(group0: &wgpu::BindGroupLayout) -> crate::passes::lit::LitPipeline<'_> {
    crate::passes::lit::LitPipeline {
        label: "buildings",
        group0,
        stages: ("vs_building", "fs_building"),
        buffers: &crate::passes::pipeline::VEC4_VERTICES,
    }
}

pub struct BuildingsPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    /// What the `shadows` effect's depth-only twin of the pipeline is made
    /// from, and that twin once a frame casts shadows.
    pipeline_layout: wgpu::PipelineLayout,
    shader: wgpu::ShaderModule,
    caster: Option<wgpu::RenderPipeline>,
    /// The pipeline's twin receiving shadows, while the scene casts them.
    shadowed: Option<crate::passes::lit::Receiving>,
    tiles: HashMap<TileKey, TileMesh>,
    /// Mesh tiles turned into device buffers since the pass was built.
    pub tiles_built: u64,
    /// What the shadow maps hold of each tile.
    cast: HashMap<TileKey, TileCast>,
}

impl BuildingsPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let shader = crate::passes::lit::lit_shader(device, "buildings", SOURCE, None);
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty,
            count: None,
        };
        let buffer = |ty| wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("buildings"),
            entries: &[
                entry(0, crate::passes::pipeline::params_binding(None)),
                entry(1, buffer(wgpu::BufferBindingType::Storage { read_only: true })),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("buildings"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = lit_pipeline(&layout).build(device, &shader, None);
        Self {
            pipeline,
            layout,
            pipeline_layout,
            shader,
            caster: None,
            shadowed: None,
            tiles: HashMap::new(),
            tiles_built: 0,
            cast: HashMap::new(),
        }
    }

    /// What the pass holds, bytes: each mesh tile's buffers and buildings.
    pub fn held_bytes(&self) -> u64 {
        self.tiles
            .values()
            .map(|t| {
                let corners: usize = t.buildings.iter().map(|b| b.corners.len() * 16).sum();
                t.vertices.size() + t.indices.size() + (t.buildings.len() * size_of::<Building>() + corners) as u64
            })
            .sum()
    }

    /// Chooses and fetches the mesh tiles the clipmap's rings call for,
    /// brings changed ones to the device, and lifts every building shown
    /// onto the drawn terrain (`ground`: its height over a grid point).
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        frame_buffer: &wgpu::Buffer,
        terrain: &DrawnTerrain<'_>,
        meshes: &dyn MeshTiles,
    ) -> BuildingsDraw {
        let DrawnTerrain { surface, clipmap, active, ground, .. } = *terrain;
        let rings = rings(surface, clipmap, active, meshes.min_level(), terrain.camera);
        let mut keys: Vec<TileKey> = Vec::new();
        for ring in &rings {
            for area in &ring.windows {
                for key in surface.grid().keys_overlapping(ring.level, area) {
                    if !keys.contains(&key) {
                        keys.push(key);
                    }
                }
            }
        }
        let fetched = meshes.meshes(&keys);
        // Tiles new or changed made ready on the CPU side by side, then
        // brought to the device: a bulk edit rebuilds them in parallel.
        let fresh: Vec<(TileKey, Arc<Payload>)> = keys
            .iter()
            .zip(&fetched)
            .filter_map(|(key, payload)| Some((*key, Arc::clone(payload.as_ref()?))))
            .filter(|(key, payload)| match self.tiles.get(key) {
                Some(t) => !Arc::ptr_eq(&t.payload, payload) && t.content != content_of(payload),
                None => true,
            })
            .collect();
        let prepared: Vec<(TileKey, Option<Prepared>)> =
            fresh.into_par_iter().map(|(key, payload)| (key, Prepared::new(surface, payload))).collect();
        for (key, prepared) in prepared {
            match prepared.and_then(|p| TileMesh::new(device, p)) {
                Some(mesh) => {
                    self.tiles.insert(key, mesh);
                    self.tiles_built += 1;
                }
                None => {
                    self.tiles.remove(&key);
                }
            }
        }
        let mut draw =
            BuildingsDraw { tiles: Vec::new(), bind_group: None, drawn: 0, not_ready: 0, cast: HashMap::new() };
        let mut lifts: Vec<Lift> = Vec::new();
        for (key, payload) in keys.iter().zip(fetched) {
            let Some(payload) = payload else {
                draw.not_ready += 1;
                continue;
            };
            // Built again the same (its input changed elsewhere): kept.
            let Some(tile) = self.tiles.get_mut(key) else { continue };
            tile.payload = payload;
            let tile = &*tile;
            // A building shows where a ring drawing its tile's level holds
            // its centre (rings do not overlap: it is drawn once).
            let shows = |c: (f64, f64)| rings.iter().any(|r| r.level == key.level && r.shows(c));
            let first = lifts.len() as u32;
            let mut shown: Vec<std::ops::Range<u32>> = Vec::new();
            for building in &tile.buildings {
                let visible = shows(building.centre);
                lifts.push(if visible { building.lift(ground) } else { Lift::zeroed() });
                if !visible {
                    continue;
                }
                draw.drawn += 1;
                let range = building.first_index..building.first_index + building.index_count;
                match shown.last_mut() {
                    Some(last) if last.end == range.start => last.end = range.end,
                    _ => shown.push(range),
                }
            }
            if !shown.is_empty() {
                let tile_lifts = &lifts[first as usize..];
                let reach = tile_lifts.iter().map(Lift::reach_m).fold(0.0, f64::max);
                let key_of = crate::passes::pipeline::key_of(&(
                    tile.content,
                    &shown,
                    bytemuck::cast_slice::<Lift, u8>(tile_lifts),
                ));
                draw.cast.insert(*key, TileCast { key: key_of, centre: tile.centre, radius: tile.radius + reach });
                draw.tiles.push((*key, first, shown));
            }
        }
        // Tiles no ring asks for any more are let go (not on a frame whose
        // terrain is not ready: no rings say nothing).
        if !rings.is_empty() {
            self.tiles.retain(|k, _| keys.contains(k));
        }
        let most = device.limits().max_storage_buffer_binding_size as usize / size_of::<Lift>();
        if lifts.len() > most {
            // More buildings than one binding holds: the first ones only.
            lifts.truncate(most);
            draw.tiles.retain(|(_, first, _)| (*first as usize) < most);
        }
        if !lifts.is_empty() {
            let lifts_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("building lifts"),
                contents: bytemuck::cast_slice(&lifts),
                usage: wgpu::BufferUsages::STORAGE,
            });
            draw.bind_group = Some(device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("buildings"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: lifts_buffer.as_entire_binding() },
                ],
            }));
        }
        draw
    }

    /// Makes (or drops) the pipeline receiving shadows from the maps
    /// `lookup` describes (their layout and count), as the frame casts them.
    pub fn receive_shadows(&mut self, device: &wgpu::Device, lookup: Option<(&wgpu::BindGroupLayout, u32)>) {
        let pipelines = [lit_pipeline(&self.layout)];
        crate::passes::lit::Receiving::update(&mut self.shadowed, device, lookup, ("buildings", SOURCE), &pipelines);
    }

    /// Draws the buildings; with `shadows` (the cascades' lookup, after
    /// `receive_shadows`), receiving them.
    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>, draw: &BuildingsDraw, shadows: Option<&wgpu::BindGroup>) {
        let [pipeline] = crate::passes::lit::Receiving::choose(self.shadowed.as_ref(), pass, shadows, [&self.pipeline]);
        self.record_with(pass, pipeline, draw);
    }

    /// The scene no longer casts shadows: the depth-only pipeline goes.
    pub fn drop_casters(&mut self) {
        self.caster = None;
    }

    /// Builds the depth-only pipeline the first time a frame casts shadows.
    pub fn prepare_casters(&mut self, device: &wgpu::Device) {
        if self.caster.is_none() {
            let (layout, shader) = (&self.pipeline_layout, &self.shader);
            self.caster = Some(crate::passes::pipeline::caster_pipeline(
                device,
                "building casters",
                layout,
                shader,
                "vs_building",
                &crate::passes::pipeline::VEC4_VERTICES,
            ));
        }
    }

    fn record_with(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline, draw: &BuildingsDraw) {
        self.record_tiles(pass, pipeline, draw, &|_| true);
    }

    /// Records the tiles of `draw` that `keep` keeps.
    fn record_tiles(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipeline: &wgpu::RenderPipeline,
        draw: &BuildingsDraw,
        keep: &dyn Fn(&TileKey) -> bool,
    ) {
        let Some(bind_group) = &draw.bind_group else { return };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        for (key, first, shown) in draw.tiles.iter().filter(|(k, ..)| keep(k)) {
            let tile = &self.tiles[key];
            pass.set_vertex_buffer(0, tile.vertices.slice(..));
            pass.set_index_buffer(tile.indices.slice(..), wgpu::IndexFormat::Uint32);
            for range in shown {
                pass.draw_indexed(range.clone(), 0, *first..*first + 1);
            }
        }
    }
}

/// A digest of a mesh tile's triangles, parts and colours.
fn content_of(payload: &Payload) -> u64 {
    let Payload::Mesh(mesh) = payload else { return 0 };
    let parts: Vec<(u64, u32, u32, [u8; 4])> =
        mesh.parts.iter().map(|p| (p.feature_id, p.first_index, p.index_count, p.color)).collect();
    crate::passes::pipeline::key_of(&(bytemuck::cast_slice::<[f64; 3], u8>(&mesh.positions), &mesh.indices, parts))
}

impl Lift {
    /// How far it moves a building's points, metres (up or down).
    fn reach_m(&self) -> f64 {
        let length = |v: [f32; 4]| f64::from(v[0].hypot(v[1]).hypot(v[2]));
        length(self.offset) + length(self.skirt)
    }
}

/// The buildings as the shadow maps take them in: what `draw` (this
/// frame, seen from `eye`) shows of them.
pub struct BuildingsCasting<'a> {
    pub pass: &'a mut BuildingsPass,
    pub draw: &'a BuildingsDraw,
    pub eye: DVec3,
    /// The tiles the region being drawn sees.
    seen: Vec<TileKey>,
}

impl<'a> BuildingsCasting<'a> {
    pub fn new(pass: &'a mut BuildingsPass, draw: &'a BuildingsDraw, eye: DVec3) -> Self {
        Self { pass, draw, eye, seen: Vec::new() }
    }
}

impl ShadowCaster for BuildingsCasting<'_> {
    /// Each tile whose buildings, or whose lifts, differ from what the
    /// maps hold, where it was and where it is.
    fn changes(&self) -> Changes {
        tile_changes(&self.pass.cast, &self.draw.cast)
    }

    fn ready(&mut self, gpu: &Gpu, into: &CastInto<'_>) {
        self.pass.prepare_casters(&gpu.device);
        let eye = self.eye;
        self.seen = (self.draw.cast.iter())
            .filter(|(_, t)| into.volume.sees(t.centre - eye, t.radius))
            .map(|(k, _)| *k)
            .collect();
    }

    fn record(&self, pass: &mut wgpu::RenderPass<'_>) {
        if let Some(caster) = &self.pass.caster {
            self.pass.record_tiles(pass, caster, self.draw, &|k| self.seen.contains(k));
        }
    }

    fn cast(&mut self) {
        self.pass.cast.clone_from(&self.draw.cast);
    }
}

impl Building {
    /// Onto the drawn terrain: the base to the lowest drawn ground under
    /// its corners, the walls down past the highest difference there.
    fn lift(&self, ground: &dyn Fn(f64, f64) -> Option<f64>) -> Lift {
        if !self.on_ground {
            return Lift::zeroed();
        }
        let drawn: Vec<f64> = self.corners.iter().filter_map(|&(x, y)| ground(x, y)).collect();
        let (low, high) = drawn.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &z| (l.min(z), h.max(z)));
        let (offset, skirt) =
            if drawn.is_empty() { (0.0, MIN_SKIRT_M) } else { (low - self.base_m, MIN_SKIRT_M + (high - low)) };
        let o = (self.up * offset).as_vec3();
        let s = (self.up * skirt).as_vec3();
        Lift { offset: [o.x, o.y, o.z, 0.0], skirt: [s.x, s.y, s.z, 0.0] }
    }
}

/// A mesh tile made ready on the CPU (in parallel with the others), before
/// its buffers are made.
struct Prepared {
    payload: Arc<Payload>,
    content: u64,
    vertices: Vec<Vertex>,
    buildings: Vec<Building>,
    centre: DVec3,
    radius: f64,
}

impl Prepared {
    /// The tile's triangles in world positions with flat normals; None for
    /// a payload that is not a mesh or has no triangles.
    fn new(surface: &Surface, payload: Arc<Payload>) -> Option<Self> {
        let Payload::Mesh(mesh) = payload.as_ref() else { return None };
        if mesh.indices.is_empty() {
            return None;
        }
        let (vertices, buildings, (centre, radius)) = vertices(surface, mesh);
        let content = content_of(&payload);
        Some(Self { payload, content, vertices, buildings, centre, radius })
    }
}

impl TileMesh {
    /// The tile's buffers on the device; None for one too large for them.
    fn new(device: &wgpu::Device, prepared: Prepared) -> Option<Self> {
        let Prepared { payload, content, vertices, buildings, centre, radius } = prepared;
        let Payload::Mesh(mesh) = payload.as_ref() else { return None };
        let largest = (vertices.len() * size_of::<Vertex>()).max(mesh.indices.len() * 4) as u64;
        if largest > device.limits().max_buffer_size {
            // A tile too big for one buffer (a coarse tile of a huge city):
            // left out, never a failed frame.
            tracing::warn!(bytes = largest, "a building mesh tile is larger than the device's buffers: not drawn");
            return None;
        }
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("building vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("building triangles"),
            contents: bytemuck::cast_slice(&mesh.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        Some(Self { payload, content, vertices, indices, buildings, centre, radius })
    }
}

/// The device vertices of a mesh tile, its buildings, and a sphere (world)
/// holding them. Normals are the area-weighted faces round each vertex
/// (`extrude` gives every wall its own four vertices, so walls stay flat
/// and roofs face up).
fn vertices(surface: &Surface, mesh: &MeshTile) -> (Vec<Vertex>, Vec<Building>, (DVec3, f64)) {
    let world: Vec<DVec3> = mesh.positions.iter().map(|p| surface.world(p[0], p[1], p[2])).collect();
    let n = world.len().max(1) as f64;
    let centre = world.iter().fold(DVec3::ZERO, |c, p| c + *p / n);
    let radius = world.iter().map(|p| (*p - centre).length()).fold(0.0, f64::max);
    let mut normals = vec![DVec3::ZERO; world.len()];
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| t[k] as usize);
        let n = (world[b] - world[a]).cross(world[c] - world[a]);
        for v in [a, b, c] {
            normals[v] += n;
        }
    }
    let mut part_of = vec![0u32; world.len()];
    let mut color_of = vec![[0.8f32, 0.8, 0.8, 1.0]; world.len()];
    let mut base_of = vec![false; world.len()];
    let mut buildings = Vec::with_capacity(mesh.parts.len());
    for (k, part) in mesh.parts.iter().enumerate() {
        let triangles = &mesh.indices[part.first_index as usize..(part.first_index + part.index_count) as usize];
        let mut used: Vec<usize> = triangles.iter().map(|&i| i as usize).collect();
        used.sort_unstable();
        used.dedup();
        let base_m = used.iter().map(|&v| mesh.positions[v][2]).fold(f64::INFINITY, f64::min);
        let mut footprint: Vec<(f64, f64)> = Vec::new();
        for &v in &used {
            part_of[v] = k as u32;
            color_of[v] = part.color.map(|c| f32::from(c) / 255.0);
            let [x, y, z] = mesh.positions[v];
            base_of[v] = part.on_ground && z == base_m;
            if z == base_m && !footprint.contains(&(x, y)) {
                footprint.push((x, y));
            }
        }
        let n = footprint.len().max(1) as f64;
        let centre = footprint.iter().fold((0.0, 0.0), |(sx, sy), p| (sx + p.0 / n, sy + p.1 / n));
        let stride = footprint.len().div_ceil(LIFT_SAMPLES).max(1);
        let corners = footprint.iter().step_by(stride).copied().collect();
        buildings.push(Building {
            first_index: part.first_index,
            index_count: part.index_count,
            centre,
            corners,
            base_m,
            up: surface.enu(centre.0, centre.1)[2],
            on_ground: part.on_ground,
        });
    }
    let vertices = world
        .iter()
        .enumerate()
        .map(|(v, &p)| {
            let (high, low) = split(p);
            let n = normals[v].normalize_or_zero().as_vec3();
            Vertex {
                high: [high[0], high[1], high[2], part_of[v] as f32],
                low: [low[0], low[1], low[2], if base_of[v] { 1.0 } else { 0.0 }],
                normal: [n.x, n.y, n.z, 0.0],
                color: color_of[v],
            }
        })
        .collect();
    (vertices, buildings, (centre, radius))
}

/// The area one active level shows buildings in: its window less the
/// next finer level's (grid units; on the planet, also shifted a turn
/// east and west so a window across the antimeridian is whole), and the
/// tile level its buildings come from (its own, or `min_level` for a
/// coarser level, within reach of the camera).
struct Ring {
    level: u8,
    windows: Vec<Extent>,
    holes: Vec<Extent>,
}

impl Ring {
    fn shows(&self, (x, y): (f64, f64)) -> bool {
        self.windows.iter().any(|w| w.contains(x, y)) && !self.holes.iter().any(|h| h.contains(x, y))
    }
}

fn rings(surface: &Surface, clipmap: &Clipmap, active: &[u8], min_level: u8, camera: (f64, f64)) -> Vec<Ring> {
    let window = |t: u8| -> Option<Vec<Extent>> {
        let level = clipmap.level(t)?;
        let last = level.n as i64 - 1;
        let (x0, y0) = surface.sample_point(t, level.origin.0, level.origin.1);
        let (x1, y1) = surface.sample_point(t, level.origin.0 + last, level.origin.1 + last);
        Some(surface.turns(Extent::new(x0.min(x1), y0.min(y1), x0.max(x1), y0.max(y1))))
    };
    // How far round the camera `min_level` reaches: half its window's
    // height, as far east and west on the ground (near a pole a window of
    // samples is far narrower than tall, and coarser levels are still fine
    // enough there for buildings).
    let n = clipmap.config.n as f64;
    let half_y = n / 2.0 * surface.step(min_level);
    let reach = surface.around(camera.0, camera.1, half_y);
    let mut out = Vec::new();
    for (k, &t) in active.iter().enumerate() {
        let Some(mut windows) = window(t) else { continue };
        if t < min_level {
            // A coarser ring shows min_level's tiles, within reach.
            windows = windows.iter().flat_map(|w| reach.iter().filter_map(|r| w.intersection(r))).collect();
            if windows.is_empty() {
                continue;
            }
        }
        let holes = active.get(k + 1).and_then(|&f| window(f)).unwrap_or_default();
        out.push(Ring { level: t.max(min_level), windows, holes });
    }
    out
}
