//! Pixels on demand: the raster's levels as blocks of 256 x 256 pixels,
//! read through GDAL when a tile first needs them and kept in one cache
//! for the process under a byte budget. A level is read from the file's
//! own overview where it has one of that size; otherwise it is halved from
//! the level below, only over the blocks asked for.

use std::cell::RefCell;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use gdal::Dataset;
use moka::sync::Cache;
use relief_source::SourceError;

use super::halve::{Covers, Halving, halve_window};
use super::pixels::{Block, Pixels, Window, exact_i16};
use super::{PixelRect, Store};

/// Side of a block, in pixels of its level.
pub(crate) const BLOCK: usize = 256;

/// The default budget of decoded blocks, when the scene states none.
pub const DEFAULT_BLOCK_BUDGET: u64 = 512 << 20;

/// GDAL's own block cache, under relief's (which holds decoded pixels),
/// unless the environment sets GDAL_CACHEMAX.
pub(crate) const GDAL_CACHE_MB: &str = "64";

/// Open datasets each thread keeps (GDAL datasets are not shared between threads).
const HANDLES_PER_THREAD: usize = 8;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct BlockKey {
    raster: u64,
    level: u8,
    bx: u32,
    by: u32,
    /// Bumped when the block's pixels change, so an old block is never served.
    stamp: u32,
}

/// Keys of a version's blocks that a newer version replaced: dropped from
/// the cache when the version holding this goes.
#[derive(Debug, Default)]
pub(crate) struct Departing(std::sync::Mutex<Vec<BlockKey>>);

impl Departing {
    pub(super) fn note(&self, key: BlockKey) {
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push(key);
    }
}

impl Drop for Departing {
    fn drop(&mut self) {
        for key in self.0.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner).iter() {
            cache().invalidate(key);
        }
    }
}

static BUDGET: AtomicU64 = AtomicU64::new(DEFAULT_BLOCK_BUDGET);
static CACHE: OnceLock<Cache<BlockKey, Arc<Block>>> = OnceLock::new();

/// Sets the byte budget of decoded raster blocks for the process. Call it
/// before the first raster is read; later calls change nothing.
pub fn set_block_budget(bytes: u64) {
    if CACHE.get().is_none() {
        BUDGET.store(bytes.max(1 << 20), Ordering::Relaxed);
    }
}

/// The budget in force.
pub fn block_budget() -> u64 {
    BUDGET.load(Ordering::Relaxed)
}

fn cache() -> &'static Cache<BlockKey, Arc<Block>> {
    CACHE.get_or_init(|| Cache::builder().max_capacity(block_budget()).weigher(|_, b: &Arc<Block>| b.bytes()).build())
}

/// Bytes held in the block cache now (for the scene state and tests).
pub fn cached_bytes() -> u64 {
    let cache = cache();
    cache.run_pending_tasks();
    cache.weighted_size()
}

/// A new identity for a raster's blocks in the cache.
pub(crate) fn new_uid() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

thread_local! {
    static HANDLES: RefCell<Vec<(u64, Dataset)>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` on this thread's open dataset for `version` (one version of
/// the file: a changed file is opened afresh, never read through a handle
/// that may hold its old blocks).
pub(crate) fn with_dataset<T>(
    version: u64,
    path: &Path,
    f: impl FnOnce(&Dataset) -> Result<T, SourceError>,
) -> Result<T, SourceError> {
    HANDLES.with(|handles| kept_open(handles, version, HANDLES_PER_THREAD, || super::open_dataset(path), f))
}

/// Runs `f` on the handle `handles` keep under `key` (most recently used
/// last), opening it with `open` first when they keep none, and dropping
/// the least recently used past `limit`: a thread's GDAL handles, which
/// are never shared between threads.
pub(crate) fn kept_open<K: PartialEq, T>(
    handles: &RefCell<Vec<(K, Dataset)>>,
    key: K,
    limit: usize,
    open: impl FnOnce() -> Result<Dataset, SourceError>,
    f: impl FnOnce(&Dataset) -> Result<T, SourceError>,
) -> Result<T, SourceError> {
    let mut handles = handles.borrow_mut();
    let entry = match handles.iter().position(|(k, _)| *k == key) {
        Some(at) => handles.remove(at),
        None => {
            let ds = open()?;
            if handles.len() >= limit {
                handles.remove(0);
            }
            (key, ds)
        }
    };
    handles.push(entry);
    f(&handles.last().expect("just pushed").1)
}

impl Store {
    pub(super) fn blocks_across(&self, level: usize) -> usize {
        self.levels[level].width.div_ceil(BLOCK)
    }

    /// The stamp of a block: its key in the cache changes with it.
    fn stamp(&self, level: usize, bx: usize, by: usize) -> u32 {
        self.stamps[level][by * self.blocks_across(level) + bx]
    }

    pub(super) fn key(&self, level: usize, bx: usize, by: usize) -> BlockKey {
        BlockKey {
            raster: self.uid,
            level: level as u8,
            bx: bx as u32,
            by: by as u32,
            stamp: self.stamp(level, bx, by),
        }
    }

    /// Block (bx, by) of `level`.
    pub(crate) fn block(&self, level: usize, bx: usize, by: usize) -> Result<Arc<Block>, SourceError> {
        if level == 0
            && let Some(pinned) = &self.pinned
        {
            return Ok(Arc::clone(&pinned[by * self.blocks_across(0) + bx]));
        }
        let key = self.key(level, bx, by);
        cache()
            .try_get_with(key, || self.load(level, bx, by).map(Arc::new))
            .map_err(|e| Arc::try_unwrap(e).unwrap_or_else(|e| SourceError::format(e.to_string(), &self.path)))
    }

    /// Block (bx, by) of `level` if the cache holds it (never read).
    pub(crate) fn peek(&self, level: usize, bx: usize, by: usize) -> Option<Arc<Block>> {
        let key = self.key(level, bx, by);
        cache().get(&key)
    }

    /// Puts a block just read into the cache (a reload that read it anyway).
    pub(crate) fn keep(&self, level: usize, bx: usize, by: usize, block: Arc<Block>) {
        let key = self.key(level, bx, by);
        cache().insert(key, block);
    }

    /// The pixels of block (bx, by) of `level`, rectangle of that level.
    pub(crate) fn block_rect(&self, level: usize, bx: usize, by: usize) -> PixelRect {
        let l = &self.levels[level];
        let (x0, y0) = (bx * BLOCK, by * BLOCK);
        PixelRect { x0, y0, x1: (x0 + BLOCK).min(l.width), y1: (y0 + BLOCK).min(l.height) }
    }

    /// Reads or makes a block that is not in the cache.
    pub(crate) fn load(&self, level: usize, bx: usize, by: usize) -> Result<Block, SourceError> {
        let rect = self.block_rect(level, bx, by);
        let info = &self.levels[level];
        if level == 0 || info.overview.is_some() {
            let pixels = self.read_pixels(info.overview, rect)?;
            return Ok(Block { width: rect.width(), height: rect.height(), pixels });
        }
        // No overview of this size: halve the level below over this block.
        let below = &self.levels[level - 1];
        let under = PixelRect {
            x0: 2 * rect.x0,
            y0: 2 * rect.y0,
            x1: (2 * rect.x1).min(below.width),
            y1: (2 * rect.y1).min(below.height),
        };
        let w = self.window(level - 1, under)?;
        let columns: Vec<f64> = (under.x0..under.x1).map(|x| below.column_cover(x)).collect();
        let rows: Vec<f64> = (under.y0..under.y1).map(|y| below.row_cover(y)).collect();
        let covers = Covers { columns: &columns, rows: &rows };
        let planes = w
            .planes
            .iter()
            .map(|p| halve_window(p, w.width, w.height, covers, (rect.width(), rect.height()), self.halving))
            .collect();
        Ok(Block { width: rect.width(), height: rect.height(), pixels: Pixels::Planes(planes) })
    }

    /// Decodes a rectangle of the file (base level or an overview), checking
    /// that the file is the version this store describes before and after:
    /// a writer at work makes the read fail as `Changing`, never half-read.
    pub(crate) fn read_file(&self, overview: Option<usize>, rect: PixelRect) -> Result<Vec<Vec<f32>>, SourceError> {
        self.read_pixels(overview, rect).map(Pixels::into_planes)
    }

    /// `read_file`, keeping 16-bit heights as they are stored where they
    /// can be (`Pixels::Int16`).
    fn read_pixels(&self, overview: Option<usize>, rect: PixelRect) -> Result<Pixels, SourceError> {
        let changing = || SourceError::Changing { path: self.path.clone() };
        if super::FileStamp::of(&self.path) != Some(self.file_stamp) {
            return Err(changing());
        }
        let level = overview.and_then(|o| self.levels.iter().position(|l| l.overview == Some(o)));
        let info = &self.levels[level.unwrap_or(0)];
        let size = (info.width, info.height);
        // Heights read as stored stay 16-bit where the header found the
        // level can (`LevelInfo::kept_i16`): from the file's blocks decoded
        // here, a mosaic's members, or GDAL's read of an Int16 band.
        let mut members_tried = false;
        if info.kept_i16() {
            let values = match (&self.tiling, &self.native) {
                (Some(tiling), _) => {
                    // What the members cannot give as i16, they cannot as f32.
                    members_tried = true;
                    tiling.read_i16(level.unwrap_or(0), rect)?
                }
                // None for a block that will not decode: the read below
                // says what is wrong.
                (None, Some(native)) if native.decodes(size) => native.read_i16(size, rect),
                // The same GDAL read as `Decoder::read`, not widened.
                _ => with_dataset(self.version, &self.open_path, |ds| {
                    self.decoder.read_i16(ds, overview, rect, &self.path)
                })?,
            };
            if let Some(values) = values {
                let nodata = self.decoder.nodata().and_then(exact_i16);
                return self.read_done(rect, Pixels::Int16 { values, nodata });
            }
        }
        let from_members = match &self.tiling {
            Some(tiling) if !members_tried => tiling.read(level.unwrap_or(0), rect)?,
            _ => None,
        };
        let decoded_here = || self.native.as_ref()?.read(size, rect);
        let mut planes = match from_members.or_else(decoded_here) {
            Some(values) => vec![self.decoder.to_heights(values, None)],
            None => {
                with_dataset(self.version, &self.open_path, |ds| self.decoder.read(ds, overview, rect, &self.path))?
            }
        };
        let level = level.map(|l| &self.levels[l]);
        for hole in &self.holes {
            let hole = level.map_or(*hole, |l| hole.on_level(l));
            let (x0, x1) = (hole.x0.max(rect.x0), hole.x1.min(rect.x1));
            let (y0, y1) = (hole.y0.max(rect.y0), hole.y1.min(rect.y1));
            let fill = if self.halving == Halving::ColorMean { 0.0 } else { f32::NAN };
            for plane in &mut planes {
                for y in y0..y1 {
                    for x in x0..x1 {
                        plane[(y - rect.y0) * rect.width() + (x - rect.x0)] = fill;
                    }
                }
            }
        }
        self.read_done(rect, Pixels::Planes(planes))
    }

    /// A read of `rect` ends: the file must still be the version read.
    fn read_done(&self, rect: PixelRect, pixels: Pixels) -> Result<Pixels, SourceError> {
        if super::FileStamp::of(&self.path) != Some(self.file_stamp) {
            return Err(SourceError::Changing { path: self.path.clone() });
        }
        self.bytes_read.fetch_add((rect.width() * rect.height() * self.bytes_per_pixel) as u64, Ordering::Relaxed);
        Ok(pixels)
    }

    /// The pixels of `rect` of `level`, from the blocks under it, a row
    /// of blocks at a time, each row of pixels written once and in order.
    pub(crate) fn window(&self, level: usize, rect: PixelRect) -> Result<Window, SourceError> {
        let (width, height) = (rect.width(), rect.height());
        let mut planes: Vec<Vec<f32>> = (0..self.decoder.planes()).map(|_| Window::plane(width * height)).collect();
        if width == 0 || height == 0 {
            return Ok(Window { width, height, planes });
        }
        let (bx0, bx1) = (rect.x0 / BLOCK, (rect.x1 - 1) / BLOCK);
        for by in rect.y0 / BLOCK..=(rect.y1 - 1) / BLOCK {
            let row: Vec<Arc<Block>> = (bx0..=bx1).map(|bx| self.block(level, bx, by)).collect::<Result<_, _>>()?;
            let top = by * BLOCK;
            for (p, plane) in planes.iter_mut().enumerate() {
                for y in rect.y0.max(top)..rect.y1.min(top + BLOCK) {
                    for (block, left) in row.iter().zip((bx0..).map(|bx| bx * BLOCK)) {
                        let (x0, x1) = (rect.x0.max(left), rect.x1.min(left + block.width));
                        block.extend(p, (y - top) * block.width + (x0 - left), x1 - x0, plane);
                    }
                }
            }
        }
        // Blocks tile their level: every pixel of a rectangle on it came from one.
        if planes.iter().any(|p| p.len() != width * height) {
            return Err(SourceError::format(format!("pixels {rect:?} of level {level} lie past its edge"), &self.path));
        }
        Ok(Window { width, height, planes })
    }
}
