//! Geometry clipmaps (Losasso & Hoppe 2004), CPU side: L nested windows of
//! n x n samples centred under the camera, one per tile level, each stored
//! toroidally so a camera move rewrites only the L-shaped strip that came
//! into view. Positions are kept relative to an anchor per level (f64 on
//! the CPU, f32 offsets for the GPU), as in Kooima's planetary rendering.

use std::collections::BTreeMap;
use std::ops::Range;

use glam::DVec3;
use relief_source::Extent;

use crate::camera::Pose;
use crate::surface::Surface;

mod normals;

/// The validity of a sample off a flat grid: so far below the 0.5 the
/// fragment shader keeps that a cell touching one is dropped whole
/// (interpolation reaches 0.5 within a millionth of the cell).
pub const OFF_GRID: f32 = -1.0e6;

/// A sample's height as the terrain draws it: nodata (NaN) at 0, sea level.
pub fn drawn_height(h: f32) -> f32 {
    if h.is_finite() { h } else { 0.0 }
}

/// A colour as the GPU keeps it: premultiplied by its alpha, so that
/// filtering a texel with a transparent neighbour (nodata beside data, a
/// polygon's edge) blends coverage, never the neighbour's black, and the
/// shader lays it over the grey of ground without colour.
pub(crate) fn premultiplied([r, g, b, a]: [u8; 4]) -> [u8; 4] {
    let times_a = |c: u8| ((u32::from(c) * u32::from(a) + 127) / 255) as u8;
    [times_a(r), times_a(g), times_a(b), a]
}

/// Where the renderer gets terrain: the daemon answers from its tile store.
/// Blocks are corner samples at a tile level, columns `xs` and rows `ys` of
/// the level's global lattice, row-major. Indices may run past the grid: the
/// implementation wraps longitudes, continues over the poles and clamps a
/// flat grid. None when the data is not ready.
pub trait TerrainSamples: Sync {
    /// Heights in metres, NaN for nodata.
    fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>>;

    /// Colours (RGBA8, not premultiplied; alpha 0 where the scene has no
    /// colour).
    fn colors(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>>;

    /// The finest tile level worth drawing (the data's resolution).
    fn max_level(&self) -> u8;
}

/// The default colour samples per geometry sample along a side: each
/// level's colour is read from the tile level below it, so imagery is twice
/// as sharp as the mesh (a texture clipmap over the geometry clipmap).
pub const COLOR_DETAIL: usize = 2;

/// The clipmap's knobs, from the manifest's `[quality]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClipmapConfig {
    /// Samples per level side: 2^k - 1 (63, 127, 255).
    pub n: usize,
    /// How many nested levels.
    pub levels: usize,
    /// Colour samples per geometry sample along a side (1, 2 or 4): each
    /// level's colour comes from the tile level log2 of this finer.
    pub color_detail: usize,
}

impl Default for ClipmapConfig {
    fn default() -> Self {
        Self::new(127, 8)
    }
}

impl ClipmapConfig {
    /// `n` samples a side, `levels` levels, the default colour detail.
    pub const fn new(n: usize, levels: usize) -> Self {
        Self { n, levels, color_detail: COLOR_DETAIL }
    }

    /// How many tile levels finer than its geometry a level's colour is read.
    pub fn color_levels(&self) -> u8 {
        self.color_detail.trailing_zeros() as u8
    }

    pub fn validate(&self) -> Result<(), String> {
        if ![1, 2, 4].contains(&self.color_detail) {
            return Err(format!("color_detail {} is not 1, 2 or 4", self.color_detail));
        }
        if !(self.n + 1).is_power_of_two() || !(15..=511).contains(&self.n) {
            return Err(format!("clipmap_n {} is not 2^k - 1 from 15 to 511", self.n));
        }
        if !(1..=16).contains(&self.levels) {
            return Err(format!("clipmap_levels {} is not from 1 to 16", self.levels));
        }
        Ok(())
    }
}

/// A rectangle of global sample indices, half-open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rect {
    pub x: Range<i64>,
    pub y: Range<i64>,
}

impl Rect {
    fn is_empty(&self) -> bool {
        self.x.is_empty() || self.y.is_empty()
    }

    fn intersect(&self, other: &Rect) -> Rect {
        Rect {
            x: self.x.start.max(other.x.start)..self.x.end.min(other.x.end),
            y: self.y.start.max(other.y.start)..self.y.end.min(other.y.end),
        }
    }
}

/// A rectangle of a level's toroidal storage (for partial texture uploads).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StorageRect {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

/// The storage spans of global indices `range` (length at most n).
fn spans(range: &Range<i64>, n: usize) -> Vec<(usize, usize)> {
    let len = (range.end - range.start) as usize;
    let start = range.start.rem_euclid(n as i64) as usize;
    if start + len <= n { vec![(start, len)] } else { vec![(start, n - start), (0, start + len - n)] }
}

/// The storage rectangles of `rect` (global indices, each side at most
/// `side`) in a toroidal `side` x `side` array.
fn storage_rects(rect: &Rect, side: usize) -> Vec<StorageRect> {
    let columns = spans(&rect.x, side);
    spans(&rect.y, side)
        .into_iter()
        .flat_map(|(y, height)| columns.iter().map(move |&(x, width)| StorageRect { x, y, width, height }))
        .collect()
}

/// The samples entering a square window of `size` when its origin moves
/// from `old` to `new`: the whole columns that came in, then the rows that
/// came in across the remaining columns (an L).
fn entering(old: (i64, i64), new: (i64, i64), size: i64) -> Vec<Rect> {
    let (dx, dy) = (new.0 - old.0, new.1 - old.1);
    let (xs, ys) = (new.0..new.0 + size, new.1..new.1 + size);
    let columns = if dx > 0 { xs.end - dx..xs.end } else { xs.start..xs.start - dx };
    let kept = if dx > 0 { xs.start..xs.end - dx } else { xs.start - dx..xs.end };
    let rows = if dy > 0 { ys.end - dy..ys.end } else { ys.start..ys.start - dy };
    [Rect { x: columns, y: ys }, Rect { x: kept, y: rows }].into_iter().filter(|r| !r.is_empty()).collect()
}

/// The part of `window` (samples at `level`) inside `area` (grid units); on
/// the planet the window may hold the area a revolution east or west.
fn area_in(surface: &Surface, level: u8, area: &Extent, window: &Rect) -> Rect {
    let (x0, y0) = surface.sample_coords(level, area.min_x, area.max_y);
    let (x1, y1) = surface.sample_coords(level, area.max_x, area.min_y);
    let touched = Rect { x: x0.floor() as i64..x1.ceil() as i64 + 1, y: y0.floor() as i64..y1.ceil() as i64 + 1 };
    let mut rect = touched.intersect(window);
    if surface.is_planet() && rect.is_empty() {
        let total = surface.revolution(level);
        for shift in [-total, total] {
            let moved = Rect { x: touched.x.start + shift..touched.x.end + shift, y: touched.y.clone() };
            rect = moved.intersect(window);
            if !rect.is_empty() {
                break;
            }
        }
    }
    rect
}

/// One clipmap level: the window of samples at one tile level, and its
/// colour window at the next finer tile level.
#[derive(Debug, Clone)]
pub struct ClipLevel {
    pub tile_level: u8,
    pub n: usize,
    /// Global index of the window's north-west sample; both even, so the
    /// window's edges lie on the coarser level's samples.
    pub origin: (i64, i64),
    /// World position the stored positions are relative to.
    pub anchor: DVec3,
    anchor_sample: (i64, i64),
    /// Toroidal n x n: xyz relative to the anchor; w is 1 where there is
    /// terrain and `OFF_GRID` off a flat grid.
    pub positions: Vec<[f32; 4]>,
    /// Toroidal n x n: each sample's normal (xyz; `normals.rs`).
    pub normals: Vec<[f32; 4]>,
    /// Toroidal n x n: each sample's height as drawn (metres).
    heights: Vec<f32>,
    /// Colour samples per geometry sample along a side (`ClipmapConfig::color_detail`).
    pub color_detail: usize,
    /// Toroidal (color_detail n) squared: colour samples of tile level
    /// + log2 color_detail, premultiplied.
    pub colors: Vec<[u8; 4]>,
    dirty: Vec<StorageRect>,
    color_dirty: Vec<StorageRect>,
    normal_dirty: Vec<StorageRect>,
    /// The window's origin when its edge normals were last worked out.
    normals_origin: Option<(i64, i64)>,
    /// A refresh found its data not ready: the whole window is fetched again
    /// on the next move.
    stale: bool,
    /// Samples written since the level was made (incremental work done).
    pub samples_written: u64,
    /// Times the whole window was rewritten after it was made.
    pub full_refills: u32,
    /// No stored sample is lower than this (metres; nodata is stored at 0):
    /// the lowest height written since the window was last filled whole.
    pub lowest_m: f64,
}

/// Heights and colours fetched for a move, before anything is changed.
struct Fetched {
    heights: Vec<(Rect, Vec<f32>)>,
    colors: Vec<(Rect, Vec<[u8; 4]>)>,
}

impl ClipLevel {
    /// A level filled from scratch, or None when the data is not ready.
    pub fn filled(
        surface: &Surface,
        source: &dyn TerrainSamples,
        tile_level: u8,
        n: usize,
        color_detail: usize,
        origin: (i64, i64),
    ) -> Option<Self> {
        let side = color_detail * n;
        let mut level = Self {
            tile_level,
            n,
            color_detail,
            origin,
            anchor: DVec3::ZERO,
            anchor_sample: (0, 0),
            positions: vec![[0.0; 4]; n * n],
            normals: vec![[0.0; 4]; n * n],
            heights: vec![0.0; n * n],
            colors: vec![[0; 4]; side * side],
            dirty: Vec::new(),
            color_dirty: Vec::new(),
            normal_dirty: Vec::new(),
            normals_origin: None,
            stale: false,
            samples_written: 0,
            full_refills: 0,
            lowest_m: f64::INFINITY,
        };
        level.refill(surface, source, origin)?;
        level.full_refills = 0;
        Some(level)
    }

    pub fn window(&self) -> Rect {
        let n = self.n as i64;
        Rect { x: self.origin.0..self.origin.0 + n, y: self.origin.1..self.origin.1 + n }
    }

    /// The tile level the colour is read from.
    pub fn color_level(&self) -> u8 {
        self.tile_level + self.color_detail.trailing_zeros() as u8
    }

    /// Where global sample (gx, gy) is stored (toroidally, n x n).
    pub(crate) fn slot(&self, gx: i64, gy: i64) -> usize {
        let n = self.n as i64;
        (gy.rem_euclid(n) * n + gx.rem_euclid(n)) as usize
    }

    /// Stored sample (gx, gy) (global indices) as a world point; None off
    /// the grid.
    pub(crate) fn sample(&self, gx: i64, gy: i64) -> Option<DVec3> {
        let p = self.positions[self.slot(gx, gy)];
        (p[3] >= 0.5).then(|| self.anchor + DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
    }

    /// The colour window: samples of the colour level over the same ground.
    pub fn color_window(&self) -> Rect {
        let r = self.color_detail as i64;
        let side = r * (self.n as i64 - 1) + 1;
        Rect { x: r * self.origin.0..r * self.origin.0 + side, y: r * self.origin.1..r * self.origin.1 + side }
    }

    /// The stored colour of colour sample (cx, cy), global at the colour
    /// level (premultiplied).
    pub fn color_at(&self, cx: i64, cy: i64) -> [u8; 4] {
        let side = (self.color_detail * self.n) as i64;
        self.colors[(cy.rem_euclid(side) * side + cx.rem_euclid(side)) as usize]
    }

    fn fetch(&self, source: &dyn TerrainSamples, heights: &[Rect], colors: &[Rect]) -> Option<Fetched> {
        let mut out = Fetched { heights: Vec::new(), colors: Vec::new() };
        for r in heights {
            out.heights.push((r.clone(), source.heights(self.tile_level, r.x.clone(), r.y.clone())?));
        }
        for r in colors {
            out.colors.push((r.clone(), source.colors(self.color_level(), r.x.clone(), r.y.clone())?));
        }
        Some(out)
    }

    fn refill(&mut self, surface: &Surface, source: &dyn TerrainSamples, origin: (i64, i64)) -> Option<()> {
        let previous = self.origin;
        self.origin = origin;
        let fetched = self.fetch(source, &[self.window()], &[self.color_window()]);
        let Some(fetched) = fetched else {
            self.origin = previous;
            return None;
        };
        let half = (self.n / 2) as i64;
        self.anchor_sample = (origin.0 + half, origin.1 + half);
        let (ax, ay) = surface.sample_point(self.tile_level, self.anchor_sample.0, self.anchor_sample.1);
        self.anchor = surface.world(ax, ay, 0.0);
        self.lowest_m = f64::INFINITY;
        self.store(surface, fetched);
        self.stale = false;
        self.full_refills += 1;
        Some(())
    }

    /// Moves the window to `origin`, fetching only the samples that came
    /// into it. Returns false (and keeps the old window) when the data is
    /// not ready.
    pub fn move_to(&mut self, surface: &Surface, source: &dyn TerrainSamples, origin: (i64, i64)) -> bool {
        let n = self.n as i64;
        let (dx, dy) = (origin.0 - self.origin.0, origin.1 - self.origin.1);
        if dx == 0 && dy == 0 && !self.stale {
            return true;
        }
        let far_from_anchor =
            (origin.0 - self.anchor_sample.0).abs() > 2 * n || (origin.1 - self.anchor_sample.1).abs() > 2 * n;
        if dx.abs() >= n || dy.abs() >= n || far_from_anchor || self.stale {
            return self.refill(surface, source, origin).is_some();
        }
        let r = self.color_detail as i64;
        let heights = entering(self.origin, origin, n);
        let colors = entering((r * self.origin.0, r * self.origin.1), (r * origin.0, r * origin.1), r * (n - 1) + 1);
        let Some(fetched) = self.fetch(source, &heights, &colors) else { return false };
        self.origin = origin;
        self.store(surface, fetched);
        true
    }

    /// The lowest and highest heights stored over `area` (grid units);
    /// None where the window holds none of it.
    pub fn heights_over(&self, surface: &Surface, area: &Extent) -> Option<(f64, f64)> {
        let rect = area_in(surface, self.tile_level, area, &self.window());
        let mut range: Option<(f64, f64)> = None;
        for gy in rect.y.clone() {
            for gx in rect.x.clone() {
                let h = f64::from(self.heights[self.slot(gx, gy)]);
                range = Some(range.map_or((h, h), |(lo, hi)| (lo.min(h), hi.max(h))));
            }
        }
        range
    }

    /// Fetches again the part of the window inside `area` (grid units),
    /// after the scene rebuilt tiles there. When that data is not ready the
    /// level is marked stale (refilled on its next move) and false returned.
    pub fn refresh(&mut self, surface: &Surface, source: &dyn TerrainSamples, area: &Extent) -> bool {
        let heights = area_in(surface, self.tile_level, area, &self.window());
        let colors = area_in(surface, self.color_level(), area, &self.color_window());
        let heights: Vec<Rect> = [heights].into_iter().filter(|r| !r.is_empty()).collect();
        let colors: Vec<Rect> = [colors].into_iter().filter(|r| !r.is_empty()).collect();
        match self.fetch(source, &heights, &colors) {
            Some(fetched) => {
                self.store(surface, fetched);
                true
            }
            None => {
                self.stale = true;
                false
            }
        }
    }

    fn store(&mut self, surface: &Surface, fetched: Fetched) {
        let n = self.n;
        let written: Vec<Rect> = fetched.heights.iter().map(|(rect, _)| rect.clone()).collect();
        for (rect, heights) in fetched.heights {
            let width = (rect.x.end - rect.x.start) as usize;
            for (k, gy) in rect.y.clone().enumerate() {
                for (m, gx) in rect.x.clone().enumerate() {
                    let h = heights[k * width + m];
                    let (x, y) = surface.sample_point(self.tile_level, gx, gy);
                    let on = surface.on_grid(self.tile_level, gx, gy);
                    let h = drawn_height(h);
                    let slot = self.slot(gx, gy);
                    self.heights[slot] = h;
                    let h = f64::from(h);
                    self.lowest_m = self.lowest_m.min(h);
                    let p = surface.world(x, y, h) - self.anchor;
                    self.positions[slot] = [p.x as f32, p.y as f32, p.z as f32, if on { 1.0 } else { OFF_GRID }];
                }
            }
            self.samples_written += (width * rect.y.clone().count()) as u64;
            self.dirty.extend(storage_rects(&rect, n));
        }
        self.renormal(&written);
        let side = self.color_detail * n;
        for (rect, colors) in fetched.colors {
            let width = (rect.x.end - rect.x.start) as usize;
            for (k, cy) in rect.y.clone().enumerate() {
                let row = cy.rem_euclid(side as i64) as usize * side;
                for (m, cx) in rect.x.clone().enumerate() {
                    self.colors[row + cx.rem_euclid(side as i64) as usize] = premultiplied(colors[k * width + m]);
                }
            }
            self.color_dirty.extend(storage_rects(&rect, side));
        }
    }

    /// The storage rectangles written since the last call.
    pub fn take_dirty(&mut self) -> Dirty {
        Dirty {
            positions: std::mem::take(&mut self.dirty),
            normals: std::mem::take(&mut self.normal_dirty),
            colors: std::mem::take(&mut self.color_dirty),
        }
    }
}

/// A level's storage rectangles written since they were last taken.
#[derive(Debug, Default)]
pub struct Dirty {
    pub positions: Vec<StorageRect>,
    pub normals: Vec<StorageRect>,
    pub colors: Vec<StorageRect>,
}

/// What one update did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UpdateStats {
    /// Tile levels drawn this frame, coarse to fine.
    pub active: Vec<u8>,
    /// Samples fetched and written: those that came into view, and those
    /// refreshed where the scene changed since the last frame.
    pub samples_written: u64,
    /// Levels that wanted data that was not ready (not drawn).
    pub not_ready: Vec<u8>,
}

/// The nested levels, kept by tile level so a camera that climbs and
/// comes back finds its data still there.
#[derive(Debug, Default)]
pub struct Clipmap {
    pub config: ClipmapConfig,
    levels: BTreeMap<u8, ClipLevel>,
    active: Vec<u8>,
    /// Samples refreshed by `invalidate` since the last update.
    refreshed: u64,
}

impl Clipmap {
    pub fn new(config: ClipmapConfig) -> Self {
        Self { config, levels: BTreeMap::new(), active: Vec::new(), refreshed: 0 }
    }

    /// What the levels hold on the CPU, bytes: positions, normals,
    /// heights and colours of every level kept.
    pub fn held_bytes(&self) -> u64 {
        self.levels
            .values()
            .map(|l| (l.positions.len() * 16 + l.normals.len() * 16 + l.heights.len() * 4 + l.colors.len() * 4) as u64)
            .sum()
    }

    pub fn level(&self, tile_level: u8) -> Option<&ClipLevel> {
        self.levels.get(&tile_level)
    }

    pub fn level_mut(&mut self, tile_level: u8) -> Option<&mut ClipLevel> {
        self.levels.get_mut(&tile_level)
    }

    /// Tile levels drawn, coarse to fine.
    pub fn active(&self) -> &[u8] {
        &self.active
    }

    /// The lowest height levels `active` hold (nodata counted at 0, as
    /// drawn), metres; infinite while they hold none.
    pub fn lowest_m(&self, active: &[u8]) -> f64 {
        active.iter().filter_map(|&t| self.level(t)).map(|l| l.lowest_m).fold(f64::INFINITY, f64::min)
    }

    /// The window origin of tile level `level` for a camera over (x, y):
    /// centred, snapped to even samples. On the planet it stays within half
    /// a revolution of `near` so the antimeridian is no jump.
    pub fn placement(&self, surface: &Surface, level: u8, x: f64, y: f64, near: Option<(i64, i64)>) -> (i64, i64) {
        let (fx, fy) = surface.sample_coords(level, x, y);
        let half = (self.config.n / 2) as f64;
        let even = |v: f64| 2 * ((v - half) / 2.0).round() as i64;
        let (mut ox, oy) = (even(fx), even(fy));
        if let (true, Some(near)) = (surface.is_planet(), near) {
            let total = surface.revolution(level);
            ox += total * ((near.0 - ox) as f64 / total as f64).round() as i64;
        }
        (ox, oy)
    }

    /// The finest and coarsest tile levels for a camera `height_m` above
    /// the ground whose pixels each span `pixel_angle` radians: the finest
    /// level's cells are about two pixels wide under the camera, as fine as
    /// the data allows; each coarser level doubles them further out.
    pub fn level_range(&self, surface: &Surface, height_m: f64, max_level: u8, pixel_angle: f64) -> (u8, u8) {
        let wanted_step = 2.0 * height_m.max(0.01) * pixel_angle;
        // Colour reads one tile level finer than the geometry.
        let mut finest = max_level.min(relief_source::MAX_LEVEL - 1);
        while finest > 0 && surface.spacing_m(finest) < wanted_step {
            finest -= 1;
        }
        let coarsest = finest.saturating_sub(self.config.levels as u8 - 1);
        (finest, coarsest)
    }

    /// Brings the levels to `pose`, coarse to fine. A level whose data is
    /// not ready is not drawn, nor any finer one: every frame covers the
    /// view at the best detail that is ready.
    pub fn update(
        &mut self,
        surface: &Surface,
        source: &dyn TerrainSamples,
        pose: &Pose,
        pixel_angle: f64,
    ) -> UpdateStats {
        let [x, y, h] = pose.position;
        let max_level = source.max_level();
        let probe = max_level.min(self.active.last().copied().unwrap_or(8));
        let (px, py) = surface.sample_coords(probe, x, y);
        let ground = source
            .heights(probe, px.round() as i64..px.round() as i64 + 1, py.round() as i64..py.round() as i64 + 1)
            .and_then(|h| h.first().copied())
            .filter(|h| h.is_finite())
            .map_or(0.0, f64::from);
        let (finest, coarsest) = self.level_range(surface, h - ground, max_level, pixel_angle);
        let mut stats = UpdateStats::default();
        let before: u64 = self.levels.values().map(|l| l.samples_written).sum();
        let mut coarser: Option<(i64, i64)> = None;
        for level in coarsest..=finest {
            // On the planet a window may sit a revolution east or west: the
            // coarsest stays where it was, each finer one nests in the
            // coarser one (same revolution), or blending and holes break.
            let near = match coarser {
                Some(c) => Some((2 * c.0 + (self.config.n / 2) as i64, 2 * c.1)),
                None => self.levels.get(&level).map(|l| l.origin),
            };
            let origin = self.placement(surface, level, x, y, near);
            coarser = Some(origin);
            let ready = match self.levels.get_mut(&level) {
                Some(l) => l.move_to(surface, source, origin),
                None => {
                    match ClipLevel::filled(surface, source, level, self.config.n, self.config.color_detail, origin) {
                        Some(l) => {
                            self.levels.insert(level, l);
                            true
                        }
                        None => false,
                    }
                }
            };
            if !ready {
                stats.not_ready.push(level);
                break;
            }
            stats.active.push(level);
        }
        // Keep a level either side of the range; drop the rest.
        self.levels.retain(|&l, _| l + 1 >= coarsest && l <= finest + 1);
        // With the samples refreshed since the last frame (`invalidate`).
        stats.samples_written = self.levels.values().map(|l| l.samples_written).sum::<u64>().saturating_sub(before)
            + std::mem::take(&mut self.refreshed);
        self.active.clone_from(&stats.active);
        stats
    }

    /// Re-fetches what the scene rebuilt in `area`, in every kept level.
    /// Every level finer than tile level `level` is read again whole at the
    /// next update (what it draws is synthesized there, and the synthesis
    /// changed); the others keep their samples.
    pub fn invalidate_finer_than(&mut self, level: u8) {
        for l in self.levels.values_mut().filter(|l| l.tile_level > level) {
            l.stale = true;
        }
    }

    /// Returns the lowest and highest heights the levels held there
    /// before and hold after (None where no level holds any of it).
    pub fn invalidate(&mut self, surface: &Surface, source: &dyn TerrainSamples, area: &Extent) -> Option<(f64, f64)> {
        let before: u64 = self.levels.values().map(|l| l.samples_written).sum();
        let mut range: Option<(f64, f64)> = None;
        let mut widen = |r: Option<(f64, f64)>| {
            if let Some((lo, hi)) = r {
                range = Some(range.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
            }
        };
        for level in self.levels.values_mut() {
            widen(level.heights_over(surface, area));
            level.refresh(surface, source, area);
            widen(level.heights_over(surface, area));
        }
        self.refreshed += self.levels.values().map(|l| l.samples_written).sum::<u64>() - before;
        range
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_split_at_the_wrap() {
        assert_eq!(spans(&(3..7), 10), vec![(3, 4)]);
        assert_eq!(spans(&(8..13), 10), vec![(8, 2), (0, 3)]);
        assert_eq!(spans(&(-2..1), 10), vec![(8, 2), (0, 1)]);
    }

    #[test]
    fn config_is_checked() {
        assert!(ClipmapConfig::new(127, 8).validate().is_ok());
        assert!(ClipmapConfig::new(128, 8).validate().is_err());
        assert!(ClipmapConfig::new(63, 0).validate().is_err());
        assert!(ClipmapConfig { color_detail: 4, ..ClipmapConfig::new(63, 4) }.validate().is_ok());
        assert!(ClipmapConfig { color_detail: 3, ..ClipmapConfig::new(63, 4) }.validate().is_err());
    }
}
