//! What a raster must pass when it opens: every block inside the file,
//! and overviews that agree with the base, within what the file's
//! compression may change (`Lossy`).

use std::path::Path;

use rayon::prelude::*;
use relief_source::SourceError;

use super::blocks::BLOCK;
use super::decode::Decoder;
use super::halve;
use super::{PixelRect, Raster, format_err, tiff};

/// Of the sampled pixels of the first overview, more than one in
/// `OFF_SHARE` outside the range of the base pixels under them (beyond
/// the slack) is a disagreement.
const OFF_SHARE: usize = 10;

/// What the overview check found, when it does not refuse the raster.
#[derive(Debug)]
pub(super) enum Overviews {
    /// No overview to check, or the first agrees with the base; with a
    /// sentence for the state's details on how a lossy file was checked.
    Agree(Option<String>),
    /// A lossy file whose first overview differs from its base beyond
    /// what its compression explains: its coarse levels are to be halved
    /// from the base instead. The sentence for the state's details, and
    /// the warning.
    Rebuild { detail: String, warning: String },
}

/// A lossy compression and how far it may move a pixel, in the band's
/// stored units.
///
/// Both the overview and the base under it went through the compression,
/// so an overview pixel may fall outside the range of the four base
/// pixels under it by what the compression moved it plus what it moved
/// them: the tolerance is twice the error one image may carry.
///
/// - LERC: its max Z error `e`, read from the first base block's Lerc2
///   header (LERC guarantees every pixel within `e`): `2 e`. A max Z error
///   of 0 is lossless; for integer data LERC writes 0.5, which rounds back
///   exactly, and the tolerance is then 1, one step of the data.
/// - JPEG: no per-pixel bound exists, so the bound is the step by which
///   JPEG quantises each 8 x 8 block's mean brightness: the DC entry of
///   the standard luminance table (16) at the file's quality `q`
///   (`JPEG_QUALITY`, which GDAL reads back from the quantisation tables;
///   75, GDAL's default, when unknown), scaled as libjpeg scales it
///   (`5000 / q` below 50, `200 - 2 q` from 50). Each image may move a
///   block by half that step, so together by one step: 8 levels at
///   quality 75, 3 at 90, 16 at 50. Measured on a smooth textured image
///   (sinusoids, a COG at quality 75 with averaged overviews), 2 % of the
///   first overview's pixels lie beyond it (20 % beyond the range alone):
///   what is left beyond it is detail finer than a block (edges, fine
///   texture), where JPEG's error is larger and an overview is better
///   halved from the base.
/// - WebP (lossy, `WEBP_LEVEL`, default 75): WebP publishes no table from
///   quality to quantiser; the JPEG bound for the same quality is used, as
///   WebP's quality scale was made to follow JPEG's.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Lossy {
    /// The compression and its setting, in words ("JPEG, quality 75").
    pub what: String,
    /// The tolerance in stored units (grey levels for bytes).
    pub tolerance: f64,
    /// How the tolerance was chosen, in words.
    pub why: String,
}

impl Lossy {
    /// The lossy compression of the raster GDAL opened as `ds` (its
    /// IMAGE_STRUCTURE metadata; for LERC the first base block of `path`'s
    /// TIFF); None when it is lossless.
    pub(super) fn of(ds: &gdal::Dataset, path: &Path) -> Option<Self> {
        use gdal::Metadata;
        let item = |name: &str| ds.metadata_item(name, "IMAGE_STRUCTURE");
        let compression = item("COMPRESSION")?.to_ascii_uppercase();
        let lossless = item("COMPRESSION_REVERSIBILITY").is_some_and(|r| r.eq_ignore_ascii_case("LOSSLESS"))
            || item("WEBP_LOSSLESS").is_some_and(|v| v.eq_ignore_ascii_case("TRUE"));
        if lossless {
            return None;
        }
        if compression.contains("JPEG") || compression.contains("WEBP") {
            let (name, key) =
                if compression.contains("JPEG") { ("JPEG", "JPEG_QUALITY") } else { ("WebP", "WEBP_LEVEL") };
            let quality = item(key).and_then(|q| q.trim().parse::<u32>().ok()).filter(|q| (1..=100).contains(q));
            let step = jpeg_dc_step(quality.unwrap_or(75));
            let told = quality.map_or_else(|| "quality unknown, 75 assumed".to_owned(), |q| format!("quality {q}"));
            return Some(Self {
                what: format!("{name}, {told}"),
                tolerance: f64::from(step),
                why: format!("the step JPEG quantises an 8x8 block's mean by at that quality, {step}"),
            });
        }
        if compression.starts_with("LERC") {
            return match lerc_max_z_error(path) {
                Some(e) if e <= 0.0 => None,
                Some(e) => Some(Self {
                    what: format!("LERC, max Z error {e}"),
                    tolerance: 2.0 * e,
                    why: format!("twice its max Z error {e}: the overview and the base may each move by it"),
                }),
                None => Some(Self {
                    what: "LERC, max Z error unreadable".into(),
                    tolerance: 0.0,
                    why: "no bound: its max Z error could not be read".into(),
                }),
            };
        }
        None
    }
}

/// The DC entry (16) of the standard JPEG luminance table at quality `q`,
/// scaled as libjpeg's `jpeg_quality_scaling` and `jpeg_add_quant_table`
/// scale it.
pub(super) fn jpeg_dc_step(quality: u32) -> u32 {
    let q = quality.clamp(1, 100);
    let scale = if q < 50 { 5000 / q } else { 200 - 2 * q };
    ((16 * scale + 50) / 100).clamp(1, 255)
}

/// The max Z error of the first base block of a LERC-compressed TIFF,
/// from its Lerc2 header (inflated first for LERC_DEFLATE); None when it
/// cannot be read (LERC_ZSTD, or not a TIFF).
fn lerc_max_z_error(path: &Path) -> Option<f64> {
    use std::io::{Read, Seek, SeekFrom};
    let images = tiff::images(path)?;
    let image = images.first()?;
    let (offset, size) = image.offsets.iter().zip(&image.sizes).find(|(_, s)| **s > 0)?;
    let mut file = std::fs::File::open(path).ok()?;
    file.seek(SeekFrom::Start(*offset)).ok()?;
    let mut blob = vec![0; usize::try_from(*size).ok()?.min(64 << 20)];
    file.read_exact(&mut blob).ok()?;
    if !blob.starts_with(b"Lerc2 ") {
        let raw = image.block.0 * image.block.1 * usize::from(image.samples.max(1)) * 8;
        let mut inflated = vec![0; raw + 4096];
        let n = libdeflater::Decompressor::new().zlib_decompress(&blob, &mut inflated).ok()?;
        inflated.truncate(n);
        blob = inflated;
    }
    lerc2_max_z_error(&blob)
}

/// The max Z error in a Lerc2 blob's header.
fn lerc2_max_z_error(blob: &[u8]) -> Option<f64> {
    if !blob.starts_with(b"Lerc2 ") {
        return None;
    }
    let version = i32::from_le_bytes(blob.get(6..10)?.try_into().ok()?);
    // After the version: a checksum (3+), rows, columns, depth (4+), valid
    // pixels, micro block size, blob size, data type, and from version 6
    // the count of blobs more and four flags.
    let mut at = 10;
    at += if version >= 3 { 4 } else { 0 };
    at += 8;
    at += if version >= 4 { 4 } else { 0 };
    at += 16;
    at += if version >= 6 { 8 } else { 0 };
    let error = f64::from_le_bytes(blob.get(at..at + 8)?.try_into().ok()?);
    error.is_finite().then_some(error)
}

impl Raster {
    /// Checks that a windowed raster's blocks are all in the file (a TIFF's
    /// block tables), or reads its first and last base blocks (any other
    /// format): a file cut short fails here, when it opens, not at its
    /// first tile.
    pub(super) fn probe(self) -> Result<Self, SourceError> {
        if let Some(images) = tiff::images(&self.path) {
            for image in images.iter() {
                image.check_within(&self.path)?;
            }
            return Ok(self);
        }
        let (bw, bh) = (self.width().div_ceil(BLOCK), self.height().div_ceil(BLOCK));
        self.store.block(0, 0, 0)?;
        self.store.block(0, bw - 1, bh - 1)?;
        Ok(self)
    }

    /// Checks that the raster's first overview is a reduction of its base:
    /// at up to 16 places, each overview pixel must lie within the range
    /// of the four base pixels under it (with a little slack for smoothing
    /// kernels), as nearest, average, bilinear or mode overviews all do.
    ///
    /// A lossless raster with more than one pixel in ten outside is
    /// refused (an overview not rebuilt after its base changed). A lossy
    /// one (`Lossy`) has the slack widened by what its compression may
    /// change; beyond that it is not refused: `Overviews::Rebuild`, its
    /// coarse levels then halved from the base, with a warning.
    pub(super) fn check_overviews(&self) -> Result<Overviews, SourceError> {
        let levels = &self.store.levels;
        let Some(level) = levels.get(1).filter(|l| l.overview.is_some()) else {
            return Ok(Overviews::Agree(None));
        };
        let lossy = super::open_dataset(&self.store.open_path).ok().and_then(|ds| Lossy::of(&ds, &self.path));
        // The tolerance in decoded units: heights scaled as decoded, colours in 0..1.
        let per_unit = match &self.store.decoder {
            Decoder::Height { scale, .. } => scale.abs(),
            Decoder::Palette { .. } | Decoder::Bands { .. } => 1.0 / 255.0,
        };
        let tolerance = lossy.as_ref().map_or(0.0, |l| (l.tolerance * per_unit) as f32);
        const SIDE: usize = 8;
        // At each place, a block or two of each level is decoded: side by
        // side where relief decodes them (GDAL reads take a handle a thread).
        let probe = |k: usize| -> Result<Probe, SourceError> {
            let (fx, fy) = ((k % 4) as f64 / 3.0, (k / 4) as f64 / 3.0);
            let x0 = ((level.width.saturating_sub(SIDE)) as f64 * fx) as usize;
            let y0 = ((level.height.saturating_sub(SIDE)) as f64 * fy) as usize;
            let rect = PixelRect { x0, y0, x1: (x0 + SIDE).min(level.width), y1: (y0 + SIDE).min(level.height) };
            // Read straight from the file: a few pixels, not whole blocks.
            let over = self.store.read_file(level.overview, rect)?;
            let under = PixelRect {
                x0: 2 * rect.x0,
                y0: 2 * rect.y0,
                x1: (2 * rect.x1).min(self.width()),
                y1: (2 * rect.y1).min(self.height()),
            };
            let base = self.store.read_file(None, under)?;
            let (base_width, base_height) = (under.width(), under.height());
            let mut found = Probe::default();
            for (o, b) in over.iter().zip(&base) {
                for j in 0..rect.height() {
                    for i in 0..rect.width() {
                        let v = o[j * rect.width() + i];
                        let below: Vec<f32> = halve::under(b, base_width, base_height, i, j)
                            .into_iter()
                            .flatten()
                            .filter(|h| !h.is_nan())
                            .collect();
                        if v.is_nan() || below.is_empty() {
                            continue;
                        }
                        let lo = below.iter().copied().fold(f32::INFINITY, f32::min);
                        let hi = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                        let slack = 0.25 * (hi - lo) + 0.01 * hi.abs().max(lo.abs()) + 0.5 / 255.0 + tolerance;
                        found.checked += 1;
                        let excess = (lo - slack - v).max(v - hi - slack);
                        if excess > 0.0 {
                            found.off += 1;
                            found.worst = Some((v, lo, hi));
                            found.excess_sum += f64::from(excess);
                            found.excess_max = found.excess_max.max(f64::from(excess));
                        }
                    }
                }
            }
            Ok(found)
        };
        let parallel = self.store.native.is_some() || self.store.tiling.is_some();
        let places: Vec<Probe> = if parallel {
            (0..16).into_par_iter().map(probe).collect::<Result<_, _>>()?
        } else {
            (0..16).map(probe).collect::<Result<_, _>>()?
        };
        let checked: usize = places.iter().map(|p| p.checked).sum();
        let off: usize = places.iter().map(|p| p.off).sum();
        let worst = places.iter().rev().find_map(|p| p.worst).unwrap_or((0.0, 0.0, 0.0));
        let disagree = checked > 0 && off * OFF_SHARE > checked;
        let Some(lossy) = lossy else {
            if disagree {
                return Err(format_err(
                    format!(
                        "its overviews disagree with its base: {off} of {checked} sampled pixels of the first overview \
                         lie outside the range of the base pixels under them (e.g. {} over {}..{}); rebuild them \
                         (gdaladdo) or set overviews = false on the source",
                        worst.0, worst.1, worst.2
                    ),
                    &self.path,
                ));
            }
            return Ok(Overviews::Agree(None));
        };
        let detail = format!(
            "lossy ({}): the first overview checked against the base with a tolerance of {} in stored units ({})",
            lossy.what, lossy.tolerance, lossy.why
        );
        if !disagree {
            return Ok(Overviews::Agree(Some(detail)));
        }
        // Back in stored units (grey levels for bytes), for the sentence.
        let excess_sum: f64 = places.iter().map(|p| p.excess_sum).sum();
        let excess_max = places.iter().map(|p| p.excess_max).fold(0.0, f64::max);
        let (mean, max) = (excess_sum / off as f64 / per_unit, excess_max / per_unit);
        let overviews = levels.iter().filter(|l| l.overview.is_some()).count();
        let warning = format!(
            "{}: its first overview (level 1, {}x{}) differs from its base beyond what its compression ({}) \
             explains: {off} of {checked} sampled pixels ({:.0}%) lie more than {} outside the range of the base \
             pixels under them, by {mean:.1} on average and {max:.1} at most beyond it (stored units); its \
             {overviews} overview{} left out, the coarse levels halved from the base (as with overviews = false)",
            self.path.display(),
            level.width,
            level.height,
            lossy.what,
            100.0 * off as f64 / checked as f64,
            lossy.tolerance,
            if overviews == 1 { "" } else { "s" },
        );
        Ok(Overviews::Rebuild { detail, warning })
    }
}

/// What one place of the overview check found: pixels checked, pixels
/// off, and the last one off (its value and the range under it).
#[derive(Default)]
struct Probe {
    checked: usize,
    off: usize,
    worst: Option<(f32, f32, f32)>,
    /// How far beyond the widened range the pixels off lie, in decoded
    /// units: their sum and the largest.
    excess_sum: f64,
    excess_max: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_jpeg_bound_follows_libjpegs_scaling_of_the_dc_step() {
        assert_eq!(jpeg_dc_step(50), 16);
        assert_eq!(jpeg_dc_step(75), 8);
        assert_eq!(jpeg_dc_step(90), 3);
        assert_eq!(jpeg_dc_step(100), 1);
        assert_eq!(jpeg_dc_step(10), 80);
        assert_eq!(jpeg_dc_step(0), 255);
    }

    #[test]
    fn the_max_z_error_is_read_from_a_lerc2_header() {
        // Version 4: checksum, rows, columns, depth, valid pixels, micro
        // block size, blob size, data type, then the max Z error.
        let mut blob = b"Lerc2 ".to_vec();
        blob.extend(4i32.to_le_bytes());
        blob.extend([0u8; 4 * 8]);
        blob.extend(0.25f64.to_le_bytes());
        blob.extend(1.0f64.to_le_bytes());
        assert_eq!(lerc2_max_z_error(&blob), Some(0.25));
        assert_eq!(lerc2_max_z_error(b"Lerc1 "), None);
        assert_eq!(lerc2_max_z_error(&blob[..30]), None);
    }
}
