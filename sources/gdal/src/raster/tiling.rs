//! A VRT mosaic read file by file. A mosaic as `gdalbuildvrt` writes it
//! places every member pixel for pixel; its members' own pixels, and their
//! own overviews for the VRT's implicit ones, are then what a read through
//! the VRT gives, without it. Two costs go: GDAL's VRT machinery on every
//! block (a coarse level over 400 files is 400 reads of parts of files),
//! and opening the VRT again for every new version on every thread. Each
//! member is checked once per version of its file for all threads (its
//! band, and the plan for decoding its blocks here), so a reload after
//! one member's edit opens that member alone, and a member relief decodes
//! is read without opening it through GDAL on every thread.
//!
//! Anything else a VRT may do (scaling, lookup tables, resampling, masks,
//! overlaps with transparency aside, other data types, overviews of its
//! own) leaves the raster read through GDAL's VRT, as before.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use gdal::Dataset;
use gdal::raster::RasterBand;
use moka::sync::Cache;
use relief_source::SourceError;

use super::blocks::kept_open;
use super::decode::{read_values, read_window};
use super::native::Native;
use super::pixels::exact_i16;
use super::vrt::Members;
use super::{FileStamp, PixelRect, format_err};

/// GDAL handles of members each thread keeps, for members GDAL reads (an
/// open GeoTIFF is a file descriptor and its directory in memory).
const HANDLES_PER_THREAD: usize = 32;

/// How to read one band of a mosaic from its members.
#[derive(Debug, Clone)]
pub(crate) struct Tiling {
    members: Vec<Member>,
    /// What a pixel no member covers holds: the VRT band's nodata, else 0.
    fill: f32,
    /// The VRT's overviews are its members' (it has none of its own).
    member_overviews: bool,
    /// The mosaic's size in base pixels.
    size: (usize, usize),
    /// The band's data type, as GDAL names it: every member's too.
    data_type: String,
    /// Members by file, where a file is placed once.
    placed_once: HashMap<PathBuf, usize>,
}

#[derive(Debug, Clone)]
struct Member {
    path: PathBuf,
    /// The file as this version of the mosaic found it.
    stamp: FileStamp,
    band: usize,
    /// Its pixels, in the mosaic's base pixels.
    at: PixelRect,
    /// Its pixels of this value leave what is under them.
    nodata: Option<f64>,
}

impl Tiling {
    /// The plan for band `band` of the VRT `vrt` (opened from `path`), whose
    /// sources are `sources`; None when the VRT does more than place whole
    /// files of the band's data type pixel for pixel.
    pub(super) fn plan(members: &Members, band: usize, vrt: &Dataset, path: &Path) -> Option<Self> {
        if members.hides_nodata {
            return None;
        }
        let (sources, own_overviews) = (&members.sources, members.own_overviews);
        let vrt_band = vrt.rasterband(band).ok()?;
        let flags = vrt_band.mask_flags().ok()?;
        if !(flags.is_all_valid() || flags.is_nodata()) {
            return None;
        }
        let data_type = vrt_band.band_type().name();
        let size = vrt.raster_size();
        let whole = |v: f64| (v >= 0.0 && v.fract() == 0.0).then_some(v as usize);
        let mut members = Vec::new();
        for source in sources.iter().filter(|s| s.band == band) {
            let (Some(src), Some(dst)) = (source.src, source.dst) else { return None };
            let [sx, sy, sw, sh] = src.map(whole);
            let [dx, dy, dw, dh] = dst.map(whole);
            let (dx, dy, w, h) = (dx?, dy?, dw?, dh?);
            let placed_whole = sx == Some(0) && sy == Some(0) && sw == Some(w) && sh == Some(h);
            if !source.plain
                || !placed_whole
                || source.file_size != Some((w, h))
                || source.data_type.as_deref() != Some(data_type.as_str())
                || dx + w > size.0
                || dy + h > size.1
            {
                return None;
            }
            members.push(Member {
                path: source.file.clone(),
                stamp: FileStamp::of(&source.file)?,
                band: source.file_band,
                at: PixelRect { x0: dx, y0: dy, x1: dx + w, y1: dy + h },
                nodata: source.nodata,
            });
        }
        if members.is_empty() {
            return None;
        }
        let own_overviews = own_overviews || PathBuf::from(format!("{}.ovr", path.display())).exists();
        let mut placed_once = HashMap::new();
        let mut twice = Vec::new();
        for (i, m) in members.iter().enumerate() {
            if placed_once.insert(m.path.clone(), i).is_some() {
                twice.push(m.path.clone());
            }
        }
        for path in twice {
            placed_once.remove(&path);
        }
        Some(Self {
            members,
            placed_once,
            fill: vrt_band.no_data_value().map_or(0.0, |v| v as f32),
            member_overviews: !own_overviews,
            size,
            data_type,
        })
    }

    /// The same plan for the members as `stamped` finds them now (a
    /// mosaic whose VRT is unchanged); None when a member is not there.
    pub(super) fn restamped(&self, stamped: &[(PathBuf, Option<FileStamp>)]) -> Option<Self> {
        let now: HashMap<&Path, Option<FileStamp>> = stamped.iter().map(|(p, s)| (p.as_path(), *s)).collect();
        let mut next = self.clone();
        for member in &mut next.members {
            member.stamp = match now.get(member.path.as_path()) {
                Some(stamp) => (*stamp)?,
                None => FileStamp::of(&member.path)?,
            };
        }
        Some(next)
    }

    /// Where the member `path` lies in the mosaic's base pixels (its
    /// origin) and its size, when it is one member placed once.
    pub(super) fn placement(&self, path: &Path) -> Option<((f64, f64), (usize, usize))> {
        let at = &self.members[*self.placed_once.get(path)?].at;
        Some(((at.x0 as f64, at.y0 as f64), (at.width(), at.height())))
    }

    /// The values (as the files hold them) of `rect` of the level `level`
    /// halvings above the base, from the members: the base from their own
    /// pixels, a coarser level from their overviews of exactly its size.
    /// None when a member cannot give that level so (the caller reads
    /// through the VRT). A member changed since the plan fails the read as
    /// `Changing`.
    pub(super) fn read(&self, level: usize, rect: PixelRect) -> Result<Option<Vec<f32>>, SourceError> {
        self.read_as(level, rect, self.fill)
    }

    /// The mosaic holds 16-bit signed integers that `read_i16` gives.
    pub(super) fn holds_i16(&self) -> bool {
        self.fill_i16().is_some()
    }

    /// True when `read_i16` gives level `level`, as far as the plan tells
    /// without opening a member: not a level the members have no overviews
    /// for, nor one whose grid a member does not start on. (A member
    /// without an overview of that size is found only by reading it.)
    pub(super) fn gives_i16(&self, level: usize) -> bool {
        self.holds_i16()
            && (level == 0
                || self.member_overviews && self.members.iter().all(|m| m.on_level(1 << level, self.size).is_some()))
    }

    /// The fill as a 16-bit integer, for a mosaic of Int16 files whose
    /// fill is one.
    fn fill_i16(&self) -> Option<i16> {
        exact_i16(self.fill).filter(|_| self.data_type == "Int16")
    }

    /// The same values as the 16-bit signed integers a mosaic of Int16
    /// files holds (None for any other, or one whose fill is no such integer).
    pub(super) fn read_i16(&self, level: usize, rect: PixelRect) -> Result<Option<Vec<i16>>, SourceError> {
        match self.fill_i16() {
            Some(fill) => self.read_as(level, rect, fill),
            None => Ok(None),
        }
    }

    fn read_as<T: Value>(&self, level: usize, rect: PixelRect, fill: T) -> Result<Option<Vec<T>>, SourceError> {
        if level > 0 && !self.member_overviews {
            return Ok(None);
        }
        let factor = 1usize << level;
        let mut values = vec![fill; rect.width() * rect.height()];
        for member in &self.members {
            let Some(at) = member.on_level(factor, self.size) else { return Ok(None) };
            let part = PixelRect {
                x0: at.x0.max(rect.x0),
                y0: at.y0.max(rect.y0),
                x1: at.x1.min(rect.x1),
                y1: at.y1.min(rect.y1),
            };
            if part.x0 >= part.x1 || part.y0 >= part.y1 {
                continue;
            }
            let inside =
                PixelRect { x0: part.x0 - at.x0, y0: part.y0 - at.y0, x1: part.x1 - at.x0, y1: part.y1 - at.y0 };
            let Some(read) = member.read::<T>(level, (at.width(), at.height()), inside, &self.data_type)? else {
                return Ok(None);
            };
            let transparent = member.nodata.map_or(T::NONE, T::nodata);
            for (row, y) in (part.y0..part.y1).enumerate() {
                let from = &read[row * inside.width()..(row + 1) * inside.width()];
                let to = (y - rect.y0) * rect.width() + (part.x0 - rect.x0);
                for (out, &v) in values[to..to + inside.width()].iter_mut().zip(from) {
                    if !v.is(transparent) {
                        *out = v;
                    }
                }
            }
        }
        Ok(Some(values))
    }
}

/// What a mosaic's values are read as: f32, or the 16-bit signed
/// integers an Int16 mosaic holds.
trait Value: Copy {
    /// What a member's nodata value matches (`NONE`: nothing).
    type Nodata: Copy;
    const NONE: Self::Nodata;
    fn nodata(value: f64) -> Self::Nodata;
    /// This value is the member's nodata: transparent.
    fn is(self, nodata: Self::Nodata) -> bool;
    /// The values of `rect` of an image of `size` pixels, decoded by relief.
    fn decode(native: &Native, size: (usize, usize), rect: PixelRect) -> Option<Vec<Self>>;
    /// The values of `rect` of `band` (of the mosaic's type), read by GDAL.
    fn read(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Vec<Self>, SourceError>;
}

impl Value for f32 {
    type Nodata = Option<f32>;
    const NONE: Option<f32> = None;

    fn nodata(value: f64) -> Option<f32> {
        Some(value as f32)
    }

    fn is(self, nodata: Option<f32>) -> bool {
        nodata.is_some_and(|nd| self == nd || (nd.is_nan() && self.is_nan()))
    }

    fn decode(native: &Native, size: (usize, usize), rect: PixelRect) -> Option<Vec<Self>> {
        native.read(size, rect)
    }

    fn read(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Vec<Self>, SourceError> {
        read_window(band, rect, path)
    }
}

impl Value for i16 {
    /// Out of i16's range: matches nothing.
    type Nodata = i32;
    const NONE: i32 = i32::MIN;

    fn nodata(value: f64) -> i32 {
        exact_i16(value as f32).map_or(Self::NONE, i32::from)
    }

    fn is(self, nodata: i32) -> bool {
        i32::from(self) == nodata
    }

    fn decode(native: &Native, size: (usize, usize), rect: PixelRect) -> Option<Vec<Self>> {
        native.read_i16(size, rect)
    }

    fn read(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Vec<Self>, SourceError> {
        read_values::<i16>(band, rect, path)
    }
}

impl Member {
    /// Its pixels on a level `factor` base pixels a pixel, when its edges
    /// fall on that level's pixel edges (or the mosaic's own edge).
    fn on_level(&self, factor: usize, size: (usize, usize)) -> Option<PixelRect> {
        let at = &self.at;
        let fits = |start: usize, end: usize, whole: usize| {
            start.is_multiple_of(factor) && (end.is_multiple_of(factor) || end == whole)
        };
        (fits(at.x0, at.x1, size.0) && fits(at.y0, at.y1, size.1)).then(|| PixelRect {
            x0: at.x0 / factor,
            y0: at.y0 / factor,
            x1: at.x1.div_ceil(factor),
            y1: at.y1.div_ceil(factor),
        })
    }

    /// `rect` of its band (level 0) or of its overview of `size` pixels;
    /// None when it has no overview of that size, or when the file is not
    /// as the VRT describes it (another size or data type: GDAL's VRT then
    /// converts, and reads it).
    fn read<T: Value>(
        &self,
        level: usize,
        size: (usize, usize),
        rect: PixelRect,
        data_type: &str,
    ) -> Result<Option<Vec<T>>, SourceError> {
        let changing = || SourceError::Changing { path: self.path.clone() };
        if FileStamp::of(&self.path) != Some(self.stamp) {
            return Err(changing());
        }
        let checked = checked(self)?;
        if checked.size != (self.at.width(), self.at.height()) || checked.data_type != data_type {
            return Ok(None);
        }
        let image = if level == 0 { checked.size } else { size };
        let decoded = checked.native.as_ref().and_then(|n| T::decode(n, image, rect));
        let values = match decoded {
            Some(values) => Some(values),
            None => with_member(self, |ds| {
                let band = ds.rasterband(self.band).map_err(|e| format_err(e, &self.path))?;
                if level == 0 {
                    return T::read(&band, rect, &self.path).map(Some);
                }
                let count = band.overview_count().unwrap_or(0).max(0) as usize;
                let overview = (0..count).filter_map(|i| band.overview(i).ok()).find(|o| o.size() == size);
                overview.map(|o| T::read(&o, rect, &self.path)).transpose()
            })?,
        };
        if FileStamp::of(&self.path) != Some(self.stamp) {
            return Err(changing());
        }
        Ok(values)
    }
}

/// What one version of a member's file is, found once for every thread:
/// its band's size and type, and the plan for decoding its blocks here
/// when it is a plain GeoTIFF (GDAL reads it otherwise).
struct Checked {
    /// The version of the file checked.
    stamp: FileStamp,
    size: (usize, usize),
    data_type: String,
    native: Option<Native>,
}

/// Members whose check is kept (each plan holds the file open). A
/// mosaic's first frame reads every member: checked once, not on each
/// thread, and read without opening GDAL at all where relief decodes it.
const CHECKED_MEMBERS: u64 = 512;

/// The check of `member`'s file as its stamp says (a member written since
/// is checked afresh).
fn checked(member: &Member) -> Result<Arc<Checked>, SourceError> {
    static CHECKED: OnceLock<Cache<(PathBuf, usize), Arc<Checked>>> = OnceLock::new();
    let cache = CHECKED.get_or_init(|| Cache::new(CHECKED_MEMBERS));
    let key = (member.path.clone(), member.band);
    if let Some(checked) = cache.get(&key).filter(|c| c.stamp == member.stamp) {
        return Ok(checked);
    }
    let ds = super::open_dataset(&member.path)?;
    let band = ds.rasterband(member.band).map_err(|e| format_err(e, &member.path))?;
    let checked = Arc::new(Checked {
        stamp: member.stamp,
        size: band.size(),
        data_type: band.band_type().name(),
        native: Native::plan(&ds, member.band, &member.path).filter(|n| n.stamp == member.stamp),
    });
    cache.insert(key, Arc::clone(&checked));
    Ok(checked)
}

thread_local! {
    /// Members open on this thread for GDAL to read, by path and stamp.
    static MEMBERS: RefCell<Vec<((PathBuf, FileStamp), Dataset)>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` on this thread's handle of `member` as its stamp says (a
/// member written since is opened afresh, never read through a handle that
/// may hold its old directory or blocks).
fn with_member<T>(member: &Member, f: impl FnOnce(&Dataset) -> Result<T, SourceError>) -> Result<T, SourceError> {
    let key = (member.path.clone(), member.stamp);
    MEMBERS.with(|handles| kept_open(handles, key, HANDLES_PER_THREAD, || super::open_dataset(&member.path), f))
}

#[cfg(test)]
mod tests {
    use gdal::DriverManager;
    use gdal::raster::{Buffer, RasterCreationOptions};

    use super::*;
    use crate::raster::vrt;

    const NODATA: i16 = -32768;

    /// An Int16 member of `side` pixels at pixel (x, y) of a 1e-3 degree
    /// grid, tiled and compressed, with AVERAGE overviews 2, 4, 8, and a
    /// nodata hole: values vary with place so misplacement shows.
    fn member(path: &Path, (x, y): (usize, usize), side: usize, seed: i32) -> Result<(), Box<dyn std::error::Error>> {
        let driver = DriverManager::get_driver_by_name("GTiff")?;
        let options =
            RasterCreationOptions::from_iter(["TILED=YES", "BLOCKXSIZE=64", "BLOCKYSIZE=64", "COMPRESS=DEFLATE"]);
        let mut ds = driver.create_with_band_type_with_options::<i16, _>(path, side, side, 1, &options)?;
        ds.set_geo_transform(&[10.0 + x as f64 * 1e-3, 1e-3, 0.0, 46.0 - y as f64 * 1e-3, 0.0, -1e-3])?;
        let mut band = ds.rasterband(1)?;
        band.set_no_data_value(Some(f64::from(NODATA)))?;
        let values: Vec<i16> = (0..side * side)
            .map(|k| {
                let (i, j) = ((k % side) as i32, (k / side) as i32);
                let hole = (10..20).contains(&i) && (30..45).contains(&j);
                if hole { NODATA } else { (seed + 7 * i - 3 * j + (i * j) % 11) as i16 }
            })
            .collect();
        band.write((0, 0), (side, side), &mut Buffer::new((side, side), values))?;
        ds.build_overviews("AVERAGE", &[2, 4, 8], &[])?;
        Ok(())
    }

    fn build_vrt(dir: &Path, files: &[PathBuf]) -> PathBuf {
        let vrt = dir.join("mosaic.vrt");
        let status = std::process::Command::new("gdalbuildvrt")
            .arg("-q")
            .arg(&vrt)
            .args(files)
            .status()
            .expect("gdalbuildvrt (gdal-bin) is installed");
        assert!(status.success());
        vrt
    }

    /// Every level the plan reads from the members, against the same
    /// rectangles read through GDAL's VRT (the base and each overview).
    fn assert_same_as_the_vrt(vrt: &Path, expect_levels: usize) -> Result<(), Box<dyn std::error::Error>> {
        let members = vrt::members(vrt)?;
        let ds = Dataset::open(vrt)?;
        let tiling = Tiling::plan(&members, 1, &ds, vrt).ok_or("no plan")?;
        let band = ds.rasterband(1)?;
        let mut levels = 0;
        for level in 0..=band.overview_count()? as usize {
            let through = if level == 0 { ds.rasterband(1)? } else { band.overview(level - 1)? };
            let (w, h) = through.size();
            // The whole level, and a window across members' edges.
            for rect in
                [PixelRect { x0: 0, y0: 0, x1: w, y1: h }, PixelRect { x0: w / 3, y0: h / 4, x1: w - 1, y1: h / 2 + 3 }]
            {
                let direct = tiling.read(level, rect)?.ok_or(format!("level {level} not read from the members"))?;
                let size = (rect.width(), rect.height());
                let expected = through.read_as::<i16>((rect.x0 as isize, rect.y0 as isize), size, size, None)?;
                let expected: Vec<f32> = expected.data().iter().map(|&v| f32::from(v)).collect();
                assert_eq!(direct, expected, "level {level}, {rect:?}");
                // As the members' 16-bit integers: the same values.
                let narrow = tiling.read_i16(level, rect)?.ok_or(format!("level {level} not read as i16"))?;
                assert_eq!(narrow.into_iter().map(f32::from).collect::<Vec<f32>>(), expected, "level {level} as i16");
            }
            levels += 1;
        }
        assert_eq!(levels, expect_levels, "the VRT's levels");
        Ok(())
    }

    #[test]
    fn a_mosaic_read_from_its_members_equals_its_vrt_at_every_level() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let mut files = Vec::new();
        // GDAL 3.6 shows a VRT's implicit overviews down to 256 pixels:
        // members of 1024 give three.
        for (n, (i, j)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let path = dir.path().join(format!("m{n}.tif"));
            member(&path, (i * 1024, j * 1024), 1024, 100 * n as i32)?;
            files.push(path);
        }
        assert_same_as_the_vrt(&build_vrt(dir.path(), &files), 4)
    }

    #[test]
    fn overlapping_members_show_through_each_others_nodata() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let (a, b) = (dir.path().join("a.tif"), dir.path().join("b.tif"));
        member(&a, (0, 0), 128, 0)?;
        // Half over the first, its hole over the first's pixels.
        member(&b, (64, 8), 128, 500)?;
        assert_same_as_the_vrt(&build_vrt(dir.path(), &[a, b]), 1)
    }

    #[test]
    fn a_member_no_longer_as_its_vrt_describes_is_left_to_gdal() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let a = dir.path().join("a.tif");
        member(&a, (0, 0), 64, 0)?;
        let vrt = build_vrt(dir.path(), std::slice::from_ref(&a));
        let members = vrt::members(&vrt)?;
        let ds = Dataset::open(&vrt)?;
        // Written again at another size after the VRT was built.
        member(&a, (0, 0), 48, 0)?;
        let tiling = Tiling::plan(&members, 1, &ds, &vrt).ok_or("no plan")?;
        assert_eq!(tiling.read(0, PixelRect { x0: 0, y0: 0, x1: 8, y1: 8 })?, None);
        assert_eq!(tiling.read_i16(0, PixelRect { x0: 0, y0: 0, x1: 8, y1: 8 })?, None);
        Ok(())
    }

    #[test]
    fn a_vrt_that_does_more_than_place_files_is_read_through_gdal() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let a = dir.path().join("a.tif");
        member(&a, (0, 0), 64, 0)?;
        let vrt = build_vrt(dir.path(), &[a]);
        let plain = std::fs::read_to_string(&vrt)?;
        let odd = [
            plain.replace("<NODATA>", "<ScaleRatio>2</ScaleRatio><NODATA>"),
            plain.replace("<ColorInterp>", "<HideNoDataValue>1</HideNoDataValue><ColorInterp>"),
        ];
        for text in odd {
            std::fs::write(&vrt, &text)?;
            let members = vrt::members(&vrt)?;
            let ds = Dataset::open(&vrt)?;
            assert!(Tiling::plan(&members, 1, &ds, &vrt).is_none(), "{text}");
        }
        Ok(())
    }
}
