//! The `gdal` source kind: a raster, or a mosaic of rasters, resampled into
//! the scene's tile grid.

use std::sync::{Arc, Once};

use gdal::errors::CplErrType;
use relief_source::{
    ColorTile, DirtySet, Extent, GenerateContext, GeodeticPoint, HeightTile, Lattice, Payload, PayloadKind, Quality,
    Refresh, Resampling, SampleKind, Source, SourceError, SourceInfo, SourceSpec, TileGrid, TileKey,
};

use crate::crs;
use crate::raster::{ChangeDetection, PixelRect, Raster, RasterKind, ReadOptions, Reloaded, Residency, VerticalUnits};
use crate::resample::{LevelAxis, Taps, axis_taps, color_from_taps, height_from_taps, heights_by_rows, level_taps};

/// The manifest kind of this source.
pub const KIND: &str = "gdal";

/// How far, in output samples, a changed source pixel can reach: the widest
/// kernel (lanczos, 3) plus one for the footprint of a mip pixel.
const DIRTY_MARGIN_SAMPLES: u32 = 4;

const OPTIONS: &[&str] = &[
    "output",
    "crs",
    "vertical_datum",
    "vertical_units",
    "band",
    "resampling",
    "read",
    "change_detection",
    "overviews",
];

/// Sets GDAL up for relief, once: its block cache and directory listing
/// (below), and its own messages routed to tracing instead of stderr
/// (every failure that matters comes back as an error value anyway).
pub fn configure_gdal() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        crate::guard::configure();
        // Reads of uncompressed GeoTIFFs skip GDAL's block cache: relief
        // keeps the decoded blocks itself.
        let _unknown_option_is_harmless = gdal::config::set_config_option("GTIFF_DIRECT_IO", "YES");
        if std::env::var_os("GDAL_CACHEMAX").is_none() {
            let _ = gdal::config::set_config_option("GDAL_CACHEMAX", crate::raster::GDAL_CACHE_MB);
        }
        // GDAL lists a file's whole folder at every open to find its side
        // files (.ovr, .aux.xml, .msk), and sorts the list. A mosaic's
        // members share a folder of hundreds of files, each opened on
        // each read thread: a first frame of a 400-file mosaic listed its
        // folder about a thousand times. Without the list GDAL asks for
        // each side file by name, and finds the same ones.
        if std::env::var_os("GDAL_DISABLE_READDIR_ON_OPEN").is_none() {
            let _ = gdal::config::set_config_option("GDAL_DISABLE_READDIR_ON_OPEN", "TRUE");
        }
        // GDAL's words can hold an object's URL: no query (a signature) in a log.
        gdal::config::set_error_handler(|class, code, msg| match class {
            CplErrType::Fatal | CplErrType::Failure => tracing::debug!(code, "gdal: {}", crate::objects::redact(msg)),
            _ => tracing::trace!(code, "gdal: {}", crate::objects::redact(msg)),
        });
        relief_source::objects::set_version_of(crate::objects::version);
    });
}

/// Kernel taps for every sample of a tile in one raster.
struct Sampler {
    mip: usize,
    /// Per column and per row when `separable`, else per sample (u and v).
    columns: Vec<Option<Taps>>,
    rows: Vec<Option<Taps>>,
    separable: bool,
}

impl Sampler {
    /// The pixels of the level the taps read (None when no sample falls on the raster).
    fn window_rect(&self) -> Option<PixelRect> {
        let span =
            |taps: &[Option<Taps>]| taps.iter().flatten().map(Taps::span).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)));
        let ((x0, x1), (y0, y1)) = (span(&self.columns)?, span(&self.rows)?);
        Some(PixelRect { x0, y0, x1: x1 + 1, y1: y1 + 1 })
    }

    /// The taps moved into a window starting at (x0, y0).
    fn shift(&mut self, rect: &PixelRect) {
        for t in self.columns.iter_mut().flatten() {
            *t = t.shifted(rect.x0);
        }
        for t in self.rows.iter_mut().flatten() {
            *t = t.shifted(rect.y0);
        }
    }

    /// Calls `f` with every sample's index (row-major, `cols` a row) and
    /// its taps, None off the raster.
    fn each(&self, cols: usize, rows: usize, mut f: impl FnMut(usize, Option<(&Taps, &Taps)>)) {
        for j in 0..rows {
            for i in 0..cols {
                let n = j * cols + i;
                let (tx, ty) =
                    if self.separable { (&self.columns[i], &self.rows[j]) } else { (&self.columns[n], &self.rows[n]) };
                f(n, tx.as_ref().zip(ty.as_ref()));
            }
        }
    }
}

/// One raster of the mosaic, placed in the scene grid.
#[derive(Debug, Clone)]
struct Placed {
    raster: Arc<Raster>,
    /// True when the raster's CRS is the grid's: pixels are then an affine
    /// function of grid coordinates and nothing goes through PROJ.
    same_crs: bool,
    extent_in_grid: Option<Extent>,
}

#[derive(Debug)]
pub struct GdalSource {
    id: String,
    spec: SourceSpec,
    kind: RasterKind,
    read: ReadOptions,
    vertical_datum: String,
    grid_crs: String,
    rasters: Vec<Placed>,
    /// The source's own kernel (`resampling`), else the scene's.
    resampling: Option<Resampling>,
}

impl GdalSource {
    /// Opens every raster of `spec` and places it in `grid`. Only the grid's
    /// CRS matters here: the source serves any grid in that CRS.
    pub fn open(spec: &SourceSpec, grid: &TileGrid) -> Result<Self, SourceError> {
        spec.only_options(OPTIONS)?;
        if spec.paths.is_empty() {
            return Err(SourceError::option("path", "a gdal source needs 'path' (or 'paths')"));
        }
        let kind = match spec.text("output")? {
            None => None,
            Some("height") => Some(RasterKind::Height),
            Some("color" | "colour") => Some(RasterKind::Color),
            Some(other) => {
                return Err(SourceError::option("output", format!("'{other}' is neither \"height\" nor \"color\"")));
            }
        };
        let units_override = match spec.text("vertical_units")? {
            None => None,
            Some("m") => Some(VerticalUnits::Metres),
            Some("ft") => Some(VerticalUnits::Feet),
            Some("us-ft") => Some(VerticalUnits::UsSurveyFeet),
            Some(other) => {
                return Err(SourceError::option("vertical_units", format!("'{other}' is not m, ft or us-ft")));
            }
        };
        let band = match spec.number("band")? {
            None => 1,
            Some(b) if b >= 1.0 && b.fract() == 0.0 => b as usize,
            Some(b) => {
                return Err(SourceError::option("band", format!("{b} is not a band number (1, 2, ...)")));
            }
        };
        let crs_override = spec.text("crs")?.map(str::to_owned);
        if let Some(def) = &crs_override {
            crs::spatial_ref(def, None)?;
        }
        // A source's own kernel wins over the scene's: a land-cover raster
        // reads "nearest" (and its mips keep classes) under a bilinear DEM.
        let resampling = spec
            .text("resampling")?
            .map(|r| r.parse::<Resampling>().map_err(|e| SourceError::option("resampling", e)))
            .transpose()?;
        let categorical = resampling == Some(Resampling::Nearest);
        let residency = match spec.text("read")? {
            None | Some("auto") => Residency::Auto,
            Some("whole") => Residency::Whole,
            Some("windowed") => Residency::Windowed,
            Some(other) => {
                return Err(SourceError::option("read", format!("'{other}' is not auto, whole or windowed")));
            }
        };
        let changes = match spec.text("change_detection")? {
            Some("exact") => ChangeDetection::Exact,
            None | Some("layout") => ChangeDetection::Layout,
            Some(other) => {
                return Err(SourceError::option("change_detection", format!("'{other}' is not layout or exact")));
            }
        };
        let overviews = spec.flag("overviews")?.unwrap_or(true);
        let read = ReadOptions { kind, crs_override, units_override, band, categorical, residency, changes, overviews };
        let rasters = spec.paths.iter().map(|p| Raster::open(p, &read)).collect::<Result<Vec<_>, _>>()?;
        let kind = rasters[0].kind;
        if let Some(odd) = rasters.iter().find(|r| r.kind != kind) {
            return Err(SourceError::format(
                format!("mosaic mixes colour and height rasters ({:?} vs {kind:?})", odd.kind),
                &odd.path,
            ));
        }
        let vertical_datum = match spec.text("vertical_datum")? {
            Some(d) => d.to_owned(),
            None if rasters[0].details.get("driver").is_some_and(|d| d == "SRTMHGT") => "EGM96 geoid (SRTM)".into(),
            None => "unknown (not stated by the file)".into(),
        };
        let grid_srs = crs::spatial_ref(grid.crs(), None)?;
        let rasters =
            rasters.into_iter().map(|raster| place(raster, grid, &grid_srs)).collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            id: spec.id.clone(),
            spec: spec.clone(),
            kind,
            read,
            vertical_datum,
            grid_crs: grid.crs().to_owned(),
            rasters,
            resampling,
        })
    }

    /// Pixel-edge coordinates of every lattice sample in `placed`'s raster.
    fn pixel_coords(
        &self,
        placed: &Placed,
        lattice: &Lattice,
        max_error_px: f64,
    ) -> Result<(Vec<f64>, Vec<f64>), SourceError> {
        let r = &placed.raster;
        let (cols, rows) = (lattice.cols, lattice.rows);
        let mut us = Vec::with_capacity(cols * rows);
        let mut vs = Vec::with_capacity(cols * rows);
        if placed.same_crs {
            for j in 0..rows {
                let y = lattice.y(j);
                for i in 0..cols {
                    let (u, v) = r.pixel_of(lattice.x(i), y);
                    us.push(u);
                    vs.push(v);
                }
            }
            return Ok((us, vs));
        }
        let to_pixels = |points: &[(usize, usize)]| -> Result<Vec<(f64, f64)>, SourceError> {
            let mut xs: Vec<f64> = points.iter().map(|&(i, _)| lattice.x(i)).collect();
            let mut ys: Vec<f64> = points.iter().map(|&(_, j)| lattice.y(j)).collect();
            crs::transform(&self.grid_crs, &r.crs_wkt, &mut xs, &mut ys)?;
            Ok(xs.iter().zip(&ys).map(|(x, y)| r.pixel_of(*x, *y)).collect())
        };
        // Transform a coarse lattice exactly and interpolate between, halving
        // the step until the interpolation error at cell centres is small
        // enough (GDAL's approximate transformer does the same per scanline).
        let mut step = 32usize.min(cols.saturating_sub(1)).max(1);
        while max_error_px > 0.0 && step > 1 {
            let idx = |n: usize| -> Vec<usize> {
                let mut v: Vec<usize> = (0..n).step_by(step).collect();
                if *v.last().expect("n > 0") != n - 1 {
                    v.push(n - 1);
                }
                v
            };
            let (ci, cj) = (idx(cols), idx(rows));
            let coarse_points: Vec<(usize, usize)> = cj.iter().flat_map(|&j| ci.iter().map(move |&i| (i, j))).collect();
            let coarse = to_pixels(&coarse_points)?;
            let centres: Vec<(usize, usize)> = cj
                .windows(2)
                .flat_map(|wj| {
                    ci.windows(2).map(move |wi| (usize::midpoint(wi[0], wi[1]), usize::midpoint(wj[0], wj[1])))
                })
                .collect();
            let exact = to_pixels(&centres)?;
            let interp = |i: usize, j: usize| -> (f64, f64) {
                let a = ci.partition_point(|&c| c <= i).clamp(1, ci.len() - 1) - 1;
                let b = cj.partition_point(|&c| c <= j).clamp(1, cj.len() - 1) - 1;
                let fx = (i - ci[a]) as f64 / (ci[a + 1] - ci[a]) as f64;
                let fy = (j - cj[b]) as f64 / (cj[b + 1] - cj[b]) as f64;
                let p = |x: usize, y: usize| coarse[y * ci.len() + x];
                let (p00, p10, p01, p11) = (p(a, b), p(a + 1, b), p(a, b + 1), p(a + 1, b + 1));
                let lerp = |s: f64, t: f64, k: fn((f64, f64)) -> f64| {
                    (1.0 - t) * ((1.0 - s) * k(p00) + s * k(p10)) + t * ((1.0 - s) * k(p01) + s * k(p11))
                };
                (lerp(fx, fy, |p| p.0), lerp(fx, fy, |p| p.1))
            };
            let worst = centres
                .iter()
                .zip(&exact)
                .map(|(&(i, j), e)| {
                    let (u, v) = interp(i, j);
                    (u - e.0).hypot(v - e.1)
                })
                .fold(0.0f64, |m, d| if d.is_nan() { f64::INFINITY } else { m.max(d) });
            if worst <= max_error_px {
                for j in 0..rows {
                    for i in 0..cols {
                        let (u, v) = interp(i, j);
                        us.push(u);
                        vs.push(v);
                    }
                }
                return Ok((us, vs));
            }
            step /= 2;
        }
        let all: Vec<(usize, usize)> = (0..rows).flat_map(|j| (0..cols).map(move |i| (i, j))).collect();
        for (u, v) in to_pixels(&all)? {
            us.push(u);
            vs.push(v);
        }
        Ok((us, vs))
    }

    /// Where each lattice sample reads `placed`'s raster: the mip level
    /// whose pixels are at most as large as the samples near the tile's
    /// centre, and the kernel taps there. A north-up raster in the grid's
    /// CRS maps columns to columns and rows to rows, so its taps are found
    /// once per column and row; any other needs them per sample.
    fn sampler(&self, placed: &Placed, lattice: &Lattice, quality: &Quality) -> Result<Sampler, SourceError> {
        let r = &placed.raster;
        let (cols, rows) = (lattice.cols, lattice.rows);
        let kernel = self.resampling.unwrap_or(quality.resampling);
        let mip_for = |dx: f64, dy: f64| {
            let ratio = dx.abs().max(dy.abs());
            if !ratio.is_finite() || ratio < 2.0 {
                0
            } else {
                (ratio.log2().floor() as usize).min(r.levels().len() - 1)
            }
        };
        let taps_of = |coords: &[f64], axis: LevelAxis| -> Vec<Option<Taps>> {
            coords.iter().map(|&c| level_taps(c, axis, kernel)).collect()
        };
        if placed.same_crs && r.geo[2] == 0.0 && r.geo[4] == 0.0 {
            // North-up: the inverse has no cross terms, so u depends on x alone.
            let us: Vec<f64> = (0..cols).map(|i| r.pixel_of(lattice.x(i), 0.0).0).collect();
            let vs: Vec<f64> = (0..rows).map(|j| r.pixel_of(0.0, lattice.y(j)).1).collect();
            let mip = mip_for(us[cols / 2 + 1] - us[cols / 2], vs[rows / 2 + 1] - vs[rows / 2]);
            let (across, down) = r.levels()[mip].axes((r.width(), r.height()), r.wraps_x);
            return Ok(Sampler { mip, columns: taps_of(&us, across), rows: taps_of(&vs, down), separable: true });
        }
        let (us, vs) = self.pixel_coords(placed, lattice, quality.reprojection_error_px)?;
        let c = (rows / 2) * cols + cols / 2;
        let (dx, dy) =
            ((us[c + 1] - us[c]).hypot(vs[c + 1] - vs[c]), (us[c + cols] - us[c]).hypot(vs[c + cols] - vs[c]));
        let mip = mip_for(dx, dy);
        let (across, down) = r.levels()[mip].axes((r.width(), r.height()), r.wraps_x);
        Ok(Sampler { mip, columns: taps_of(&us, across), rows: taps_of(&vs, down), separable: false })
    }

    fn generate_into(&self, key: TileKey, grid: &TileGrid, quality: &Quality) -> Result<Payload, SourceError> {
        let sample_kind = match self.kind {
            RasterKind::Height => SampleKind::Corner,
            RasterKind::Color => SampleKind::TexelWithBorder,
        };
        let lattice = grid.lattice(key, sample_kind);
        let n = lattice.cols * lattice.rows;
        let reach = grid.tile_extent(key).dilate(lattice.step_x, lattice.step_y);
        let mut heights = vec![f32::NAN; if self.kind == RasterKind::Height { n } else { 0 }];
        let mut colors = vec![[0.0f32; 4]; if self.kind == RasterKind::Color { n } else { 0 }];
        for placed in &self.rasters {
            if !placed.extent_in_grid.is_some_and(|e| e.touches(&reach)) {
                continue;
            }
            let mut sampler = self.sampler(placed, &lattice, quality)?;
            let Some(rect) = sampler.window_rect() else {
                continue;
            };
            let level = &placed.raster.window(sampler.mip, rect)?;
            sampler.shift(&rect);
            match self.kind {
                RasterKind::Height if sampler.separable => {
                    heights_by_rows(level, &sampler.columns, &sampler.rows, &mut heights);
                }
                RasterKind::Height => sampler.each(lattice.cols, lattice.rows, |n, taps| {
                    if heights[n].is_nan() {
                        heights[n] = taps.map_or(f32::NAN, |(tx, ty)| height_from_taps(level, tx, ty));
                    }
                }),
                RasterKind::Color => sampler.each(lattice.cols, lattice.rows, |n, taps| {
                    let c = &mut colors[n];
                    if c[3] < 1.0 {
                        let new = taps.map_or([0.0; 4], |(tx, ty)| color_from_taps(level, tx, ty));
                        // Earlier rasters stay on top: "over" compositing.
                        let keep = 1.0 - c[3];
                        for k in 0..4 {
                            c[k] += keep * new[k];
                        }
                    }
                }),
            }
        }
        if self.kind == RasterKind::Height && grid.is_geodetic() {
            // Rows on a pole are one point: every sample there takes the
            // pole's one height, the same in every tile and at every level.
            for (row, north) in [(0, true), (lattice.rows - 1, false)] {
                if lattice.y(row).abs() == 90.0
                    && let Some(h) = self.pole_height(north)?
                {
                    heights[row * lattice.cols..(row + 1) * lattice.cols].fill(h);
                }
            }
        }
        Ok(match self.kind {
            RasterKind::Height => Payload::Height(HeightTile { size: lattice.cols, heights }),
            RasterKind::Color => {
                let mut rgba = Vec::with_capacity(n * 4);
                for c in colors {
                    let a = c[3];
                    let un = |v: f32| {
                        if a > 0.0 { (v / a * 255.0).round().clamp(0.0, 255.0) as u8 } else { 0 }
                    };
                    rgba.extend([un(c[0]), un(c[1]), un(c[2]), (a * 255.0).round() as u8]);
                }
                Payload::Color(ColorTile { size: lattice.cols, rgba })
            }
        })
    }
}

impl GdalSource {
    /// The height of a pole from the first raster that reaches it.
    fn pole_height(&self, north: bool) -> Result<Option<f32>, SourceError> {
        for placed in &self.rasters {
            if let Some(h) = placed.raster.pole_height(north)? {
                return Ok(Some(h));
            }
        }
        Ok(None)
    }

    /// Bytes of pixels read from the files so far, every raster and version
    /// together (what a windowed read saves shows here).
    pub fn bytes_read(&self) -> u64 {
        self.rasters.iter().map(|p| p.raster.bytes_read()).sum()
    }

    /// A height at a point of `raster` (its CRS), read from the base level.
    fn height_at(raster: &Raster, x: f64, y: f64, kernel: Resampling) -> Result<f32, SourceError> {
        let (u, v) = raster.pixel_of(x, y);
        let (Some(tx), Some(ty)) =
            (axis_taps(u, raster.width(), kernel, raster.wraps_x), axis_taps(v, raster.height(), kernel, false))
        else {
            return Ok(f32::NAN);
        };
        let ((x0, x1), (y0, y1)) = (tx.span(), ty.span());
        let rect = PixelRect { x0, y0, x1: x1 + 1, y1: y1 + 1 };
        let window = raster.window(0, rect)?;
        Ok(height_from_taps(&window, &tx.shifted(x0), &ty.shifted(y0)))
    }
}

impl Placed {
    /// The raster's sample spacing in grid units: its extent's width over
    /// its columns; for a rotated raster, its pixel's side (its extent's
    /// width spans its columns and rows both).
    fn resolution(&self) -> Option<f64> {
        let e = self.extent_in_grid?;
        let (r, g) = (&self.raster, &self.raster.geo);
        if g[2] == 0.0 && g[4] == 0.0 {
            return Some(e.width() / r.size.0 as f64);
        }
        let [min_x, _, max_x, _] = r.bounds();
        let side = g[1].hypot(g[4]).min(g[2].hypot(g[5]));
        Some(side * e.width() / (max_x - min_x))
    }
}

fn place(raster: Raster, grid: &TileGrid, grid_srs: &gdal::spatial_ref::SpatialRef) -> Result<Placed, SourceError> {
    let srs = crs::spatial_ref(&raster.crs_wkt, Some(&raster.path))?;
    let same_crs = srs == *grid_srs;
    let bounds = raster.bounds();
    let extent_in_grid =
        if same_crs { Some(bounds) } else { crs::transform_bounds(&raster.crs_wkt, grid.crs(), bounds) }
            .map(|[a, b, c, d]| Extent::new(a, b, c, d));
    if extent_in_grid.is_none() {
        return Err(SourceError::format(
            format!("raster extent cannot be placed in the scene grid ({})", grid.crs()),
            &raster.path,
        ));
    }
    Ok(Placed { raster: Arc::new(raster), same_crs, extent_in_grid })
}

impl Source for GdalSource {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        KIND
    }

    fn output(&self) -> PayloadKind {
        match self.kind {
            RasterKind::Height => PayloadKind::Height,
            RasterKind::Color => PayloadKind::Color,
        }
    }

    fn info(&self) -> SourceInfo {
        let first = &self.rasters[0].raster;
        let extent = self.rasters.iter().filter_map(|p| p.extent_in_grid).reduce(|a, b| a.union(&b));
        let mut details = first.details.clone();
        if self.rasters.len() > 1 {
            details.insert("mosaic".into(), format!("{} rasters", self.rasters.len()));
            let missing: Vec<&String> =
                self.rasters.iter().filter_map(|p| p.raster.details.get("missing_files")).collect();
            if !missing.is_empty() {
                details.insert("missing_files".into(), missing.into_iter().cloned().collect::<Vec<_>>().join("; "));
            }
        }
        let windowed = self.rasters.iter().filter(|p| p.raster.windowed()).count();
        details.insert(
            "read".into(),
            match windowed {
                0 => "whole (read when opened)".into(),
                n if n == self.rasters.len() => "windowed (blocks read as tiles need them)".into(),
                n => format!("{n} of {} rasters windowed", self.rasters.len()),
            },
        );
        let mut changes = self.read.changes.name().to_owned();
        if self.rasters.iter().any(|p| p.raster.warped) {
            changes.push_str(" (a warped raster: hashes of its warped values)");
        }
        details.insert("change_detection".into(), changes);
        details.insert("bytes_read".into(), self.bytes_read().to_string());
        if let Some(r) = self.resampling {
            let how = if r == Resampling::Nearest { "; its mips keep the most common value, for classes" } else { "" };
            details.insert("resampling".into(), format!("{r} (the source's own{how})"));
        }
        SourceInfo {
            files: self.rasters.iter().flat_map(|p| p.raster.files()).collect(),
            extent,
            crs: first.crs_name.clone(),
            vertical_datum: if self.kind == RasterKind::Height { self.vertical_datum.clone() } else { String::new() },
            vertical_units: if self.kind == RasterKind::Height {
                format!("m (file: {})", first.units.name())
            } else {
                String::new()
            },
            resolution: self.rasters.iter().filter_map(Placed::resolution).reduce(f64::min),
            details,
            warnings: self.rasters.iter().flat_map(|p| p.raster.warnings.iter().cloned()).collect(),
            ..SourceInfo::default()
        }
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        self.generate_into(key, ctx.grid, ctx.quality)
    }

    /// Re-reads the rasters whose files changed. Where only pixels changed
    /// the dirt is exactly the changed blocks (plus the widest kernel's
    /// reach); where the frame changed, the old and new extents whole.
    fn refresh(&self, grid: &TileGrid) -> Result<Refresh, SourceError> {
        let mut replaced = false;
        let mut dirty = DirtySet::none();
        let mut rasters = Vec::with_capacity(self.rasters.len());
        for placed in &self.rasters {
            let raster = &placed.raster;
            if !raster.files_changed()? {
                rasters.push(Placed { raster: Arc::clone(raster), ..*placed });
                continue;
            }
            replaced = true;
            match raster.reload(&self.read)? {
                Reloaded::Same(same) => rasters.push(Placed { raster: Arc::new(same), ..*placed }),
                Reloaded::Pixels(new, rects) => {
                    let extents = rects.iter().filter_map(|rect| {
                        let b = new.rect_bounds(rect);
                        let b =
                            if placed.same_crs { Some(b) } else { crs::transform_bounds(&new.crs_wkt, grid.crs(), b) };
                        b.map(|[a, b, c, d]| Extent::new(a, b, c, d))
                    });
                    dirty = dirty.union(
                        &DirtySet::from_extents(extents.collect::<Vec<_>>()).dilate_samples(DIRTY_MARGIN_SAMPLES),
                    );
                    rasters.push(Placed { raster: Arc::new(new), ..*placed });
                }
                Reloaded::Everything(new) => {
                    let grid_srs = crs::spatial_ref(grid.crs(), None)?;
                    let new = place(new, grid, &grid_srs)?;
                    let extents = [placed.extent_in_grid, new.extent_in_grid].into_iter().flatten();
                    dirty = dirty.union(&DirtySet::from_extents(extents).dilate_samples(DIRTY_MARGIN_SAMPLES));
                    rasters.push(new);
                }
            }
        }
        if !replaced {
            return Ok(Refresh::Unchanged);
        }
        Ok(Refresh::Changed {
            source: Arc::new(Self {
                id: self.id.clone(),
                spec: self.spec.clone(),
                kind: self.kind,
                read: self.read.clone(),
                vertical_datum: self.vertical_datum.clone(),
                grid_crs: self.grid_crs.clone(),
                rasters,
                resampling: self.resampling,
            }),
            dirty,
        })
    }

    fn sample_heights(&self, points: &[GeodeticPoint], quality: &Quality) -> Result<Vec<Option<f64>>, SourceError> {
        if self.kind != RasterKind::Height {
            return Err(SourceError::Unsupported("sampling elevations of a colour raster"));
        }
        let mut out: Vec<Option<f64>> = vec![None; points.len()];
        for placed in &self.rasters {
            let r = &placed.raster;
            let mut xs: Vec<f64> = points.iter().map(|p| p.lon_deg).collect();
            let mut ys: Vec<f64> = points.iter().map(|p| p.lat_deg).collect();
            crs::transform("EPSG:4326", &r.crs_wkt, &mut xs, &mut ys)?;
            let poles = [r.pole_height(true)?, r.pole_height(false)?];
            let kernel = self.resampling.unwrap_or(quality.resampling);
            for (((slot, x), y), p) in out.iter_mut().zip(&xs).zip(&ys).zip(points) {
                if slot.is_none() {
                    // A pole is one point, whatever the longitude.
                    let pole = if p.lat_deg == 90.0 {
                        poles[0]
                    } else if p.lat_deg == -90.0 {
                        poles[1]
                    } else {
                        None
                    };
                    let h = match pole {
                        Some(h) => h,
                        None => Self::height_at(r, *x, *y, kernel)?,
                    };
                    *slot = (!h.is_nan()).then_some(f64::from(h));
                }
            }
        }
        Ok(out)
    }
}
