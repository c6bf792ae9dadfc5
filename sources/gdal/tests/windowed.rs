//! Windowed reads against whole reads, overviews against halving, and
//! reloads against fresh opens, on files the examples write through GDAL.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::{Path, PathBuf};

use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::{Dataset, DatasetOptions, DriverManager, GdalOpenFlags};
use relief_examples::{self as examples, RasterSpec};
use relief_source::{
    Extent, GenerateContext, GeodeticPoint, NoInputs, OptionValue, Payload, Quality, Refresh, Source, SourceSpec,
    TileGrid, TileKey,
};
use relief_source_gdal::GdalSource;

fn spec(paths: &[&Path], options: &[(&str, OptionValue)]) -> SourceSpec {
    SourceSpec {
        id: "dem".into(),
        kind: "gdal".into(),
        paths: paths.iter().map(|p| p.to_path_buf()).collect(),
        options: options.iter().map(|(k, v)| ((*k).to_owned(), v.clone())).collect(),
        ..SourceSpec::default()
    }
}

fn text(v: &str) -> OptionValue {
    OptionValue::Text(v.into())
}

fn grid() -> TileGrid {
    TileGrid::geodetic(256).unwrap()
}

fn open(path: &Path, options: &[(&str, OptionValue)]) -> GdalSource {
    GdalSource::open(&spec(&[path], options), &grid()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A payload as bytes: heights bit for bit (every NaN alike), colour as is.
fn bytes(payload: &Payload) -> Vec<u8> {
    match payload {
        Payload::Height(h) => {
            h.heights.iter().flat_map(|v| if v.is_nan() { u32::MAX } else { v.to_bits() }.to_le_bytes()).collect()
        }
        Payload::Color(c) => c.rgba.clone(),
        other => panic!("a gdal source made {other:?}"),
    }
}

/// Every tile over the source's extent from level 0 to `max_level`.
fn keys(source: &GdalSource, max_level: u8) -> Vec<TileKey> {
    let extent = source.info().extent.expect("an extent");
    (0..=max_level).flat_map(|l| grid().keys_overlapping(l, &extent)).collect()
}

fn tiles(source: &GdalSource, keys: &[TileKey]) -> Vec<Vec<u8>> {
    let (grid, quality) = (grid(), Quality::default());
    let ctx = GenerateContext { grid: &grid, quality: &quality, inputs: &NoInputs };
    keys.iter().map(|k| bytes(&source.generate(*k, &ctx).unwrap_or_else(|e| panic!("tile {k:?}: {e}")))).collect()
}

fn assert_same_tiles(a: &GdalSource, b: &GdalSource, max_level: u8, what: &str) {
    let keys = keys(a, max_level);
    assert!(!keys.is_empty());
    for ((key, x), y) in keys.iter().zip(tiles(a, &keys)).zip(tiles(b, &keys)) {
        assert!(x == y, "{what}: tile {key:?} differs");
    }
}

/// A copy of `from` as a tiled, compressed GeoTIFF, with overviews made by
/// `overviews` (a GDAL resampling) when given.
fn tiled_copy(from: &Path, to: &Path, overviews: Option<&str>) -> PathBuf {
    let source = Dataset::open(from).unwrap();
    let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
    let options = RasterCreationOptions::from_iter(["TILED=YES", "BLOCKXSIZE=64", "BLOCKYSIZE=64", "COMPRESS=DEFLATE"]);
    let mut copy = source.create_copy(&driver, to, &options).unwrap();
    if let Some(resampling) = overviews {
        copy.build_overviews(resampling, &[2, 4, 8], &[]).unwrap();
    }
    to.to_path_buf()
}

fn update(path: &Path) -> Dataset {
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_RASTER | GdalOpenFlags::GDAL_OF_UPDATE,
        ..DatasetOptions::default()
    };
    Dataset::open_ex(path, options).unwrap()
}

/// Adds `by` to the `w` x `h` window at (x, y) of band 1 of level
/// `overview` (None: the base).
fn bump(ds: &Dataset, overview: Option<usize>, (x, y, w, h): (isize, isize, usize, usize), by: f32) {
    let band = ds.rasterband(1).unwrap();
    let mut band = match overview {
        Some(o) => band.overview(o).unwrap(),
        None => band,
    };
    let old = band.read_as::<f32>((x, y), (w, h), (w, h), None).unwrap();
    let new: Vec<f32> = old.data().iter().map(|v| v + by).collect();
    band.write((x, y), (w, h), &mut Buffer::new((w, h), new)).unwrap();
}

fn refreshed(source: &GdalSource) -> (std::sync::Arc<dyn Source>, Vec<Extent>) {
    // A file written within the same clock tick still differs in size or
    // inode, and the test waits a tick anyway.
    match source.refresh(&grid()).unwrap() {
        Refresh::Changed { source, dirty } => {
            let extents = dirty.extents(&grid());
            (source, extents)
        }
        Refresh::Unchanged => panic!("the edit was not seen"),
    }
}

fn same_dyn(a: &dyn Source, b: &GdalSource, max_level: u8, what: &str) {
    let (grid, quality) = (grid(), Quality::default());
    let ctx = GenerateContext { grid: &grid, quality: &quality, inputs: &NoInputs };
    for key in keys(b, max_level) {
        let x = bytes(&a.generate(key, &ctx).unwrap());
        let y = bytes(&b.generate(key, &ctx).unwrap());
        assert!(x == y, "{what}: tile {key:?} differs from a fresh open");
    }
}

/// Bytes read by a refreshed gdal source (the trait object of a refresh).
fn new_bytes_read(source: &dyn Source) -> u64 {
    source.info().details["bytes_read"].parse().unwrap()
}

struct Fixture {
    name: &'static str,
    path: PathBuf,
    options: Vec<(&'static str, OptionValue)>,
    max_level: u8,
}

fn fixtures(dir: &Path) -> Vec<Fixture> {
    examples::write_demo_scene(dir).unwrap();
    let hill = examples::write_dem(&dir.join("hill.tif"), &examples::hill_spec(), examples::hill).unwrap();
    let utm = examples::write_dem(&dir.join("utm.tif"), &examples::utm_spec(), examples::utm_surface).unwrap();
    let holes = examples::write_dem(
        &dir.join("holes.tif"),
        &RasterSpec { nodata: Some(-9999.0), ..examples::hill_spec() },
        |lon, lat| {
            if ((lon * 40.0).floor() + (lat * 40.0).floor()) % 3.0 == 0.0 { -9999.0 } else { examples::hill(lon, lat) }
        },
    )
    .unwrap();
    let tiled = tiled_copy(&hill, &dir.join("hill-tiled.tif"), None);
    // The whole planet: columns wrap at the antimeridian, rows reach both poles.
    let globe = examples::write_dem(&dir.join("globe.tif"), &examples::globe_spec(), |lon, lat| {
        1000.0 * (lon.to_radians() * 3.0).sin() * lat.to_radians().cos() + 10.0 * lat
    })
    .unwrap();
    let f = |name, path: PathBuf, options: Vec<(&'static str, OptionValue)>, max_level| Fixture {
        name,
        path,
        options,
        max_level,
    };
    vec![
        f("hill", hill, vec![], 10),
        f("globe (antimeridian, poles)", globe, vec![], 4),
        f("hill, tiled", tiled, vec![], 10),
        f("holes", holes, vec![], 10),
        f("utm (reprojected)", utm, vec![], 11),
        f("demo dem (a void)", dir.join("dem.tif"), vec![], 9),
        f("demo ortho (colour)", dir.join("ortho.tif"), vec![], 9),
        f("demo land cover (classes)", dir.join("landcover.tif"), vec![("resampling", text("nearest"))], 9),
        f("hill, cubic", dir.join("hill.tif"), vec![("resampling", text("cubic"))], 10),
    ]
}

/// A copy of the DEM `from` as `T` (each value through `convert`, nodata
/// kept), written with `options`, with overviews 2, 4 and 8: `from`'s own
/// where it has them (the same values), else AVERAGE ones GDAL makes.
fn copy_as<T: gdal::raster::GdalType + Copy>(
    from: &Path,
    to: &Path,
    options: &[&str],
    convert: impl Fn(f64) -> T,
) -> PathBuf {
    let source = Dataset::open(from).unwrap();
    let band = source.rasterband(1).unwrap();
    let values = |band: &gdal::raster::RasterBand<'_>| -> Vec<T> {
        let (w, h) = band.size();
        band.read_as::<f64>((0, 0), (w, h), (w, h), None).unwrap().data().iter().map(|v| convert(*v)).collect()
    };
    let (w, h) = band.size();
    let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
    let options: RasterCreationOptions = options.iter().copied().collect();
    let mut copy = driver.create_with_band_type_with_options::<T, _>(to, w, h, 1, &options).unwrap();
    copy.set_geo_transform(&source.geo_transform().unwrap()).unwrap();
    copy.set_spatial_ref(&source.spatial_ref().unwrap()).unwrap();
    let mut out = copy.rasterband(1).unwrap();
    out.set_no_data_value(band.no_data_value()).unwrap();
    out.write((0, 0), (w, h), &mut Buffer::new((w, h), values(&band))).unwrap();
    copy.build_overviews("AVERAGE", &[2, 4, 8], &[]).unwrap();
    let out = copy.rasterband(1).unwrap();
    for o in 0..band.overview_count().unwrap() as usize {
        let (theirs, mut ours) = (band.overview(o).unwrap(), out.overview(o).unwrap());
        assert_eq!(theirs.size(), ours.size());
        let size = theirs.size();
        ours.write((0, 0), size, &mut Buffer::new(size, values(&theirs))).unwrap();
    }
    to.to_path_buf()
}

/// Int16 heights kept in the block cache as the file stores them give the
/// tiles of the same heights in a Float32 file (read as f32 through GDAL):
/// voids, edges and overviews alike, whether relief decodes the Int16
/// file's blocks (deflate) or GDAL reads them (LZW). The scene state says
/// which is which.
#[test]
fn sixteen_bit_heights_kept_as_stored_give_the_tiles_f32_heights_give() {
    let dir = tempfile::tempdir().unwrap();
    let holes = examples::write_dem(
        &dir.path().join("holes.tif"),
        &RasterSpec { nodata: Some(-9999.0), ..examples::hill_spec() },
        |lon, lat| {
            if ((lon * 40.0).floor() + (lat * 40.0).floor()) % 3.0 == 0.0 { -9999.0 } else { examples::hill(lon, lat) }
        },
    )
    .unwrap();
    let tiled = ["TILED=YES", "BLOCKXSIZE=64", "BLOCKYSIZE=64"];
    let with = |extra: &[&'static str]| tiled.iter().chain(extra).copied().collect::<Vec<&str>>();
    let path = |name: &str| dir.path().join(name);
    let deflated =
        copy_as(&holes, &path("deflate.tif"), &with(&["COMPRESS=DEFLATE", "PREDICTOR=2"]), |v| v.round() as i16);
    let lzw = copy_as(&deflated, &path("lzw.tif"), &with(&["COMPRESS=LZW"]), |v| v as i16);
    let floats = copy_as(&deflated, &path("f32.tif"), &with(&["COMPRESS=LZW"]), |v| v as f32);
    for read in ["windowed", "whole"] {
        let open = |path: &Path| open(path, &[("read", text(read))]);
        let reference = open(&floats);
        assert!(reference.info().details["block_cache"].starts_with("decoded f32"), "{:?}", reference.info().details);
        for (name, file) in [("decoded here", &deflated), ("read through GDAL", &lzw)] {
            let kept = open(file);
            assert!(kept.info().details["block_cache"].starts_with("16-bit"), "{name}: {:?}", kept.info().details);
            assert_same_tiles(&kept, &reference, 10, &format!("Int16 {name}, kept 16-bit, against f32 ({read})"));
        }
    }
}

#[test]
fn windowed_reads_give_the_same_tiles_as_whole_reads_on_every_fixture() {
    let dir = tempfile::tempdir().unwrap();
    for fx in fixtures(dir.path()) {
        let with = |read: &str| {
            let mut options = fx.options.clone();
            options.push(("read", text(read)));
            open(&fx.path, &options)
        };
        let (whole, windowed) = (with("whole"), with("windowed"));
        assert!(whole.info().details["read"].starts_with("whole"), "{}", fx.name);
        assert!(windowed.info().details["read"].starts_with("windowed"), "{}", fx.name);
        assert_same_tiles(&whole, &windowed, fx.max_level, fx.name);
        if whole.output() == relief_source::PayloadKind::Height {
            // A diagonal across the data, its ends and the poles included.
            let e = whole.info().extent.unwrap();
            let points: Vec<GeodeticPoint> = (0..=50)
                .map(|i| {
                    let t = f64::from(i) / 50.0;
                    GeodeticPoint { lon_deg: e.min_x + e.width() * t, lat_deg: e.max_y - e.height() * t }
                })
                .collect();
            let q = Quality::default();
            let a = whole.sample_heights(&points, &q).unwrap();
            let b = windowed.sample_heights(&points, &q).unwrap();
            assert_eq!(a, b, "{}: elevations", fx.name);
            assert!(a.iter().filter(|h| h.is_some()).count() > 10, "{}: the points fall on the data", fx.name);
        }
    }
}

#[test]
fn overviews_and_halving_give_heights_within_the_kernel_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let hill = examples::write_dem(&dir.path().join("hill.tif"), &examples::hill_spec(), examples::hill).unwrap();
    let with = tiled_copy(&hill, &dir.path().join("with.tif"), Some("AVERAGE"));
    let overviews = open(&with, &[("read", text("windowed"))]);
    let halved = open(&with, &[("read", text("windowed")), ("overviews", OptionValue::Bool(false))]);
    assert!(overviews.info().details["overviews"].contains("3 of the file's"), "{:?}", overviews.info().details);
    assert!(halved.info().details["overviews"].starts_with("none"));
    // Levels 4..=8 read mips 1..=3 of this raster (pixels of 0.00125 degrees).
    let keys: Vec<TileKey> = keys(&overviews, 8).into_iter().filter(|k| k.level >= 4).collect();
    let (a, b) = (tiles(&overviews, &keys), tiles(&halved, &keys));
    let mut worst = 0.0f32;
    for (x, y) in a.iter().zip(&b) {
        for (p, q) in x.chunks(4).zip(y.chunks(4)) {
            let (p, q) = (f32::from_le_bytes(p.try_into().unwrap()), f32::from_le_bytes(q.try_into().unwrap()));
            if !p.is_nan() && !q.is_nan() {
                worst = worst.max((p - q).abs());
            }
        }
    }
    // GDAL's average overviews are means of the base, relief's halvings
    // means of means: the same but for float rounding and the ragged edge
    // (400 is not a multiple of 8). Tolerance: 0.05 m on a 1500 m hill.
    assert!(worst < 0.05, "overviews and halving differ by {worst} m");
}

#[test]
fn overviews_in_a_side_file_are_found_in_a_folder_of_many_files() {
    // relief turns off GDAL's listing of a file's folder at each open:
    // GDAL must still find a .ovr beside the file by its name.
    let dir = tempfile::tempdir().unwrap();
    let hill = examples::write_dem(&dir.path().join("hill.tif"), &examples::hill_spec(), examples::hill).unwrap();
    let inside = tiled_copy(&hill, &dir.path().join("inside.tif"), Some("AVERAGE"));
    let beside = tiled_copy(&hill, &dir.path().join("beside.tif"), None);
    // Opened read-only, GDAL writes the overviews to beside.tif.ovr.
    Dataset::open(&beside).unwrap().build_overviews("AVERAGE", &[2, 4, 8], &[]).unwrap();
    assert!(dir.path().join("beside.tif.ovr").exists());
    for k in 0..200 {
        std::fs::write(dir.path().join(format!("other-{k:03}.tif")), b"not read").unwrap();
    }
    let (inside, beside) = (open(&inside, &[("read", text("windowed"))]), open(&beside, &[("read", text("windowed"))]));
    if std::env::var_os("GDAL_DISABLE_READDIR_ON_OPEN").is_none() {
        let listing_off = gdal::config::get_config_option("GDAL_DISABLE_READDIR_ON_OPEN", "").unwrap();
        assert_eq!(listing_off, "TRUE", "the gdal source turns the listing off when it opens a raster");
    }
    let details = beside.info().details;
    assert!(details["overviews"].contains("3 of the file's"), "{details:?}");
    // The same overviews, from the file or beside it: the same tiles.
    assert_same_tiles(&inside, &beside, 8, "overviews beside the file");
}

#[test]
fn a_large_raster_is_never_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    // 4096 x 4096 Int16 (32 MiB of samples), tiled, with overviews: a
    // test-sized version of the 3.2 GB benchmark raster.
    let side = 4096usize;
    let spec = RasterSpec {
        width: side,
        height: side,
        origin_x: 7.0,
        origin_y: 47.0,
        pixel: 1e-4,
        crs: "EPSG:4326",
        nodata: None,
    };
    let path = dir.path().join("large.tif");
    {
        let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
        let options = RasterCreationOptions::from_iter(["TILED=YES", "COMPRESS=DEFLATE", "PREDICTOR=2"]);
        let mut ds = driver.create_with_band_type_with_options::<i16, _>(&path, side, side, 1, &options).unwrap();
        ds.set_geo_transform(&[spec.origin_x, spec.pixel, 0.0, spec.origin_y, 0.0, -spec.pixel]).unwrap();
        ds.set_spatial_ref(&gdal::spatial_ref::SpatialRef::from_epsg(4326).unwrap()).unwrap();
        let mut band = ds.rasterband(1).unwrap();
        for y0 in (0..side).step_by(512) {
            let data: Vec<i16> = (y0..y0 + 512)
                .flat_map(|j| {
                    (0..side)
                        .map(move |i| (((i as f64 / 300.0).sin() + (j as f64 / 170.0).cos()) * 400.0 + 1000.0) as i16)
                })
                .collect();
            band.write((0, y0 as isize), (side, 512), &mut Buffer::new((side, 512), data)).unwrap();
        }
        ds.build_overviews("AVERAGE", &[2, 4, 8, 16], &[]).unwrap();
    }
    let whole_bytes = (side * side * 2) as f64;
    let source = open(&path, &[("read", text("windowed"))]);
    let opened = source.bytes_read() as f64;
    assert!(opened / whole_bytes < 0.02, "opening read {opened} bytes of {whole_bytes}");
    // The whole raster from afar, a mid level, and a close-up.
    let extent = source.info().extent.unwrap();
    let mut keys = grid().keys_overlapping(4, &extent);
    keys.extend(grid().keys_overlapping(8, &extent).into_iter().take(2));
    keys.extend(grid().key_at(12, 7.2, 46.8));
    tiles(&source, &keys);
    let read = source.bytes_read() as f64;
    assert!(read / whole_bytes < 0.1, "tiles read {read} bytes of {whole_bytes} ({:.1}%)", 100.0 * read / whole_bytes);
    assert!(read > opened, "the tiles read something");
}

#[test]
fn reloads_read_only_changed_blocks_and_equal_a_fresh_open() {
    let dir = tempfile::tempdir().unwrap();
    let hill = examples::write_dem(&dir.path().join("hill.tif"), &examples::hill_spec(), examples::hill).unwrap();
    // Striped, tiled, tiled with overviews, and a format without block
    // offsets (HFA), each edited in place by GDAL.
    let hfa = {
        let src = Dataset::open(&hill).unwrap();
        let driver = DriverManager::get_driver_by_name("HFA").unwrap();
        src.create_copy(&driver, dir.path().join("hill.img"), &RasterCreationOptions::new()).unwrap();
        dir.path().join("hill.img")
    };
    let cases = [
        ("striped", hill.clone(), false),
        ("tiled", tiled_copy(&hill, &dir.path().join("tiled.tif"), None), false),
        ("tiled with overviews", tiled_copy(&hill, &dir.path().join("ovr.tif"), Some("AVERAGE")), true),
        ("HFA", hfa, false),
    ];
    for (name, path, overviews) in cases {
        for (read, mode) in [("windowed", "exact"), ("windowed", "layout"), ("whole", "exact")] {
            let options = [("read", text(read)), ("change_detection", text(mode))];
            let source = open(&path, &options);
            let keys = keys(&source, 10);
            tiles(&source, &keys);
            std::thread::sleep(std::time::Duration::from_millis(20));
            {
                let ds = update(&path);
                // 20 x 20 pixels at (300, 100): 10.375..10.4 E, 45.35..45.375 N.
                bump(&ds, None, (300, 100, 20, 20), 25.0);
                if overviews {
                    for (o, f) in [(0usize, 2isize), (1, 4), (2, 8)] {
                        let (x0, y0) = (300 / f, 100 / f);
                        let (x1, y1) = ((320 + f - 1) / f, (120 + f - 1) / f);
                        bump(&ds, Some(o), (x0, y0, (x1 - x0) as usize, (y1 - y0) as usize), 25.0);
                    }
                }
            }
            let before = source.bytes_read();
            let (new, dirty) = refreshed(&source);
            let fresh = open(&path, &options);
            same_dyn(new.as_ref(), &fresh, 10, &format!("{name}, {mode}"));
            // The dirt is the edit's neighbourhood, not the raster.
            let edit = Extent::new(10.375, 45.35, 10.4, 45.375);
            assert!(!dirty.is_empty(), "{name}: no dirt");
            let area: f64 = dirty.iter().map(|e| e.width() * e.height()).sum();
            assert!(dirty.iter().all(|e| e.touches(&edit)), "{name}, {mode}: {dirty:?}");
            assert!(area < 0.25 * 0.25 * 0.5, "{name}, {mode}: dirt of {area} square degrees: {dirty:?}");
            // A TIFF's changed blocks are found from its block tables: only
            // they are read (the edit's block and its overviews' pixels),
            // not the raster's 400 x 400 x 4 bytes. Any other format is
            // hashed block by block (one pass) and its changed blocks read.
            let read = new_bytes_read(new.as_ref()) - before;
            let limit = if name == "HFA" { 400 * 400 * 4 + 256 * 256 * 4 } else { 3 * 256 * 256 * 4 };
            assert!(read <= limit, "{name}, {mode}: the reload read {read} bytes");
            // Put the file back for the next mode.
            let ds = update(&path);
            bump(&ds, None, (300, 100, 20, 20), -25.0);
            if overviews {
                for (o, f) in [(0usize, 2isize), (1, 4), (2, 8)] {
                    let (x0, y0) = (300 / f, 100 / f);
                    let (x1, y1) = ((320 + f - 1) / f, (120 + f - 1) / f);
                    bump(&ds, Some(o), (x0, y0, (x1 - x0) as usize, (y1 - y0) as usize), -25.0);
                }
            }
        }
    }
}

/// The hill as four 200 x 200 quadrant files and a VRT over them
/// (gdalbuildvrt); returns the VRT and the quadrants (NW, NE, SW, SE).
fn quadrants(dir: &Path) -> (PathBuf, Vec<PathBuf>) {
    let base = examples::hill_spec();
    let mut files = Vec::new();
    for (n, (i, j)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
        let spec = RasterSpec {
            width: 200,
            height: 200,
            origin_x: base.origin_x + f64::from(i) * 0.25,
            origin_y: base.origin_y - f64::from(j) * 0.25,
            ..base
        };
        let path = dir.join(format!("q{n}.tif"));
        files.push(tiled_copy(
            &examples::write_dem(&dir.join(format!("strip{n}.tif")), &spec, examples::hill).unwrap(),
            &path,
            None,
        ));
    }
    let vrt = dir.join("mosaic.vrt");
    let status = std::process::Command::new("gdalbuildvrt")
        .arg("-q")
        .arg(&vrt)
        .args(&files)
        .status()
        .expect("gdalbuildvrt (gdal-bin) is installed");
    assert!(status.success());
    (vrt, files)
}

#[test]
fn a_vrt_mosaic_edit_dirties_only_its_files_area() {
    let dir = tempfile::tempdir().unwrap();
    let (vrt, files) = quadrants(dir.path());
    let options = [("read", text("windowed"))];
    let source = open(&vrt, &options);
    assert_eq!(source.info().files.len(), 5, "the VRT and its members: {:?}", source.info().files);
    // gdalbuildvrt places whole files pixel for pixel: read from them.
    assert!(source.info().details.contains_key("mosaic_reads"), "{:?}", source.info().details);
    tiles(&source, &keys(&source, 10));
    std::thread::sleep(std::time::Duration::from_millis(20));
    // Edit the south-east quadrant (10.25..10.5 E, 45..45.25 N).
    bump(&update(&files[3]), None, (50, 60, 30, 30), 40.0);
    let (new, dirty) = refreshed(&source);
    let quadrant = Extent::new(10.25, 45.0, 10.5, 45.25);
    let margin = 4.0 * 180.0 / 1024.0 / 256.0 * 16.0;
    assert!(!dirty.is_empty());
    for e in &dirty {
        assert!(
            e.min_x >= quadrant.min_x - margin && e.max_y <= quadrant.max_y + margin,
            "dirt {e:?} reaches beyond the edited file's area"
        );
    }
    let area: f64 = dirty.iter().map(|e| e.width() * e.height()).sum();
    assert!(area < 0.25 * 0.25 * 0.25, "dirt of {area} square degrees for a 30 x 30 pixel edit");
    same_dyn(new.as_ref(), &open(&vrt, &options), 10, "mosaic after an edit");
}

#[test]
fn a_vrt_with_missing_files_names_each_and_serves_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let (vrt, files) = quadrants(dir.path());
    let full = open(&vrt, &[]);
    let (nw, se) = (files[0].clone(), files[3].clone());
    let kept = dir.path().join("kept");
    std::fs::create_dir(&kept).unwrap();
    for f in [&nw, &se] {
        std::fs::rename(f, kept.join(f.file_name().unwrap())).unwrap();
    }
    let source = open(&vrt, &[]);
    let details = source.info().details;
    let missing = &details["missing_files"];
    assert!(missing.contains(nw.to_str().unwrap()) && missing.contains(se.to_str().unwrap()), "{missing}");
    assert!(!missing.contains("q1.tif") && !missing.contains("q2.tif"), "{missing}");
    // The present quadrants as before; the missing ones are nodata.
    let q = Quality::default();
    let points = |lon: f64, lat: f64| [GeodeticPoint { lon_deg: lon, lat_deg: lat }];
    for (lon, lat, there) in [(10.4, 45.4, true), (10.1, 45.1, true), (10.1, 45.4, false), (10.4, 45.1, false)] {
        let got = source.sample_heights(&points(lon, lat), &q).unwrap()[0];
        if there {
            assert_eq!(got, full.sample_heights(&points(lon, lat), &q).unwrap()[0], "({lon}, {lat})");
        } else {
            assert_eq!(got, None, "({lon}, {lat}) lies in a missing file");
        }
    }
    tiles(&source, &keys(&source, 9));
    // A missing file put back is a change: the whole mosaic serves again.
    assert!(source.info().files.contains(&nw), "missing files are watched");
    for f in [&nw, &se] {
        std::fs::rename(kept.join(f.file_name().unwrap()), f).unwrap();
    }
    let (back, _) = refreshed(&source);
    assert!(!back.info().details.contains_key("missing_files"));
    let (a, b) =
        (back.sample_heights(&points(10.1, 45.4), &q).unwrap(), full.sample_heights(&points(10.1, 45.4), &q).unwrap());
    assert_eq!(a, b);
    // None of them there: refused, naming them.
    for f in &files {
        std::fs::remove_file(f).unwrap();
    }
    let e = GdalSource::open(&spec(&[&vrt], &[]), &grid()).unwrap_err().to_string();
    assert!(
        e.contains("none of the VRT's files is there") && e.contains("q2.tif") && e.contains(vrt.to_str().unwrap()),
        "{e}"
    );
}

#[test]
fn a_raster_whose_overviews_disagree_with_its_base_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let hill = examples::write_dem(&dir.path().join("hill.tif"), &examples::hill_spec(), examples::hill).unwrap();
    let path = tiled_copy(&hill, &dir.path().join("stale.tif"), Some("AVERAGE"));
    // The base rewritten (upside down) without rebuilding the overviews.
    {
        let ds = update(&path);
        let mut band = ds.rasterband(1).unwrap();
        let old = band.read_as::<f32>((0, 0), (400, 400), (400, 400), None).unwrap();
        let flipped: Vec<f32> = old.data().chunks(400).rev().flatten().map(|v| 3000.0 - v).collect();
        band.write((0, 0), (400, 400), &mut Buffer::new((400, 400), flipped)).unwrap();
    }
    let e = GdalSource::open(&spec(&[&path], &[]), &grid()).unwrap_err().to_string();
    assert!(e.contains("overviews disagree with its base") && e.contains(path.to_str().unwrap()), "{e}");
    assert!(e.contains("gdaladdo") && e.contains("overviews = false"), "says what to do: {e}");
    // Told to ignore them, the raster opens.
    open(&path, &[("overviews", OptionValue::Bool(false))]);
    // Consistent overviews (nearest, average) pass the check.
    for resampling in ["NEAREST", "AVERAGE", "BILINEAR"] {
        let fine = tiled_copy(&hill, &dir.path().join(format!("{resampling}.tif")), Some(resampling));
        open(&fine, &[]);
    }
}

#[test]
fn a_windowed_raster_cut_short_is_refused_when_it_opens() {
    let dir = tempfile::tempdir().unwrap();
    let hill = examples::write_dem(&dir.path().join("hill.tif"), &examples::hill_spec(), examples::hill).unwrap();
    for (name, path) in [("striped", hill.clone()), ("tiled", tiled_copy(&hill, &dir.path().join("tiled.tif"), None))] {
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() * 2 / 3]).unwrap();
        let e = GdalSource::open(&spec(&[&path], &[("read", text("windowed"))]), &grid()).unwrap_err().to_string();
        assert!(e.contains("cut short") && e.contains(path.to_str().unwrap()), "{name}: {e}");
    }
}
