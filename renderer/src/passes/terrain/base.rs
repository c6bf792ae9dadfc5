//! The coarse base under the clipmap: every sample of tile level 0 as one
//! vertex buffer, uploaded once and refreshed where data changed; each
//! frame draws the cells the levels do not cover, short of the horizon.

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use relief_source::{Extent, geodesy};
use wgpu::util::DeviceExt;

use crate::camera::{Pose, Sees, View};
use crate::clipmap::{Clipmap, TerrainSamples};
use crate::surface::Surface;
use crate::uniforms::split;

/// A vertex of the base or of a reference mesh: its position split into
/// two f32s (high and low parts, "double-single"), so the shader subtracts
/// the eye in two steps and keeps centimetres on a planet; w of `high` is
/// the validity.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct BaseVertex {
    pub high: [f32; 4],
    pub low: [f32; 4],
    pub normal: [f32; 4],
    pub color: [f32; 4],
}

const _: () = assert!(size_of::<BaseVertex>() == 64, "the layout of crate::passes::pipeline::VEC4_VERTICES");

/// The coarse grid of the whole scene under the clipmap: every sample of
/// tile level 0, uploaded once; each frame draws every 1st, 2nd or 4th of
/// them, as the view needs, short of the horizon.
#[derive(Debug)]
pub struct Base {
    cols: i64,
    rows: i64,
    world: Vec<DVec3>,
    /// Each sample's height as drawn (nodata at 0), metres.
    heights: Vec<f32>,
    /// The least of `heights`.
    lowest_m: f64,
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
    ) -> Option<(Vec<DVec3>, Vec<f32>, Vec<BaseVertex>)> {
        let mut heights = source.heights(0, xs.clone(), ys.clone())?;
        let colors = source.colors(0, xs.clone(), ys.clone())?;
        let (mut world, mut vertices) = (Vec::with_capacity(heights.len()), Vec::with_capacity(heights.len()));
        let samples = ys.flat_map(|gy| xs.clone().map(move |gx| (gx, gy)));
        for (((gx, gy), h), color) in samples.zip(heights.iter_mut()).zip(colors) {
            *h = crate::clipmap::drawn_height(*h);
            let (x, y) = surface.sample_point(0, gx, gy);
            let p = surface.world(x, y, f64::from(*h));
            let up = surface.enu(x, y)[2].as_vec3();
            let (high, low) = split(p);
            let valid = if surface.on_grid(0, gx, gy) { 1.0 } else { crate::clipmap::OFF_GRID };
            vertices.push(BaseVertex {
                high: [high[0], high[1], high[2], valid],
                low: [low[0], low[1], low[2], 0.0],
                normal: [up.x, up.y, up.z, 0.0],
                color: crate::clipmap::premultiplied(color).map(|v| f32::from(v) / 255.0),
            });
            world.push(p);
        }
        Some((world, heights, vertices))
    }

    pub fn fill(device: &wgpu::Device, surface: &Surface, source: &dyn TerrainSamples) -> Option<Self> {
        let (cells_x, cells_y) = surface.grid().samples_at(0);
        let (cols, rows) = (cells_x + 1, cells_y + 1);
        let (world, heights, vertices) = Self::vertices(surface, source, 0..cols, 0..rows)?;
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("base vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        });
        let lowest_m = lowest(&heights);
        Some(Self { cols, rows, world, heights, lowest_m, vertices, cell_m: surface.spacing_m(0) })
    }

    /// What the base holds, bytes: its vertex buffer, and each sample's
    /// world point and height.
    pub fn held_bytes(&self) -> u64 {
        self.vertices.size() + (self.world.len() * (size_of::<DVec3>() + size_of::<f32>())) as u64
    }

    /// Fetches again the samples inside `area` (grid units) and writes
    /// only their rows' spans of the vertex buffer. Returns the world
    /// points, before and after, of the cells round each sample whose
    /// height changed (none when none did); None when not ready.
    pub fn refresh(
        &mut self,
        queue: &wgpu::Queue,
        surface: &Surface,
        source: &dyn TerrainSamples,
        area: &Extent,
    ) -> Option<Vec<DVec3>> {
        let (x0, y0) = surface.sample_coords(0, area.min_x, area.max_y);
        let (x1, y1) = surface.sample_coords(0, area.max_x, area.min_y);
        let xs = (x0.floor() as i64).clamp(0, self.cols)..(x1.ceil() as i64 + 1).clamp(0, self.cols);
        let ys = (y0.floor() as i64).clamp(0, self.rows)..(y1.ceil() as i64 + 1).clamp(0, self.rows);
        if xs.is_empty() || ys.is_empty() {
            return Some(Vec::new());
        }
        let (world, heights, vertices) = Self::vertices(surface, source, xs.clone(), ys.clone())?;
        let width = (xs.end - xs.start) as usize;
        let mut changed = Vec::new();
        for (k, gy) in ys.clone().enumerate() {
            let first = (gy * self.cols + xs.start) as usize;
            for (m, gx) in xs.clone().enumerate() {
                if self.heights[first + m] != heights[k * width + m] {
                    changed.push((gx, gy));
                }
            }
        }
        // The cells round a changed sample, as they were.
        let mut points = Vec::new();
        let (cols, rows) = (self.cols, self.rows);
        let round = |points: &mut Vec<DVec3>, world: &[DVec3]| {
            for &(gx, gy) in &changed {
                for (dx, dy) in [(-1, -1), (1, -1), (-1, 1), (1, 1)] {
                    let (x, y) = ((gx + dx).clamp(0, cols - 1), (gy + dy).clamp(0, rows - 1));
                    points.push(world[(y * cols + x) as usize]);
                }
            }
        };
        round(&mut points, &self.world);
        for (k, gy) in ys.enumerate() {
            let first = (gy * self.cols + xs.start) as usize;
            self.world[first..first + width].copy_from_slice(&world[k * width..(k + 1) * width]);
            self.heights[first..first + width].copy_from_slice(&heights[k * width..(k + 1) * width]);
            let offset = (first * size_of::<BaseVertex>()) as u64;
            queue.write_buffer(&self.vertices, offset, bytemuck::cast_slice(&vertices[k * width..(k + 1) * width]));
        }
        // And as they are.
        round(&mut points, &self.world);
        self.lowest_m = lowest(&self.heights);
        Some(points)
    }

    /// The base's cells for this frame, and how far it is sunk. On the
    /// planet the stride is the coarsest whose flat cells sag (chord below
    /// the arc) less than a pixel at the horizon, and cells past the horizon
    /// are left out: farther than the eye's horizon and the horizon of the
    /// cell's highest corner together (a mountain stands over the eye's
    /// horizon from as far as its own reaches), both over the lowest ground
    /// drawn (sea level, or a seabed or a basin below it); cells under the
    /// coarsest level are left out too.
    #[allow(clippy::too_many_arguments)]
    pub fn cells(
        &self,
        device: &wgpu::Device,
        surface: &Surface,
        clipmap: &Clipmap,
        active: &[u8],
        view: &View,
        pose: &Pose,
        pixel_angle: f64,
        cull: Option<&dyn Sees>,
    ) -> Option<((wgpu::Buffer, wgpu::Buffer, u32), f64)> {
        let base = self;
        let planet = surface.is_planet();
        let height = pose.position[2].max(1.0);
        // Heights over the lowest ground drawn: ground below sea level hides
        // less than sea level would. An eye under it sees no horizon.
        let floor = base.lowest_m.min(clipmap.lowest_m(active)).min(0.0);
        let radius = geodesy::WGS84_A + floor;
        let horizon_m = |h: f64| (2.0 * radius * h + h * h).sqrt();
        let over_floor = pose.position[2] - floor;
        let horizon = if over_floor >= 0.0 { horizon_m(over_floor.max(1.0)) } else { f64::INFINITY };
        // The nearest base cell is about where the coarsest level ends.
        let nearest = active.first().and_then(|&t| clipmap.level(t)).map_or(height, |level| {
            let reach = (level.n / 2) as f64 * surface.spacing_m(level.tile_level);
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
        let covered = active.first().and_then(|&t| clipmap.level(t)).map(|level| {
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
                    // Past the horizon even for the cell's highest corner,
                    // which is seen from as far as its own horizon reaches.
                    let centre = base.world[(i64::midpoint(j, j1) * base.cols + i64::midpoint(i, i1)) as usize];
                    let distance = (centre - view.eye).length();
                    if distance > horizon + cell {
                        let top = [(i, j), (i1, j), (i, j1), (i1, j1)]
                            .map(|(i, j)| f64::from(base.heights[(j * base.cols + i) as usize]) - floor)
                            .into_iter()
                            .fold(0.0, f64::max);
                        if distance > horizon + horizon_m(top) + cell {
                            continue;
                        }
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
                if let Some(frustum) = cull {
                    // The cell's two triangles lie within the sphere round
                    // its four corners.
                    let corners = [a, b, c, d].map(|k| base.world[k as usize]);
                    let centre = corners.iter().sum::<DVec3>() / 4.0;
                    let radius = corners.iter().map(|p| p.distance(centre)).fold(0.0, f64::max);
                    if !frustum.sees(centre - view.eye, radius * 1.01 + cell * 0.01 + 1.0) {
                        continue;
                    }
                }
                indices.extend([a, c, d, a, d, b]);
            }
        }
        if indices.is_empty() {
            return None;
        }
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("base cells"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        // Sunk a little below the levels, so where both are drawn the
        // clipmap is on top: 0.3% of a drawn cell.
        Some(((base.vertices.clone(), index_buffer, indices.len() as u32), 0.003 * cell))
    }
}

/// The least of `heights` (0 when there are none: sea level).
fn lowest(heights: &[f32]) -> f64 {
    heights.iter().copied().reduce(f32::min).map_or(0.0, f64::from)
}
