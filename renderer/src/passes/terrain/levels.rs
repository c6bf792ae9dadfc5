//! The clipmap levels on the device: texture layers brought up to date
//! where they changed, each level's uniform (where it is, what blends it
//! into the next coarser), and the cells each draws.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use crate::camera::{Pose, View};
use crate::clipmap::{COLOR_DETAIL, Clipmap, StorageRect};
use crate::surface::Surface;

/// Most clipmap levels a frame draws (the shader's uniform array).
pub const MAX_LEVELS: usize = 16;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct LevelUniform {
    offset: [f32; 4],
    window: [i32; 4],
    coarse: [i32; 4],
    blend: [f32; 4],
}

/// The level textures and what each layer holds.
pub struct Levels {
    pub positions: wgpu::Texture,
    pub colors: wgpu::Texture,
    /// Which tile level each texture layer holds now.
    layer_holds: Vec<Option<u8>>,
    /// Index buffers by the finer level's hole (in cells), or none.
    index_cache: HashMap<Option<(i64, i64)>, (wgpu::Buffer, u32)>,
}

impl Levels {
    pub fn new(positions: wgpu::Texture, colors: wgpu::Texture, layers: usize) -> Self {
        Self { positions, colors, layer_holds: vec![None; layers], index_cache: HashMap::new() }
    }

    /// The index buffer and count for a level drawn with `hole`.
    pub fn cells(&self, hole: Option<(i64, i64)>) -> &(wgpu::Buffer, u32) {
        &self.index_cache[&hole]
    }

    /// Brings each active level's texture layers up to date: whole when the
    /// layer held another level, else only the rectangles written.
    pub fn upload(&mut self, queue: &wgpu::Queue, clipmap: &mut Clipmap, active: &[u8]) {
        let layers = clipmap.config.levels;
        for &t in active {
            let layer = usize::from(t) % layers;
            let Some(level) = clipmap.level_mut(t) else { continue };
            let (n, side) = (level.n, COLOR_DETAIL as usize * level.n);
            let (mut positions, mut colors) = level.take_dirty();
            if self.layer_holds[layer] != Some(t) {
                self.layer_holds[layer] = Some(t);
                positions = vec![StorageRect { x: 0, y: 0, width: n, height: n }];
                colors = vec![StorageRect { x: 0, y: 0, width: side, height: side }];
            }
            for r in positions {
                write_rect(queue, &self.positions, layer, &r, n, &level.positions);
            }
            for r in colors {
                write_rect(queue, &self.colors, layer, &r, side, &level.colors);
            }
        }
    }

    pub fn uniforms(
        surface: &Surface,
        clipmap: &Clipmap,
        active: &[u8],
        pose: &Pose,
        view: &View,
    ) -> Vec<LevelUniform> {
        let mut out = vec![LevelUniform::zeroed(); MAX_LEVELS];
        let layers = clipmap.config.levels;
        let mut coarser: Option<[i32; 4]> = None;
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
    pub fn draws(
        &mut self,
        device: &wgpu::Device,
        surface: &Surface,
        clipmap: &Clipmap,
        active: &[u8],
    ) -> Vec<Option<(i64, i64)>> {
        let n = clipmap.config.n;
        let mut keys = Vec::new();
        for (k, &t) in active.iter().enumerate() {
            let Some(level) = clipmap.level(t) else { continue };
            let hole = active.get(k + 1).and_then(|&f| clipmap.level(f)).map(|finer| {
                let mut hx = finer.origin.0 / 2 - level.origin.0;
                if surface.is_planet() {
                    let total = surface.revolution(t);
                    hx -= total * ((hx as f64) / total as f64).round() as i64;
                }
                (hx, finer.origin.1 / 2 - level.origin.1)
            });
            self.index_cache.entry(hole).or_insert_with(|| {
                let indices = cell_indices(n, hole);
                let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("level cells"),
                    contents: bytemuck::cast_slice(&indices),
                    usage: wgpu::BufferUsages::INDEX,
                });
                (buffer, indices.len() as u32)
            });
            keys.push(hole);
        }
        keys
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
