//! A reload: the changed blocks found from the files' signatures, read,
//! compared with the old pixels, and the stamps above them bumped.

use std::sync::Arc;

use rayon::prelude::*;
use relief_source::SourceError;

use super::blocks::BLOCK;
use super::changes::{ChangeDetection, Changes, Signatures};
use super::pixels::Block;
use super::{PixelRect, Raster, ReadOptions, Store};

/// What a reload found.
#[derive(Debug)]
pub(crate) enum Reloaded {
    /// Same size, georeferencing and pixels: the same data under the
    /// files' new fingerprint.
    Same(Raster),
    /// Same size and georeferencing; these pixels changed.
    Pixels(Raster, Vec<PixelRect>),
    /// Size, georeferencing, CRS or kind changed: everything did.
    Everything(Raster),
}

/// A base block a reload read: where, its new pixels, what of it changed.
type ReadBlock = ((usize, usize), Arc<Block>, Vec<PixelRect>);

/// Side of the square blocks compared on reload.
const DIFF_BLOCK: usize = 64;

impl Raster {
    /// Finds the blocks' signatures in the background, for the next reload.
    pub(super) fn sign_in_background(&self, mode: ChangeDetection) {
        let (raster, cell) = (self.clone(), Arc::clone(&self.store.signatures));
        let spawned = std::thread::Builder::new().name("relief-sign".into()).spawn(move || {
            let t = std::time::Instant::now();
            let signed = Signatures::of(&raster, mode, None, true);
            let still = matches!(raster.files_changed(), Ok(false));
            tracing::debug!(ms = t.elapsed().as_secs_f64() * 1e3, ok = signed.is_ok(), "raster blocks signed");
            let _ = cell.set(signed.ok().filter(|_| still));
        });
        if spawned.is_err() {
            let _ = self.store.signatures.set(None);
        }
    }

    /// Reads the file's header again and finds what changed: the blocks
    /// whose signatures differ from the last version's are read (no other),
    /// and compared in 64 x 64 pieces with the old pixels where those are
    /// at hand (a raster read whole always has them; a windowed one when
    /// the cache does); the pieces that differ, narrowed to the pixels
    /// that changed in them, are the dirt. The mip levels above change
    /// only there.
    pub(crate) fn reload(&self, options: &ReadOptions) -> Result<Reloaded, SourceError> {
        let t = std::time::Instant::now();
        let header = match self.header_again(options)? {
            Some(header) => header,
            None => Self::header(&self.path, options)?,
        };
        let fresh = &header.raster;
        let same_frame = fresh.size == self.size
            && fresh.geo == self.geo
            && fresh.crs_wkt == self.crs_wkt
            && fresh.kind == self.kind
            && fresh.units == self.units
            && header.decoder == self.store.decoder
            // Levels alike in size, overviews and in how the cache keeps
            // their blocks (a file turned from Int16 to Float32 is read
            // again whole: no block of it could be kept as it was).
            && header.levels == self.store.levels
            && fresh.missing == self.missing;
        if !same_frame {
            return Self::open(&self.path, options).map(Reloaded::Everything);
        }
        let whole = !self.windowed();
        let mut raster = header.into_raster(self.store.uid, Some(&self.store))?;
        let (bw, bh) = (self.width().div_ceil(BLOCK), self.height().div_ceil(BLOCK));
        let old = self.store.signatures.wait().as_ref();
        let signatures = Signatures::of(&raster, options.changes, old, false)?;
        let everything = || Changes {
            base: vec![PixelRect { x0: 0, y0: 0, x1: self.width(), y1: self.height() }],
            overviews: Vec::new(),
        };
        let changes = match old {
            // An object's new ETag is new bytes: when its block tables are
            // as they were, a block was rewritten in place at its old size
            // (which the layout cannot tell), so every block is read and
            // compared. A file's stamp also moves when it is merely touched.
            Some(old) if relief_source::objects::is_object(&self.path) => {
                let found = old.diff(&signatures, self.size);
                if found.base.is_empty() && found.overviews.is_empty() { everything() } else { found }
            }
            Some(old) => old.diff(&signatures, self.size),
            None => everything(),
        };
        let rects = &changes.base;
        let mut candidates: Vec<(usize, usize)> = rects
            .iter()
            .flat_map(|r| {
                let b = r.shrink(BLOCK);
                (b.y0..b.y1.min(bh)).flat_map(move |y| (b.x0..b.x1.min(bw)).map(move |x| (x, y)))
            })
            .collect();
        candidates.sort_unstable_by_key(|&(x, y)| (y, x));
        candidates.dedup();
        tracing::debug!(ms = t.elapsed().as_secs_f64() * 1e3, blocks = candidates.len(), "raster changes found");
        // Read the candidate blocks of the new version, compare with the old.
        let new_store = &raster.store;
        let read: Vec<ReadBlock> = candidates
            .par_iter()
            .map(|&(bx, by)| {
                let new = Arc::new(new_store.load(0, bx, by)?);
                let old = self.store.cached(0, bx, by);
                let origin = (bx * BLOCK, by * BLOCK);
                let rects = match old {
                    Some(old) => diff_blocks(&old.planes(), &new.planes(), new.width, new.height),
                    None => vec![PixelRect { x0: 0, y0: 0, x1: new.width, y1: new.height }],
                };
                let rects = rects
                    .into_iter()
                    .map(|r| PixelRect {
                        x0: r.x0 + origin.0,
                        y0: r.y0 + origin.1,
                        x1: r.x1 + origin.0,
                        y1: r.y1 + origin.1,
                    })
                    .collect();
                Ok(((bx, by), new, rects))
            })
            .collect::<Result<_, SourceError>>()?;
        if raster.files_changed()? {
            return Err(SourceError::Changing { path: self.path.clone() });
        }
        let mut rects: Vec<PixelRect> = read.iter().flat_map(|(_, _, r)| r.iter().copied()).collect();
        // An overview block that changed where no base pixel did is a change
        // of its own (overviews rebuilt); one over changed base pixels came
        // with them, and the stamps above those pixels are bumped anyway.
        let overlaps = |a: &PixelRect, b: &PixelRect| a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
        let own: Vec<PixelRect> =
            changes.overviews.iter().filter(|o| !rects.iter().any(|r| overlaps(o, r))).copied().collect();
        rects.extend(own);
        let mut store = new_store.fork(self.store.uid);
        store.bump(&rects);
        // The old version's blocks under the change are never asked for
        // by a new tile: they leave the cache when the old version goes,
        // rather than when they age out of the budget (a save a second
        // would otherwise fill it with dead blocks).
        self.store.note_replaced(&store);
        if let Some(pinned) = &mut store.pinned {
            for ((bx, by), block, changed) in &read {
                if !changed.is_empty() {
                    pinned[by * bw + bx] = Arc::clone(block);
                }
            }
        }
        let _ = store.signatures.set(Some(signatures));
        raster.store = Arc::new(store);
        if !whole {
            for ((bx, by), block, changed) in read {
                if !changed.is_empty() {
                    raster.store.keep(0, bx, by, block);
                }
            }
        }
        tracing::debug!(ms = t.elapsed().as_secs_f64() * 1e3, rects = rects.len(), "raster reloaded");
        Ok(if rects.is_empty() { Reloaded::Same(raster) } else { Reloaded::Pixels(raster, rects) })
    }
}

impl Store {
    /// Bumps the stamp of every block, at every level, over `rects` of the base.
    pub(super) fn bump(&mut self, rects: &[PixelRect]) {
        for (level, info) in self.levels.iter().enumerate() {
            let across = info.width.div_ceil(BLOCK);
            for rect in rects {
                let r = rect.on_level(info).shrink(BLOCK);
                for by in r.y0..r.y1.min(info.height.div_ceil(BLOCK)) {
                    for bx in r.x0..r.x1.min(across) {
                        let s = &mut self.stamps[level][by * across + bx];
                        *s = s.wrapping_add(1);
                    }
                }
            }
        }
    }

    /// Notes this version's blocks whose stamps `next` bumped, for `Drop`.
    pub(super) fn note_replaced(&self, next: &Store) {
        for (level, (old, new)) in self.stamps.iter().zip(&next.stamps).enumerate() {
            let across = self.blocks_across(level);
            for (i, _) in old.iter().zip(new).enumerate().filter(|(_, (o, n))| o != n) {
                self.replaced.note(self.key(level, i % across, i / across));
            }
        }
    }

    /// A block of this version if it is at hand (kept, or in the cache).
    pub(super) fn cached(&self, level: usize, bx: usize, by: usize) -> Option<Arc<Block>> {
        match &self.pinned {
            Some(pinned) if level == 0 => pinned.get(by * self.levels[0].width.div_ceil(BLOCK) + bx).cloned(),
            _ => self.peek(level, bx, by),
        }
    }
}

/// The blocks whose pixels differ (bit for bit; all NaNs alike), merged
/// into rectangles: runs along each row of blocks, then runs of equal runs
/// down the rows.
fn diff_blocks<P: AsRef<[f32]> + Sync>(old: &[P], new: &[P], width: usize, height: usize) -> Vec<PixelRect> {
    let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let (bw, bh) = (width.div_ceil(DIFF_BLOCK), height.div_ceil(DIFF_BLOCK));
    let changed: Vec<bool> = (0..bw * bh)
        .into_par_iter()
        .map(|b| {
            let (x0, y0) = ((b % bw) * DIFF_BLOCK, (b / bw) * DIFF_BLOCK);
            let (x1, y1) = ((x0 + DIFF_BLOCK).min(width), (y0 + DIFF_BLOCK).min(height));
            old.iter().zip(new).any(|(o, n)| {
                (y0..y1).any(|y| {
                    let (o, n) =
                        (&o.as_ref()[y * width + x0..y * width + x1], &n.as_ref()[y * width + x0..y * width + x1]);
                    // Plain float equality is the fast check; NaNs (nodata)
                    // fail it and get the exact one.
                    o != n && o.iter().zip(n).any(|(a, b)| !same(*a, *b))
                })
            })
        })
        .collect();
    let block_changed = |bx: usize, by: usize| changed[by * bw + bx];
    let mut rects: Vec<PixelRect> = Vec::new();
    let mut open: Vec<PixelRect> = Vec::new();
    for by in 0..bh {
        let mut runs = Vec::new();
        let mut bx = 0;
        while bx < bw {
            if block_changed(bx, by) {
                let start = bx;
                while bx < bw && block_changed(bx, by) {
                    bx += 1;
                }
                runs.push((start * DIFF_BLOCK, (bx * DIFF_BLOCK).min(width)));
            } else {
                bx += 1;
            }
        }
        let (y0, y1) = (by * DIFF_BLOCK, ((by + 1) * DIFF_BLOCK).min(height));
        let mut still_open = Vec::new();
        for rect in open.drain(..) {
            if let Some(pos) = runs.iter().position(|&(x0, x1)| x0 == rect.x0 && x1 == rect.x1) {
                runs.remove(pos);
                still_open.push(PixelRect { y1, ..rect });
            } else {
                rects.push(rect);
            }
        }
        still_open.extend(runs.into_iter().map(|(x0, x1)| PixelRect { x0, y0, x1, y1 }));
        open = still_open;
    }
    rects.extend(open);
    // Each run of changed pieces narrowed to the pixels that changed in it:
    // a 16-pixel edit is 16 pixels of dirt, not a piece's 64.
    rects.into_iter().filter_map(|r| tighten(r, old, new, width, &same)).collect()
}

/// The box of the pixels of `rect` that differ between `old` and `new`.
fn tighten<P: AsRef<[f32]>>(
    rect: PixelRect,
    old: &[P],
    new: &[P],
    width: usize,
    same: &dyn Fn(f32, f32) -> bool,
) -> Option<PixelRect> {
    let mut tight: Option<PixelRect> = None;
    for y in rect.y0..rect.y1 {
        for (o, n) in old.iter().zip(new) {
            let (o, n) = (&o.as_ref()[y * width..][rect.x0..rect.x1], &n.as_ref()[y * width..][rect.x0..rect.x1]);
            let Some(first) = o.iter().zip(n).position(|(a, b)| !same(*a, *b)) else { continue };
            let last = o.iter().zip(n).rposition(|(a, b)| !same(*a, *b)).unwrap_or(first);
            let (x0, x1) = (rect.x0 + first, rect.x0 + last + 1);
            tight = Some(match tight {
                None => PixelRect { x0, y0: y, x1, y1: y + 1 },
                Some(t) => PixelRect { x0: t.x0.min(x0), y0: t.y0, x1: t.x1.max(x1), y1: y + 1 },
            });
        }
    }
    tight
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The old version's blocks under a change (at every level), and only
    /// those, leave the cache when that version goes.
    #[test]
    fn the_replaced_blocks_leave_the_cache_with_their_version() -> Result<(), Box<dyn std::error::Error>> {
        use gdal::DriverManager;
        use gdal::raster::{Buffer, RasterCreationOptions};

        let dir = tempfile::tempdir()?;
        let path = dir.path().join("two.tif");
        let (w, h) = (1100usize, 600usize);
        {
            let driver = DriverManager::get_driver_by_name("GTiff")?;
            let options = RasterCreationOptions::from_iter(["TILED=YES", "BLOCKXSIZE=256", "BLOCKYSIZE=256"]);
            let mut ds = driver.create_with_band_type_with_options::<f32, _>(&path, w, h, 1, &options)?;
            ds.set_geo_transform(&[10.0, 0.001, 0.0, 46.0, 0.0, -0.001])?;
            ds.set_spatial_ref(&gdal::spatial_ref::SpatialRef::from_epsg(4326)?)?;
            let data: Vec<f32> = (0..w * h).map(|i| (i % 977) as f32).collect();
            ds.rasterband(1)?.write((0, 0), (w, h), &mut Buffer::new((w, h), data))?;
        }
        let options = ReadOptions {
            kind: None,
            crs_override: None,
            units_override: None,
            band: 1,
            categorical: false,
            residency: super::super::Residency::Windowed,
            changes: ChangeDetection::Exact,
            overviews: false,
        };
        let raster = Raster::open(&path, &options)?;
        // Level 1 is 550 x 300 pixels: blocks (0, 0), (1, 0), (2, 0) and the row below.
        raster.window(1, PixelRect { x0: 0, y0: 0, x1: 550, y1: 300 })?;
        let held = |r: &Raster, level: usize, bx: usize, by: usize| r.store.peek(level, bx, by).is_some();
        assert!(held(&raster, 1, 0, 0) && held(&raster, 1, 2, 1) && held(&raster, 0, 0, 0));
        {
            let ds = gdal::Dataset::open_ex(
                &path,
                gdal::DatasetOptions { open_flags: gdal::GdalOpenFlags::GDAL_OF_UPDATE, ..Default::default() },
            )?;
            ds.rasterband(1)?.write((10, 10), (4, 4), &mut Buffer::new((4, 4), vec![-5.0f32; 16]))?;
        }
        let Reloaded::Pixels(fresh, rects) = raster.reload(&options)? else {
            return Err("a pixel edit reloads as changed pixels".into());
        };
        assert!(!rects.is_empty());
        // While the old version may still serve, its blocks stay.
        assert!(held(&raster, 0, 0, 0) && held(&raster, 1, 0, 0), "dropped while the old version lives");
        // When it goes, its blocks over the edit go, at both levels; the
        // others stay, and the new version holds the same ones.
        let old = raster.store.fork(raster.store.uid);
        drop(raster);
        let held_old = |level: usize, bx: usize, by: usize| old.peek(level, bx, by).is_some();
        // (The background signing thread may hold the version a moment longer.)
        for _ in 0..300 {
            if !held_old(1, 0, 0) {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(!held_old(0, 0, 0) && !held_old(1, 0, 0), "replaced blocks still held");
        assert!(held_old(1, 1, 0) && held_old(1, 2, 1), "untouched blocks dropped");
        assert!(held(&fresh, 1, 1, 0) && !held(&fresh, 1, 0, 0));
        Ok(())
    }

    #[test]
    fn block_diffs_find_exactly_the_changed_pixels() {
        let (w, h) = (300, 200);
        let old = vec![vec![1.0f32; w * h]];
        let mut new = old.clone();
        assert!(diff_blocks(&old, &new, w, h).is_empty());
        // Two pixels in one block, and a 2 x 2 run of blocks elsewhere.
        new[0][150 * w + 10] = 2.0;
        new[0][151 * w + 40] = f32::NAN;
        for (x, y) in [(130, 5), (200, 5), (130, 70), (200, 70)] {
            new[0][y * w + x] = 3.0;
        }
        let rects = diff_blocks(&old, &new, w, h);
        // Each narrowed to the pixels that changed.
        assert!(rects.contains(&PixelRect { x0: 10, y0: 150, x1: 41, y1: 152 }), "{rects:?}");
        assert!(rects.contains(&PixelRect { x0: 130, y0: 5, x1: 201, y1: 71 }), "{rects:?}");
        assert_eq!(rects.len(), 2, "{rects:?}");
        // NaN over NaN is no change.
        let holes = vec![vec![f32::NAN; 16]];
        assert!(diff_blocks(&holes, &holes.clone(), 4, 4).is_empty());
    }
}
