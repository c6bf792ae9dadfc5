//! The clipmap levels on the device: texture layers brought up to date
//! where they changed, each level's uniform (where it is, what blends it
//! into the next coarser), and the cells each draws.

use std::collections::HashMap;
use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use wgpu::util::DeviceExt;

use crate::camera::{Pose, Sees, View};
use crate::clipmap::{ClipLevel, Clipmap, Dirty, StorageRect};
use crate::horizon::Horizon;
use crate::surface::Surface;
use crate::uniforms::FrameUniform;

/// Most clipmap levels a frame draws (the shader's uniform array).
pub const MAX_LEVELS: usize = 16;

/// Cells per side of the blocks a level is culled by: Losasso & Hoppe draw
/// each level as blocks, and a block wholly outside the view is not drawn.
const BLOCK: usize = 16;

/// One block of a level's cells: its cells `[i0, i1) x [j0, j1)` and the
/// range of the level's indices that draws them (empty inside the hole).
#[derive(Debug, Clone)]
struct Block {
    cells: [usize; 4],
    indices: Range<u32>,
}

/// A level's index buffer (cells in block order) and its blocks.
struct LevelCells {
    buffer: wgpu::Buffer,
    blocks: Vec<Block>,
}

/// What one level draws in a frame: the index buffer (by its hole) and
/// the index ranges of the blocks in view, merged where adjacent.
#[derive(Debug, Clone)]
pub struct LevelDraw {
    /// The level's place in the frame's active levels (its uniform).
    pub slot: u32,
    hole: Option<(i64, i64)>,
    pub ranges: Vec<Range<u32>>,
    /// Blocks with cells, those of them drawn, and those left out though
    /// inside the view's volume: beyond the planet's horizon.
    pub blocks: usize,
    pub blocks_drawn: usize,
    pub blocks_beyond_horizon: usize,
}

/// One active level as its draws' vertices read it: an instance-rate
/// vertex record (the draw's instance is the level's slot), which the
/// vertex stage gets without loading a storage buffer lane by lane (what
/// lavapipe does), with the coarser level's offset and window beside it
/// and what the levels read of the frame's uniform (`with_frame`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct LevelRecord {
    offset: [f32; 4],
    window: [i32; 4],
    coarse: [i32; 4],
    blend: [f32; 4],
    coarse_offset: [f32; 4],
    coarse_window: [i32; 4],
    view_proj: [[f32; 4]; 4],
    centre: [f32; 4],
    sun: [f32; 4],
    light: [f32; 4],
}

/// `levels` with `frame`'s view-projection, centre, sun and light.
pub fn with_frame(levels: &[LevelRecord], frame: &FrameUniform) -> Vec<LevelRecord> {
    levels
        .iter()
        .map(|l| LevelRecord {
            view_proj: frame.view_proj,
            centre: frame.centre,
            sun: frame.sun,
            light: frame.light,
            ..*l
        })
        .collect()
}

const LEVEL_ATTRIBUTES: [wgpu::VertexAttribute; 13] = wgpu::vertex_attr_array![
    0 => Float32x4, 1 => Sint32x4, 2 => Sint32x4, 3 => Float32x4, 4 => Float32x4, 5 => Sint32x4,
    6 => Float32x4, 7 => Float32x4, 8 => Float32x4, 9 => Float32x4, 10 => Float32x4, 11 => Float32x4,
    12 => Float32x4
];

/// The levels' records as the levels' pipelines read them.
pub const LEVEL_RECORDS: [Option<wgpu::VertexBufferLayout<'static>>; 1] = [Some(wgpu::VertexBufferLayout {
    array_stride: size_of::<LevelRecord>() as u64,
    step_mode: wgpu::VertexStepMode::Instance,
    attributes: &LEVEL_ATTRIBUTES,
})];

/// The level textures and what each layer holds.
pub struct Levels {
    pub positions: wgpu::Texture,
    pub normals: wgpu::Texture,
    pub colors: wgpu::Texture,
    /// Which tile level each texture layer holds now.
    layer_holds: Vec<Option<u8>>,
    /// Index buffers by the finer level's hole (in cells), or none.
    index_cache: HashMap<Option<(i64, i64)>, LevelCells>,
}

impl Levels {
    pub fn new(positions: wgpu::Texture, normals: wgpu::Texture, colors: wgpu::Texture, layers: usize) -> Self {
        Self { positions, normals, colors, layer_holds: vec![None; layers], index_cache: HashMap::new() }
    }

    /// What the level textures and index buffers hold, bytes.
    pub fn held_bytes(&self) -> u64 {
        let textures = [&self.positions, &self.normals, &self.colors].map(crate::passes::pipeline::texture_bytes);
        textures.iter().sum::<u64>() + self.index_cache.values().map(|c| c.buffer.size()).sum::<u64>()
    }

    /// The index buffer of a level drawn as `draw` says.
    pub fn cells(&self, draw: &LevelDraw) -> &wgpu::Buffer {
        &self.index_cache[&draw.hole].buffer
    }

    /// Brings each active level's texture layers up to date: whole when the
    /// layer held another level, else only the rectangles written.
    pub fn upload(&mut self, queue: &wgpu::Queue, clipmap: &mut Clipmap, active: &[u8]) {
        let layers = clipmap.config.levels;
        for &t in active {
            let layer = usize::from(t) % layers;
            let Some(level) = clipmap.level_mut(t) else { continue };
            let (n, side) = (level.n, level.color_detail * level.n);
            let mut dirty = level.take_dirty();
            if self.layer_holds[layer] != Some(t) {
                self.layer_holds[layer] = Some(t);
                let whole = |side| vec![StorageRect { x: 0, y: 0, width: side, height: side }];
                dirty = Dirty { positions: whole(n), normals: whole(n), colors: whole(side) };
            }
            for r in dirty.positions {
                write_rect(queue, &self.positions, layer, &r, n, &level.positions);
            }
            for r in dirty.normals {
                write_rect(queue, &self.normals, layer, &r, n, &level.normals);
            }
            for r in dirty.colors {
                write_rect(queue, &self.colors, layer, &r, side, &level.colors);
            }
        }
    }

    pub fn records(surface: &Surface, clipmap: &Clipmap, active: &[u8], pose: &Pose, view: &View) -> Vec<LevelRecord> {
        let mut out = vec![LevelRecord::zeroed(); MAX_LEVELS];
        let layers = clipmap.config.levels;
        let mut coarser: Option<([f32; 4], [i32; 4])> = None;
        for (slot, &t) in active.iter().enumerate() {
            let Some(level) = clipmap.level(t) else { continue };
            let layer = (usize::from(t) % layers) as i32;
            let offset = (level.anchor - view.eye).as_vec3();
            let (mut fx, fy) = surface.sample_coords(t, pose.position[0], pose.position[1]);
            if surface.is_planet() {
                let total = surface.revolution(t) as f64;
                let centre = level.origin.0 as f64 + (level.n / 2) as f64;
                fx += total * ((centre - fx) / total).round();
            }
            let window = [level.origin.0 as i32, level.origin.1 as i32, layer, level.n as i32];
            let offset = [offset.x, offset.y, offset.z, 0.0];
            out[slot] = LevelRecord {
                offset,
                window,
                coarse: coarser.map_or([0, 0, layer, 0], |(_, c)| [c[0], c[1], c[2], 1]),
                coarse_offset: coarser.map_or([0.0; 4], |(o, _)| o),
                coarse_window: coarser.map_or([0; 4], |(_, c)| c),
                blend: [
                    (fx - level.origin.0 as f64) as f32,
                    (fy - level.origin.1 as f64) as f32,
                    (level.n as f32 / 10.0).max(2.0),
                    0.0,
                ],
                ..LevelRecord::zeroed()
            };
            coarser = Some((offset, window));
        }
        out
    }

    /// What each active level draws: every cell but the hole the next
    /// finer level fills, by blocks, leaving out the blocks `cull` (the
    /// view's frustum, or a shadow cascade's box, and the eye) shows
    /// wholly outside it, or wholly beyond its horizon. Levels whose
    /// samples are closer than `finest_m` metres are left out, the finest
    /// level kept drawn whole (no hole): a shadow map's texels cannot tell
    /// them apart.
    pub fn draws(
        &mut self,
        device: &wgpu::Device,
        surface: &Surface,
        clipmap: &Clipmap,
        active: &[u8],
        cull: Option<Cull<'_>>,
        finest_m: f64,
    ) -> Vec<LevelDraw> {
        let n = clipmap.config.n;
        // Always the coarsest; finer ones while their samples are far enough apart.
        let kept = active.iter().enumerate().take_while(|&(k, &t)| k == 0 || surface.spacing_m(t) >= finest_m).count();
        let mut draws = Vec::new();
        for (k, &t) in active.iter().enumerate().take(kept) {
            let Some(level) = clipmap.level(t) else { continue };
            let finer = active.get(k + 1).filter(|_| k + 1 < kept).and_then(|&f| clipmap.level(f));
            let coarser = k.checked_sub(1).and_then(|c| clipmap.level(active[c]));
            let hole = finer.map(|finer| {
                let mut hx = finer.origin.0 / 2 - level.origin.0;
                if surface.is_planet() {
                    let total = surface.revolution(t);
                    hx -= total * ((hx as f64) / total as f64).round() as i64;
                }
                (hx, finer.origin.1 / 2 - level.origin.1)
            });
            let cells = self.index_cache.entry(hole).or_insert_with(|| {
                let (indices, blocks) = cell_indices(n, hole);
                let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("level cells"),
                    contents: bytemuck::cast_slice(&indices),
                    usage: wgpu::BufferUsages::INDEX,
                });
                LevelCells { buffer, blocks }
            });
            let mut draw = LevelDraw {
                slot: k as u32,
                hole,
                ranges: Vec::new(),
                blocks: 0,
                blocks_drawn: 0,
                blocks_beyond_horizon: 0,
            };
            for block in cells.blocks.iter().filter(|b| !b.indices.is_empty()) {
                draw.blocks += 1;
                match cull.map_or(Sight::InView, |cull| sight(level, coarser, block, &cull)) {
                    Sight::InView => draw.blocks_drawn += 1,
                    Sight::BeyondHorizon => {
                        draw.blocks_beyond_horizon += 1;
                        continue;
                    }
                    Sight::Outside => continue,
                }
                match draw.ranges.last_mut() {
                    Some(last) if last.end == block.indices.start => last.end = block.indices.end,
                    _ => draw.ranges.push(block.indices.clone()),
                }
            }
            draws.push(draw);
        }
        draws
    }
}

/// What a level's blocks are culled by: a volume (the view's frustum, or
/// a shadow cascade's box) with the eye, and for the view the planet's
/// horizon.
#[derive(Clone, Copy)]
pub struct Cull<'a> {
    pub volume: &'a dyn Sees,
    pub eye: DVec3,
    pub horizon: Option<&'a Horizon>,
}

/// The points, relative to the eye, whose convex hull holds `block` of
/// `level` as drawn: its samples, and the `coarser` level's samples its
/// vertices are blended onto (the shader's `coarse_at`: those under it,
/// and the next one along where it lies between two).
fn block_points(level: &ClipLevel, coarser: Option<&ClipLevel>, block: &Block, eye: DVec3) -> Vec<DVec3> {
    let [i0, i1, j0, j1] = block.cells;
    let xs = level.origin.0 + i0 as i64..=level.origin.0 + i1 as i64;
    let ys = level.origin.1 + j0 as i64..=level.origin.1 + j1 as i64;
    let mut points = Vec::with_capacity(xs.clone().count() * ys.clone().count() * 5 / 4);
    let mut take = |l: &ClipLevel, gx: i64, gy: i64| points.extend(l.sample(gx, gy).map(|p| p - eye));
    for gy in ys.clone() {
        for gx in xs.clone() {
            take(level, gx, gy);
        }
    }
    if let Some(c) = coarser {
        for gy in ys.start() >> 1..=(ys.end() + 1) >> 1 {
            for gx in xs.start() >> 1..=(xs.end() + 1) >> 1 {
                take(c, gx, gy);
            }
        }
    }
    points
}

/// Where a block lies for a cull.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sight {
    InView,
    /// Wholly outside the volume.
    Outside,
    /// Inside the volume, but wholly beyond the horizon.
    BeyondHorizon,
}

/// Whether `block` of `level`, as drawn (`block_points`), lies wholly
/// outside the volume `cull` gives, or wholly beyond its horizon. Bounds
/// are taken in f64 from the levels' stored positions; a block without
/// terrain is out of view.
fn sight(level: &ClipLevel, coarser: Option<&ClipLevel>, block: &Block, cull: &Cull<'_>) -> Sight {
    let points = block_points(level, coarser, block, cull.eye);
    if points.is_empty() {
        return Sight::Outside;
    }
    let (lo, hi) = points.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    // A hundredth more than the half-diagonal: f32 positions and the
    // shader's own rounding never reach it.
    if !cull.volume.sees((lo + hi) / 2.0, (hi - lo).length() / 2.0 * 1.01 + 1.0) {
        return Sight::Outside;
    }
    // What the horizon hides is convex: when every point (with a metre
    // round it for f32 positions) is hidden, so is their hull.
    if cull.horizon.is_some_and(|h| points.iter().all(|&p| h.hides(p, 1.0))) {
        return Sight::BeyondHorizon;
    }
    Sight::InView
}

/// Two triangles per cell of an n x n vertex grid (diagonal north-west to
/// south-east, as the shader's coarse midpoints assume), block by block,
/// leaving out the `hole` of side (n - 1) / 2 cells at cell (hx, hy) but
/// for its outer ring of cells: there the finer level has blended onto this
/// level's surface, and the overlap covers the pinholes f32 rounding leaves
/// at T-junctions. The indices and the blocks with their index ranges.
fn cell_indices(n: usize, hole: Option<(i64, i64)>) -> (Vec<u32>, Vec<Block>) {
    let side = ((n - 1) / 2) as i64;
    let cells = n - 1;
    let mut out = Vec::with_capacity(cells * cells * 6);
    let mut blocks = Vec::new();
    for bj in (0..cells).step_by(BLOCK) {
        for bi in (0..cells).step_by(BLOCK) {
            let start = out.len() as u32;
            let (i1, j1) = ((bi + BLOCK).min(cells), (bj + BLOCK).min(cells));
            for j in bj as i64..j1 as i64 {
                for i in bi as i64..i1 as i64 {
                    if hole.is_some_and(|(hx, hy)| {
                        (hx + 1..hx + side - 1).contains(&i) && (hy + 1..hy + side - 1).contains(&j)
                    }) {
                        continue;
                    }
                    let a = (j * n as i64 + i) as u32;
                    let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
                    out.extend([a, c, d, a, d, b]);
                }
            }
            blocks.push(Block { cells: [bi, i1, bj, j1], indices: start..out.len() as u32 });
        }
    }
    (out, blocks)
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
