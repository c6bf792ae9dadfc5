//! A raster georeferenced by ground control points (GCPs) instead of a
//! geotransform, warped north-up through GDAL's GCP transformer: a
//! polynomial fitted to the GCPs by least squares, of the order `gdalwarp`
//! (and GDAL's `AutoCreateWarpedVRT`) pick by default: first order under
//! six GCPs, second from six; the first where six or more do not determine
//! the second (gdalwarp refuses those). No thin plate spline: gdalwarp
//! takes one only when asked (`-tps`).
//!
//! The warp is a VRT (`VRTWarpedDataset`) in GDAL's memory file system,
//! opened in place of the file: the rest of the raster (blocks, levels,
//! reloads) reads it as any other dataset, and GDAL warps a block when one
//! is read (bilinear; nearest for classes and palettes). Outside the file
//! is nodata (heights) or transparent (colour, through an alpha band). The
//! frame is chosen as `gdalwarp` chooses it (`GDALSuggestedWarpOutput`):
//! the bounding box of the file's edges mapped through the fit, square
//! pixels keeping the file's pixel count along its diagonal; its size
//! rounded up so the whole file lies inside, and so the warps GDAL makes of
//! the file's overviews are exact halves.
//!
//! A rotated geotransform needs no warp: the sampler maps points through
//! its inverse as they are (`Raster::pixel_of`), so it is served exactly,
//! with no second resampling.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use gdal::Dataset;
use gdal::raster::{ColorInterpretation, GdalDataType};
use quick_xml::escape::escape;
use relief_source::SourceError;

use super::{RasterKind, ReadOptions, format_err};
use crate::crs;

/// Side of the warped VRT's blocks: the raster's own blocks, so that one
/// block read is one warp.
const BLOCK: usize = super::blocks::BLOCK;

/// The largest warped frame, in pixels of the file: a fit that spreads
/// the file wider than this is a sign of bad GCPs, not a raster to serve.
const MAX_GROWTH: f64 = 64.0;

/// Points per edge of the file mapped to find the frame (GDAL's number).
const EDGE_STEPS: usize = 20;

/// A file in GDAL's memory file system, removed when the last version
/// that reads it is dropped (a dataset still open on it keeps its bytes).
#[derive(Debug)]
pub(crate) struct MemFile {
    pub path: PathBuf,
}

impl MemFile {
    pub(crate) fn create(path: PathBuf, bytes: Vec<u8>) -> gdal::errors::Result<Arc<Self>> {
        gdal::vsi::create_mem_file(&path, bytes)?;
        Ok(Arc::new(Self { path }))
    }
}

impl Drop for MemFile {
    fn drop(&mut self) {
        let _gone_already_is_fine = gdal::vsi::unlink_mem_file(&self.path);
    }
}

/// A raster's warp: what GDAL opens instead of the file, and what to say
/// about it.
#[derive(Debug)]
pub(crate) struct Warped {
    pub file: Arc<MemFile>,
    /// The band of the warped dataset that holds what the manifest's `band` names.
    pub band: usize,
    /// For the scene state's `georeferencing` detail.
    pub description: String,
    /// A sentence for the scene state's warnings.
    pub warning: String,
}

/// The file's GCPs (None when it has none), warped north-up. `source` is
/// what GDAL opens for the file (a VRT without its missing members, or the
/// file itself); `path` is named in errors.
pub(crate) fn from_gcps(
    ds: &Dataset,
    source: &Path,
    path: &Path,
    kind: RasterKind,
    options: &ReadOptions,
) -> Result<Option<Warped>, SourceError> {
    let gcps: Vec<gdal::Gcp> = ds.gcps().iter().map(gdal::Gcp::from).collect();
    if gcps.is_empty() {
        return Ok(None);
    }
    let n = gcps.len();
    if n < 3 {
        return Err(format_err(
            format!(
                "raster is georeferenced by {n} GCP{}, too few for GDAL's GCP transformer (a first-order \
                 polynomial needs at least 3, not on one line)",
                if n == 1 { "" } else { "s" }
            ),
            path,
        ));
    }
    if let Some(bad) = gcps.iter().find(|g| ![g.pixel, g.line, g.x, g.y].iter().all(|v| v.is_finite())) {
        return Err(format_err(format!("raster GCP '{}' has a coordinate that is not a number", bad.id), path));
    }
    let srs = match &options.crs_override {
        Some(def) => crs::spatial_ref(def, Some(path))?,
        None => match ds.gcp_projection().filter(|wkt| !wkt.trim().is_empty()) {
            Some(wkt) => crs::spatial_ref(&wkt, Some(path))?,
            None => {
                return Err(format_err("raster GCPs have no CRS (set 'crs' on the source in the manifest)", path));
            }
        },
    };
    let crs_wkt = srs.to_wkt().map_err(|e| SourceError::Crs {
        crs: "raster GCP CRS".into(),
        message: e.to_string(),
        path: Some(path.to_path_buf()),
    })?;
    // GDAL's automatic order (gdal_crs.cpp): first under six GCPs, second
    // from six (a third is never chosen). Where six or more do not
    // determine a second order (all on two lines, say), gdalwarp gives up;
    // relief falls back to the first, as `gdalwarp -order 1` would read it.
    let points: Vec<[f64; 4]> = gcps.iter().map(|g| [g.pixel, g.line, g.x, g.y]).collect();
    let (order, fit, fell_back) = match Polynomial::fit(if n >= 6 { 2 } else { 1 }, &points) {
        Some(fit) => (fit.order, fit, false),
        None => match Polynomial::fit(1, &points).filter(|_| n >= 6) {
            Some(fit) => (1, fit, true),
            None => {
                return Err(format_err(
                    format!(
                        "raster GCPs do not determine a first-order polynomial ({n} GCPs, all on one line or at \
                         one place): GDAL's GCP transformer cannot use them"
                    ),
                    path,
                ));
            }
        },
    };
    let residual = points
        .iter()
        .map(|p| {
            let (x, y) = fit.apply(p[0], p[1]);
            (x - p[2]).hypot(y - p[3])
        })
        .fold(0.0f64, f64::max);
    let size = ds.raster_size();
    // GDAL warps the file's overviews into overviews of the warp, of its
    // size over theirs, rounded: a frame of a multiple of 2^k pixels makes
    // those of k halvings exactly the halves the levels read them as.
    let overviews = ds.rasterband(1).ok().and_then(|b| b.overview_count().ok()).unwrap_or(0).clamp(0, 8);
    let frame = Frame::suggested(&fit, size, 1 << overviews)
        .ok_or_else(|| format_err(format!("raster GCPs map the raster onto no area ({n} GCPs): check them"), path))?;
    let grown = (frame.size.0 as f64 * frame.size.1 as f64) / (size.0 as f64 * size.1 as f64);
    if grown > MAX_GROWTH {
        return Err(format_err(
            format!(
                "raster GCPs spread the raster over {} x {} pixels, {grown:.0} times its own {} x {} ({n} GCPs, a \
                 {} polynomial): check them",
                frame.size.0,
                frame.size.1,
                size.0,
                size.1,
                order_name(order)
            ),
            path,
        ));
    }
    let plan = Bands::plan(ds, kind, options, path)?;
    let xml = plan.vrt(&frame, &crs_wkt, source, &gcps, order);
    let name = PathBuf::from(format!(
        "{}/{}-{}-warped.vrt",
        crate::guard::OWN_MEMORY_FILES,
        std::process::id(),
        super::blocks::new_uid()
    ));
    let file = MemFile::create(name, xml.into_bytes())
        .map_err(|e| format_err(format!("cannot write the raster's warp: {e}"), path))?;
    // Lengths in the CRS's units, to about a thousandth of a pixel.
    let (units, decimals) = if srs.is_geographic() { ("degrees", 8) } else { ("m", 3) };
    let residual = format!("{residual:.decimals$} {units}, {:.2} pixels", residual / frame.pixel);
    let kernel = plan.resampling.to_lowercase();
    let how = if fell_back {
        "GDAL's GCP transformer, as gdalwarp -order 1 does: they do not determine the second order gdalwarp takes \
         by default"
    } else {
        "GDAL's GCP transformer, as gdalwarp does by default"
    };
    let description = format!(
        "{n} GCPs, fitted by a {} polynomial ({how}; largest residual {residual}); warped north-up ({kernel}) \
         from {} x {} to {} x {} pixels of {:.decimals$} {units}",
        order_name(order),
        size.0,
        size.1,
        frame.size.0,
        frame.size.1,
        frame.pixel,
    );
    let warning = format!(
        "raster is georeferenced by {n} GCPs, not a geotransform: served warped north-up through a {} polynomial \
         fit of them (largest residual {residual}), resampled {kernel}: {}",
        order_name(order),
        path.display()
    );
    tracing::info!(raster = %path.display(), gcps = n, order, "raster warped north-up from its GCPs");
    Ok(Some(Warped { file, band: plan.band, description, warning }))
}

fn order_name(order: usize) -> &'static str {
    if order == 1 { "first-order" } else { "second-order" }
}

/// A polynomial of order 1 or 2 from (pixel, line) to (x, y), fitted by
/// least squares over coordinates centred and scaled (as GDAL's is).
#[derive(Debug, Clone)]
struct Polynomial {
    order: usize,
    /// Centre and scale of the pixel and line coordinates.
    centre: (f64, f64),
    scale: f64,
    x: Vec<f64>,
    y: Vec<f64>,
}

impl Polynomial {
    fn terms(order: usize, u: f64, v: f64) -> Vec<f64> {
        if order == 1 { vec![1.0, u, v] } else { vec![1.0, u, v, u * u, u * v, v * v] }
    }

    /// The fit of `points` ([pixel, line, x, y]); None when they do not
    /// determine it (too few, on one line, repeated).
    fn fit(order: usize, points: &[[f64; 4]]) -> Option<Self> {
        let k = Self::terms(order, 0.0, 0.0).len();
        if points.len() < k {
            return None;
        }
        let n = points.len() as f64;
        let centre = (points.iter().map(|p| p[0]).sum::<f64>() / n, points.iter().map(|p| p[1]).sum::<f64>() / n);
        let scale = points.iter().map(|p| (p[0] - centre.0).abs().max((p[1] - centre.1).abs())).fold(0.0f64, f64::max);
        if scale <= 0.0 {
            return None;
        }
        // Normal equations, one matrix for both coordinates; the targets
        // centred on their mean so the solve works in small numbers.
        let mean = (points.iter().map(|p| p[2]).sum::<f64>() / n, points.iter().map(|p| p[3]).sum::<f64>() / n);
        let mut a = vec![vec![0.0f64; k]; k];
        let (mut bx, mut by) = (vec![0.0f64; k], vec![0.0f64; k]);
        for p in points {
            let t = Self::terms(order, (p[0] - centre.0) / scale, (p[1] - centre.1) / scale);
            for (i, row) in a.iter_mut().enumerate() {
                for (v, tj) in row.iter_mut().zip(&t) {
                    *v += t[i] * tj;
                }
                bx[i] += t[i] * (p[2] - mean.0);
                by[i] += t[i] * (p[3] - mean.1);
            }
        }
        let (mut x, mut y) = solve(a, bx, by)?;
        x[0] += mean.0;
        y[0] += mean.1;
        Some(Self { order, centre, scale, x, y })
    }

    fn apply(&self, pixel: f64, line: f64) -> (f64, f64) {
        let t = Self::terms(self.order, (pixel - self.centre.0) / self.scale, (line - self.centre.1) / self.scale);
        let dot = |c: &[f64]| c.iter().zip(&t).map(|(c, t)| c * t).sum::<f64>();
        (dot(&self.x), dot(&self.y))
    }
}

/// Solves `a` x = `b1` and `a` x = `b2` by Gaussian elimination with
/// partial pivoting; None when `a` is singular.
fn solve(mut a: Vec<Vec<f64>>, mut b1: Vec<f64>, mut b2: Vec<f64>) -> Option<(Vec<f64>, Vec<f64>)> {
    let k = a.len();
    let largest = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for col in 0..k {
        let pivot = (col..k).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= largest * 1e-12 {
            return None;
        }
        a.swap(col, pivot);
        b1.swap(col, pivot);
        b2.swap(col, pivot);
        let (above, below) = a.split_at_mut(col + 1);
        let pivot_row = &above[col];
        for (offset, row) in below.iter_mut().enumerate() {
            let f = row[col] / pivot_row[col];
            for (v, p) in row[col..].iter_mut().zip(&pivot_row[col..]) {
                *v -= f * p;
            }
            b1[col + 1 + offset] -= f * b1[col];
            b2[col + 1 + offset] -= f * b2[col];
        }
    }
    let back = |b: &[f64]| {
        let mut x = vec![0.0f64; k];
        for row in (0..k).rev() {
            let s: f64 = (row + 1..k).map(|c| a[row][c] * x[c]).sum();
            x[row] = (b[row] - s) / a[row][row];
        }
        x
    };
    let (x1, x2) = (back(&b1), back(&b2));
    x1.iter().chain(&x2).all(|v| v.is_finite()).then_some((x1, x2))
}

/// The north-up frame of the warp.
#[derive(Debug, Clone, PartialEq)]
struct Frame {
    size: (usize, usize),
    pixel: f64,
    geo: [f64; 6],
}

impl Frame {
    /// GDAL's suggested output: the bounding box of the file's edges
    /// through `fit`, square pixels keeping the file's pixel count along
    /// the diagonal from its first corner to its last; its size rounded up
    /// to a multiple of `multiple` pixels.
    fn suggested(fit: &Polynomial, (width, height): (usize, usize), multiple: usize) -> Option<Self> {
        let (w, h) = (width as f64, height as f64);
        let mut points = Vec::with_capacity(4 * (EDGE_STEPS + 1));
        for s in 0..=EDGE_STEPS {
            let r = s as f64 / EDGE_STEPS as f64;
            points.extend([(r * w, 0.0), (r * w, h), (0.0, r * h), (w, r * h)]);
        }
        let mapped: Vec<(f64, f64)> = points.iter().map(|&(p, l)| fit.apply(p, l)).collect();
        let (mut min_x, mut min_y, mut max_x, mut max_y) =
            (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for &(x, y) in &mapped {
            (min_x, min_y, max_x, max_y) = (min_x.min(x), min_y.min(y), max_x.max(x), max_y.max(y));
        }
        let (a, b) = (fit.apply(0.0, 0.0), fit.apply(w, h));
        let (mut dx, mut dy) = (b.0 - a.0, b.1 - a.1);
        if dx == 0.0 || dy == 0.0 {
            (dx, dy) = (max_x - min_x, max_y - min_y);
        }
        let pixel = dx.hypot(dy) / w.hypot(h);
        if !(pixel.is_finite() && pixel > 0.0 && (max_x - min_x).is_finite() && (max_y - min_y).is_finite()) {
            return None;
        }
        // Outwards, less a hair of rounding, so the whole file lies inside.
        let count = |extent: f64| ((extent / pixel - 1e-6).ceil().max(1.0) as usize).next_multiple_of(multiple);
        let size = (count(max_x - min_x), count(max_y - min_y));
        Some(Self { size, pixel, geo: [min_x, pixel, 0.0, max_y, 0.0, -pixel] })
    }
}

/// Which bands of the file the warp reads, and how.
#[derive(Debug)]
struct Bands {
    /// Per warped band: the file's band, its VRT description.
    mapped: Vec<(usize, String, Option<f64>)>,
    /// The file's alpha band, and the warped dataset's (which is last).
    source_alpha: Option<usize>,
    alpha: Option<usize>,
    resampling: &'static str,
    /// The warped band that holds what the manifest's `band` names.
    band: usize,
}

impl Bands {
    /// Heights: the one band asked for, as floats where the file has no
    /// nodata value (outside the file is then NaN). Colour: a palette band
    /// (nearest, its table kept), or up to three colour bands and the
    /// file's alpha; outside the file is transparent through a new alpha band.
    fn plan(ds: &Dataset, kind: RasterKind, options: &ReadOptions, path: &Path) -> Result<Self, SourceError> {
        let band = |b: usize| {
            ds.rasterband(b)
                .map_err(|e| format_err(format!("raster has no band {b} ({} bands): {e}", ds.raster_count()), path))
        };
        match kind {
            RasterKind::Height => {
                let source = band(options.band)?;
                let nodata = source.no_data_value();
                let data_type = match (nodata, source.band_type()) {
                    (Some(_), t) => t.name(),
                    (None, GdalDataType::Float64) => "Float64".into(),
                    (None, _) => "Float32".into(),
                };
                let mut xml = band_xml(1, &data_type, Some(nodata.unwrap_or(f64::NAN)), "Gray");
                if let Some(s) = source.scale() {
                    let _ = write!(xml, "<Scale>{}</Scale>", number(s));
                }
                if let Some(o) = source.offset() {
                    let _ = write!(xml, "<Offset>{}</Offset>", number(o));
                }
                let unit = source.unit();
                if !unit.is_empty() {
                    let _ = write!(xml, "<UnitType>{}</UnitType>", escape(unit.as_str()));
                }
                xml.push_str("</VRTRasterBand>");
                Ok(Self {
                    mapped: vec![(options.band, xml, nodata)],
                    source_alpha: None,
                    alpha: None,
                    resampling: if options.categorical { "NearestNeighbour" } else { "Bilinear" },
                    band: 1,
                })
            }
            RasterKind::Color => {
                let first = band(1)?;
                if let Some(table) = first.color_table() {
                    let nodata = first.no_data_value();
                    let mut xml = band_xml(1, &first.band_type().name(), nodata, "Palette");
                    xml.push_str("<ColorTable>");
                    for i in 0..table.entry_count() {
                        let c = table.entry_as_rgb(i).map_or([0; 4], |c| [c.r, c.g, c.b, c.a]);
                        let _ = write!(xml, r#"<Entry c1="{}" c2="{}" c3="{}" c4="{}"/>"#, c[0], c[1], c[2], c[3]);
                    }
                    xml.push_str("</ColorTable></VRTRasterBand>");
                    return Ok(Self {
                        mapped: vec![(1, xml, nodata)],
                        source_alpha: None,
                        alpha: Some(2),
                        resampling: "NearestNeighbour",
                        band: 1,
                    });
                }
                let (mut colour, mut source_alpha) = (Vec::new(), None);
                for b in 1..=ds.raster_count().min(4) {
                    let source = band(b)?;
                    if source.color_interpretation() == ColorInterpretation::AlphaBand {
                        source_alpha = Some(b);
                    } else if colour.len() < 3 {
                        colour.push((b, source.band_type().name(), source.no_data_value()));
                    }
                }
                // A grey band alone: the decoder repeats it.
                let names: &[&str] = if colour.len() == 1 { &["Gray"] } else { &["Red", "Green", "Blue"] };
                let mapped: Vec<(usize, String, Option<f64>)> = colour
                    .into_iter()
                    .zip(names)
                    .enumerate()
                    .map(|(i, ((b, data_type, nodata), interp))| {
                        (b, band_xml(i + 1, &data_type, nodata, interp) + "</VRTRasterBand>", nodata)
                    })
                    .collect();
                let alpha = Some(mapped.len() + 1);
                Ok(Self { mapped, source_alpha, alpha, resampling: "Bilinear", band: 1 })
            }
        }
    }

    /// The warped VRT: `frame` in `crs_wkt`, reading `source` through its GCPs.
    fn vrt(&self, frame: &Frame, crs_wkt: &str, source: &Path, gcps: &[gdal::Gcp], order: usize) -> String {
        let geo = |g: &[f64; 6]| g.iter().map(|v| number(*v)).collect::<Vec<_>>().join(",");
        let inverse = {
            let g = frame.geo;
            [-g[0] / g[1], 1.0 / g[1], 0.0, -g[3] / g[5], 0.0, 1.0 / g[5]]
        };
        let mut x = String::new();
        let _ = write!(
            x,
            r#"<VRTDataset rasterXSize="{}" rasterYSize="{}" subClass="VRTWarpedDataset"><SRS>{}</SRS><GeoTransform>{}</GeoTransform>"#,
            frame.size.0,
            frame.size.1,
            escape(crs_wkt),
            geo(&frame.geo)
        );
        for (_, band, _) in &self.mapped {
            x.push_str(band);
        }
        if let Some(a) = self.alpha {
            let _ = write!(
                x,
                r#"<VRTRasterBand dataType="Byte" band="{a}" subClass="VRTWarpedRasterBand"><ColorInterp>Alpha</ColorInterp></VRTRasterBand>"#
            );
        }
        // The frame's pixels are the file's size: no downsampling. GDAL
        // would guess a scale per block from the bounding box of its source
        // window, under 1 where the file is turned, and widen the kernel
        // (0.48 m off a plane at 30 degrees; with XSCALE = YSCALE = 1, 1e-4 m).
        let _ = write!(
            x,
            "<BlockXSize>{BLOCK}</BlockXSize><BlockYSize>{BLOCK}</BlockYSize><GDALWarpOptions>\
             <WarpMemoryLimit>67108864</WarpMemoryLimit><ResampleAlg>{}</ResampleAlg>\
             <Option name=\"INIT_DEST\">NO_DATA</Option>\
             <Option name=\"XSCALE\">1</Option><Option name=\"YSCALE\">1</Option>\
             <Option name=\"ERROR_OUT_IF_EMPTY_SOURCE_WINDOW\">FALSE</Option>\
             <SourceDataset relativeToVRT=\"0\">{}</SourceDataset>\
             <Transformer><ApproxTransformer><MaxError>0.125</MaxError><BaseTransformer><GenImgProjTransformer>\
             <SrcGCPTransformer><GCPTransformer><Order>{order}</Order><Reversed>0</Reversed><GCPList>",
            self.resampling,
            escape(source.to_string_lossy())
        );
        for g in gcps {
            let _ = write!(
                x,
                r#"<GCP Id="{}" Pixel="{}" Line="{}" X="{}" Y="{}"/>"#,
                escape(g.id.as_str()),
                number(g.pixel),
                number(g.line),
                number(g.x),
                number(g.y)
            );
        }
        let _ = write!(
            x,
            "</GCPList></GCPTransformer></SrcGCPTransformer><DstGeoTransform>{}</DstGeoTransform>\
             <DstInvGeoTransform>{}</DstInvGeoTransform></GenImgProjTransformer></BaseTransformer>\
             </ApproxTransformer></Transformer><BandList>",
            geo(&frame.geo),
            geo(&inverse)
        );
        for (dst, (src, _, nodata)) in self.mapped.iter().enumerate() {
            let _ = write!(x, r#"<BandMapping src="{src}" dst="{}">"#, dst + 1);
            if let Some(nd) = nodata {
                let _ = write!(x, "<SrcNoDataReal>{0}</SrcNoDataReal><SrcNoDataImag>0</SrcNoDataImag>", number(*nd));
            }
            // Heights with no nodata of their own are NaN outside the file.
            let dst_nodata = nodata.or_else(|| (self.alpha.is_none()).then_some(f64::NAN));
            if let Some(nd) = dst_nodata {
                let _ = write!(x, "<DstNoDataReal>{0}</DstNoDataReal><DstNoDataImag>0</DstNoDataImag>", number(nd));
            }
            x.push_str("</BandMapping>");
        }
        x.push_str("</BandList>");
        if let Some(a) = self.source_alpha {
            let _ = write!(x, "<SrcAlphaBand>{a}</SrcAlphaBand>");
        }
        if let Some(a) = self.alpha {
            let _ = write!(x, "<DstAlphaBand>{a}</DstAlphaBand>");
        }
        x.push_str("</GDALWarpOptions></VRTDataset>");
        x
    }
}

/// The start of a warped band's VRT description (its nodata and colour
/// interpretation); the caller closes it.
fn band_xml(band: usize, data_type: &str, nodata: Option<f64>, interp: &str) -> String {
    let mut xml = format!(r#"<VRTRasterBand dataType="{data_type}" band="{band}" subClass="VRTWarpedRasterBand">"#);
    if let Some(nd) = nodata {
        let _ = write!(xml, "<NoDataValue>{}</NoDataValue>", number(nd));
    }
    let _ = write!(xml, "<ColorInterp>{interp}</ColorInterp>");
    xml
}

/// A number as GDAL reads it back exactly (shortest round trip; NaN and
/// infinities by GDAL's names).
fn number(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn affine(p: f64, l: f64) -> (f64, f64) {
        (500_000.0 + 8.66 * p + 5.0 * l, 5_000_000.0 + 5.0 * p - 8.66 * l)
    }

    #[test]
    fn polynomial_fits_reproduce_an_affine_frame() {
        for (order, n) in [(1usize, 3usize), (1, 5), (2, 6), (2, 12)] {
            let points: Vec<[f64; 4]> = (0..n)
                .map(|i| {
                    let (p, l) = ((i * 71 % 200) as f64, (i * i * 29 % 150) as f64 + 0.5 * i as f64);
                    let (x, y) = affine(p, l);
                    [p, l, x, y]
                })
                .collect();
            let fit = Polynomial::fit(order, &points).unwrap_or_else(|| panic!("order {order} of {n} points"));
            for (p, l) in [(0.0, 0.0), (200.0, 150.0), (17.5, 99.25)] {
                let (x, y) = fit.apply(p, l);
                let (ex, ey) = affine(p, l);
                assert!((x - ex).abs() < 1e-6 && (y - ey).abs() < 1e-6, "order {order}: ({x}, {y}) vs ({ex}, {ey})");
            }
        }
    }

    #[test]
    fn polynomial_fits_refuse_points_on_a_line_or_too_few() {
        let line: Vec<[f64; 4]> = (0..4).map(|i| [f64::from(i), f64::from(i), f64::from(i), 0.0]).collect();
        assert!(Polynomial::fit(1, &line).is_none());
        assert!(Polynomial::fit(1, &line[..2]).is_none());
        let five: Vec<[f64; 4]> = (0..5).map(|i| [f64::from(i), f64::from(i * i), 0.0, 0.0]).collect();
        assert!(Polynomial::fit(2, &five).is_none());
    }

    #[test]
    fn the_frame_of_a_rotation_keeps_the_pixel_size_and_holds_the_whole_file() -> Result<(), Box<dyn std::error::Error>>
    {
        let (s, c) = 30f64.to_radians().sin_cos();
        let points: Vec<[f64; 4]> = [(0.0, 0.0), (200.0, 0.0), (0.0, 150.0), (200.0, 150.0)]
            .iter()
            .map(|&(p, l): &(f64, f64)| [p, l, 10.0 * (c * p + s * l), 10.0 * (s * p - c * l)])
            .collect();
        let fit = Polynomial::fit(1, &points).ok_or("four corners fit a first-order polynomial")?;
        let frame = Frame::suggested(&fit, (200, 150), 1).ok_or("a frame for the fit")?;
        assert!((frame.pixel - 10.0).abs() < 1e-9, "{frame:?}");
        let width = 10.0 * (200.0 * c + 150.0 * s);
        let height = 10.0 * (200.0 * s + 150.0 * c);
        assert_eq!(frame.size, ((width / 10.0).ceil() as usize, (height / 10.0).ceil() as usize));
        assert!((frame.geo[0] - 0.0).abs() < 1e-6 && (frame.geo[3] - 10.0 * 200.0 * s).abs() < 1e-6, "{frame:?}");
        let even = Frame::suggested(&fit, (200, 150), 8).ok_or("a frame in multiples of 8")?;
        assert_eq!(even.size, (frame.size.0.next_multiple_of(8), frame.size.1.next_multiple_of(8)));
        Ok(())
    }

    #[test]
    fn numbers_read_back_exactly() -> Result<(), Box<dyn std::error::Error>> {
        for v in [0.1, -9999.0, 1.0 / 3.0, 5e6, f64::from(f32::MAX)] {
            assert_eq!(number(v).parse::<f64>()?, v);
        }
        assert_eq!(number(f64::NAN), "nan");
        Ok(())
    }
}
