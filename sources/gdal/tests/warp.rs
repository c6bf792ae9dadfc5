//! Rasters georeferenced by GCPs (warped north-up) or by a rotated
//! geotransform (sampled through it), against the analytic plane the test
//! writes into them: the served heights at known map coordinates, through
//! `sample_heights` and through tiles of a projected grid.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::{Path, PathBuf};

use gdal::raster::{Buffer, ColorEntry, ColorTable};
use gdal::spatial_ref::{CoordTransform, SpatialRef};
use gdal::{Dataset, DatasetOptions, DriverManager, GdalOpenFlags};
use relief_source::{
    GenerateContext, GeodeticPoint, GridKind, NoInputs, OptionValue, Payload, ProjectedGrid, Quality, Refresh,
    SampleKind, Source, SourceSpec, TileGrid,
};
use relief_source_gdal::GdalSource;

/// The raster's CRS and the scene grid's.
const CRS: &str = "EPSG:32632";
/// The map origin of the fixtures (easting, northing), and the pixel size.
const E0: f64 = 500_000.0;
const N0: f64 = 5_000_000.0;
const PIXEL_M: f64 = 10.0;
const SIZE: (usize, usize) = (400, 300);

/// The analytic surface: a plane in map metres from the origin.
fn plane(x: f64, y: f64) -> f64 {
    100.0 + 0.5 * (x - E0) + 0.25 * (y - N0)
}

/// The geotransform of the fixtures' frame: pixels of `PIXEL_M`, columns
/// turned `degrees` anticlockwise from east.
fn rotated(degrees: f64) -> [f64; 6] {
    let (s, c) = degrees.to_radians().sin_cos();
    [E0, PIXEL_M * c, PIXEL_M * s, N0, PIXEL_M * s, -PIXEL_M * c]
}

fn apply(gt: &[f64; 6], p: f64, l: f64) -> (f64, f64) {
    (gt[0] + p * gt[1] + l * gt[2], gt[3] + p * gt[4] + l * gt[5])
}

/// How a fixture is georeferenced.
enum Georef {
    Geotransform([f64; 6]),
    /// GCPs on a `cols` x `rows` lattice over the raster, placed by the frame.
    Gcps {
        frame: [f64; 6],
        cols: usize,
        rows: usize,
    },
}

/// Georeferences `ds` as `georef` says, in `CRS`.
fn set_georef(ds: &mut Dataset, georef: &Georef) {
    let srs = SpatialRef::from_definition(CRS).unwrap();
    match georef {
        Georef::Geotransform(gt) => {
            ds.set_geo_transform(gt).unwrap();
            ds.set_spatial_ref(&srs).unwrap();
        }
        Georef::Gcps { frame, cols, rows } => {
            let mut gcps = Vec::new();
            for j in 0..*rows {
                for i in 0..*cols {
                    let p = (SIZE.0 as f64) * i as f64 / (*cols - 1).max(1) as f64;
                    let l = (SIZE.1 as f64) * j as f64 / (*rows - 1).max(1) as f64;
                    let (x, y) = apply(frame, p, l);
                    let id = format!("{}", gcps.len() + 1);
                    gcps.push(gdal::Gcp { id, info: String::new(), pixel: p, line: l, x, y, z: 0.0 });
                }
            }
            ds.set_gcps(gcps, &srs).unwrap();
        }
    }
}

/// Writes a Float32 GeoTIFF of the plane (plus `offset`) in `frame`,
/// georeferenced as `georef` says; a new file over any old one.
fn write_plane(path: &Path, frame: &[f64; 6], georef: &Georef, offset: f64) -> PathBuf {
    let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
    let part = path.with_extension("part.tif");
    let mut ds = driver.create_with_band_type::<f32, _>(&part, SIZE.0, SIZE.1, 1).unwrap();
    set_georef(&mut ds, georef);
    let mut values = Vec::with_capacity(SIZE.0 * SIZE.1);
    for l in 0..SIZE.1 {
        for p in 0..SIZE.0 {
            let (x, y) = apply(frame, p as f64 + 0.5, l as f64 + 0.5);
            values.push((plane(x, y) + offset) as f32);
        }
    }
    let mut band = ds.rasterband(1).unwrap();
    band.set_no_data_value(Some(-9999.0)).unwrap();
    band.write((0, 0), SIZE, &mut Buffer::new(SIZE, values)).unwrap();
    drop(ds);
    std::fs::rename(&part, path).unwrap();
    path.to_path_buf()
}

fn grid() -> TileGrid {
    // Level 0 is one tile of 8192 m: samples of 32 m (read from the
    // raster's mip 1); of 16 m and 8 m at levels 1 and 2 (from its base).
    let kind =
        GridKind::Projected(ProjectedGrid { crs: CRS.into(), min_x: E0 - 1192.0, min_y: N0 - 3500.0, size: 8192.0 });
    TileGrid::new(kind, 256).unwrap()
}

fn spec(path: &Path, read: &str) -> SourceSpec {
    SourceSpec {
        id: "dem".into(),
        kind: "gdal".into(),
        paths: vec![path.to_path_buf()],
        options: [("read".to_owned(), OptionValue::Text(read.into()))].into_iter().collect(),
        ..SourceSpec::default()
    }
}

/// Opens `path` as a gdal source, read `whole` or `windowed`.
fn open(path: &Path, read: &str) -> GdalSource {
    GdalSource::open(&spec(path, read), &grid()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Points well inside the frame (at least `margin` pixels from its edges), in map coordinates.
fn inner_points(frame: &[f64; 6], margin: f64) -> Vec<(f64, f64)> {
    let mut points = Vec::new();
    for j in 0..=10 {
        for i in 0..=10 {
            let p = margin + (SIZE.0 as f64 - 2.0 * margin) * f64::from(i) / 10.0;
            let l = margin + (SIZE.1 as f64 - 2.0 * margin) * f64::from(j) / 10.0;
            points.push(apply(frame, p, l));
        }
    }
    points
}

/// A source's heights at map points (through `sample_heights`, which
/// takes longitudes and latitudes).
fn heights_at_dyn(source: &dyn Source, points: &[(f64, f64)]) -> Vec<Option<f64>> {
    let mut utm = SpatialRef::from_definition(CRS).unwrap();
    let mut wgs84 = SpatialRef::from_definition("EPSG:4326").unwrap();
    utm.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    wgs84.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&utm, &wgs84).unwrap();
    let mut xs: Vec<f64> = points.iter().map(|p| p.0).collect();
    let mut ys: Vec<f64> = points.iter().map(|p| p.1).collect();
    t.transform_coords(&mut xs, &mut ys, &mut []).unwrap();
    let geodetic: Vec<GeodeticPoint> =
        xs.iter().zip(&ys).map(|(lon, lat)| GeodeticPoint { lon_deg: *lon, lat_deg: *lat }).collect();
    source.sample_heights(&geodetic, &Quality::default()).unwrap()
}

fn heights_at(source: &GdalSource, points: &[(f64, f64)]) -> Vec<Option<f64>> {
    heights_at_dyn(source, points)
}

/// The worst difference from the plane at `points`; panics on a point with no height.
fn worst_error(source: &GdalSource, points: &[(f64, f64)], offset: f64) -> f64 {
    let heights = heights_at(source, points);
    points
        .iter()
        .zip(heights)
        .map(|(&(x, y), h)| {
            let h = h.unwrap_or_else(|| panic!("no height at ({x}, {y})"));
            (h - plane(x, y) - offset).abs()
        })
        .fold(0.0, f64::max)
}

/// The worst difference from the plane over every height-tile sample at
/// `level` that lies at least `margin` pixels inside the frame; and how many were checked.
fn worst_tile_error(source: &GdalSource, frame: &[f64; 6], level: u8, margin: f64, offset: f64) -> (f64, usize) {
    let grid = grid();
    let quality = Quality::default();
    let ctx = GenerateContext { grid: &grid, quality: &quality, inputs: &NoInputs };
    let extent = source.info().extent.unwrap();
    let inverse = invert(frame);
    let (mut worst, mut checked) = (0.0f64, 0usize);
    for key in grid.keys_overlapping(level, &extent) {
        let Payload::Height(tile) = source.generate(key, &ctx).unwrap() else { panic!("not heights") };
        let lattice = grid.lattice(key, SampleKind::Corner);
        for j in 0..lattice.rows {
            for i in 0..lattice.cols {
                let (x, y) = (lattice.x(i), lattice.y(j));
                let (p, l) = apply(&inverse, x, y);
                if p < margin || l < margin || p > SIZE.0 as f64 - margin || l > SIZE.1 as f64 - margin {
                    continue;
                }
                let h = tile.heights[j * lattice.cols + i];
                assert!(!h.is_nan(), "no height at ({x}, {y}), pixel ({p}, {l}) of the frame");
                worst = worst.max((f64::from(h) - plane(x, y) - offset).abs());
                checked += 1;
            }
        }
    }
    (worst, checked)
}

fn invert(gt: &[f64; 6]) -> [f64; 6] {
    let det = gt[1] * gt[5] - gt[2] * gt[4];
    let (a, b, c, d) = (gt[5] / det, -gt[2] / det, -gt[4] / det, gt[1] / det);
    [-(a * gt[0] + b * gt[3]), a, b, -(c * gt[0] + d * gt[3]), c, d]
}

/// Tolerance on the plane, in metres: heights are Float32 (a unit in the
/// last place of 1000 m is 6e-5 m) and bilinear interpolation of a plane
/// is exact, through the warp and through relief's own kernel alike.
const TOLERANCE_M: f64 = 1e-3;

/// Checks the heights a source serves against the plane, at points and in
/// tiles of levels 0 to 2; returns the worst errors (points, tiles).
fn check_plane(source: &GdalSource, frame: &[f64; 6], offset: f64, what: &str) -> (f64, f64) {
    let points = worst_error(source, &inner_points(frame, 2.0), offset);
    assert!(points < TOLERANCE_M, "{what}: heights at points differ from the plane by {points} m");
    let mut tiles = 0.0f64;
    for level in 0..=2 {
        // Level 0 reads mip 1, whose pixels average 2 x 2 of the base: keep
        // clear of the edge by its width too.
        let margin = if level == 0 { 6.0 } else { 2.0 };
        let (worst, checked) = worst_tile_error(source, frame, level, margin, offset);
        assert!(checked > 1000, "{what}: level {level}: only {checked} samples on the raster");
        assert!(worst < TOLERANCE_M, "{what}: level {level}: tiles differ from the plane by {worst} m");
        tiles = tiles.max(worst);
    }
    (points, tiles)
}

#[test]
fn a_raster_georeferenced_only_by_gcps_is_warped_north_up_and_serves_its_plane() {
    let dir = tempfile::tempdir().unwrap();
    let frame = rotated(30.0);
    // 4 GCPs: a first-order fit; 12: GDAL's default order for six and
    // more, the second; and the file's overviews, which GDAL warps into
    // the warp's (mip 1, read by level 0, comes from there).
    for (cols, rows, order, overviews) in
        [(2, 2, "first-order", false), (4, 3, "second-order", false), (4, 3, "second-order", true)]
    {
        let path = dir.path().join(format!("gcps-{cols}x{rows}-{overviews}.tif"));
        write_plane(&path, &frame, &Georef::Gcps { frame, cols, rows }, 0.0);
        if overviews {
            let options = DatasetOptions { open_flags: GdalOpenFlags::GDAL_OF_UPDATE, ..DatasetOptions::default() };
            let mut ds = Dataset::open_ex(&path, options).unwrap();
            ds.build_overviews("AVERAGE", &[2, 4], &[]).unwrap();
        }
        for read in ["whole", "windowed"] {
            let source = open(&path, read);
            let info = source.info();
            let georeferencing = &info.details["georeferencing"];
            let what = format!("{} GCPs, overviews {overviews}, {read}", cols * rows);
            let used = if overviews { "2 of the file's" } else { "none" };
            assert!(info.details["overviews"].starts_with(used), "{what}: {:?}", info.details);
            assert!(
                georeferencing.starts_with(&format!("{} GCPs, fitted by a {order} polynomial", cols * rows)),
                "{georeferencing}"
            );
            assert!(georeferencing.contains("largest residual 0.000 m, 0.00 pixels"), "{georeferencing}");
            assert!(georeferencing.contains("pixels of 10.000 m"), "{georeferencing}");
            assert!(info.details["change_detection"].contains("hashes of its warped values"), "{:?}", info.details);
            assert_eq!(info.warnings.len(), 1, "{:?}", info.warnings);
            assert!(info.warnings[0].contains("GCPs") && info.warnings[0].ends_with(&path.display().to_string()));
            // The warp keeps the file's pixel count along its diagonal: 10 m pixels.
            let resolution = info.resolution.unwrap();
            assert!((resolution - PIXEL_M).abs() < 1e-6, "{what}: resolution {resolution}");
            let (points, tiles) = check_plane(&source, &frame, 0.0, &what);
            eprintln!("{what}: worst error {points:.2e} m at points, {tiles:.2e} m in tiles");
        }
    }
}

#[test]
fn a_rotated_geotransform_is_sampled_through_it_and_serves_its_plane() {
    let dir = tempfile::tempdir().unwrap();
    let frame = rotated(30.0);
    let path = write_plane(&dir.path().join("rotated.tif"), &frame, &Georef::Geotransform(frame), 0.0);
    let source = open(&path, "whole");
    let info = source.info();
    let georeferencing = &info.details["georeferencing"];
    assert!(
        georeferencing.starts_with("rotated geotransform (its rows run 30.000 degrees anticlockwise"),
        "{georeferencing}"
    );
    assert_eq!(info.details["pixel_size"], "10 x 10");
    assert!((info.resolution.unwrap() - PIXEL_M).abs() < 1e-9, "{:?}", info.resolution);
    assert!(info.warnings.is_empty(), "{:?}", info.warnings);
    let (points, tiles) = check_plane(&source, &frame, 0.0, "rotated");
    eprintln!("rotated: worst error {points:.2e} m at points, {tiles:.2e} m in tiles");
}

#[test]
fn a_gcp_raster_with_too_few_or_collinear_gcps_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let frame = rotated(30.0);
    for (cols, rows, words) in [
        (2, 1, "2 GCPs, too few"),
        (3, 1, "do not determine a first-order polynomial"),
        (6, 1, "(6 GCPs, all on one line"),
    ] {
        let path = dir.path().join(format!("gcps-{cols}x{rows}.tif"));
        write_plane(&path, &frame, &Georef::Gcps { frame, cols, rows }, 0.0);
        let message = GdalSource::open(&spec(&path, "auto"), &grid()).unwrap_err().to_string();
        assert!(message.contains(words), "{message}");
        assert!(message.ends_with(&format!(": {}", path.display())), "{message}");
    }
}

#[test]
fn an_edit_of_a_gcp_raster_reloads_through_a_new_warp() {
    let dir = tempfile::tempdir().unwrap();
    let frame = rotated(30.0);
    let path = dir.path().join("gcps.tif");
    let georef = Georef::Gcps { frame, cols: 4, rows: 3 };
    write_plane(&path, &frame, &georef, 0.0);
    for read in ["whole", "windowed"] {
        let source = open(&path, read);
        check_plane(&source, &frame, 0.0, read);
        std::thread::sleep(std::time::Duration::from_millis(20));
        // Pixels only, in place: 20 x 20 pixels at (40, 40) up by 25 m.
        {
            let ds = Dataset::open_ex(
                &path,
                DatasetOptions { open_flags: GdalOpenFlags::GDAL_OF_UPDATE, ..DatasetOptions::default() },
            )
            .unwrap();
            let mut band = ds.rasterband(1).unwrap();
            let old = band.read_as::<f32>((40, 40), (20, 20), (20, 20), None).unwrap();
            let new: Vec<f32> = old.data().iter().map(|v| v + 25.0).collect();
            band.write((40, 40), (20, 20), &mut Buffer::new((20, 20), new)).unwrap();
        }
        let Refresh::Changed { source: new, dirty } = source.refresh(&grid()).unwrap() else {
            panic!("{read}: the edit was not seen");
        };
        let centre = apply(&frame, 50.0, 50.0);
        let edited = heights_at_dyn(new.as_ref(), &[centre])[0].unwrap();
        assert!((edited - plane(centre.0, centre.1) - 25.0).abs() < TOLERANCE_M, "{read}: {edited} after the edit");
        let far = apply(&frame, 300.0, 200.0);
        let kept = heights_at_dyn(new.as_ref(), &[far])[0].unwrap();
        assert!((kept - plane(far.0, far.1)).abs() < TOLERANCE_M, "{read}: {kept} away from the edit");
        // The warp's blocks are signed by their values: the dirt is the
        // warped blocks the edit reaches, not the whole raster.
        let dirt = dirty.extents(&grid());
        let extent = source.info().extent.unwrap();
        let area: f64 = dirt.iter().map(|e| e.width() * e.height()).sum();
        assert!(dirt.iter().any(|e| e.contains(centre.0, centre.1)), "{read}: {dirt:?}");
        assert!(area < 0.5 * extent.width() * extent.height(), "{read}: {dirt:?} of {extent:?}");
        // Put the plane back.
        write_plane(&path, &frame, &georef, 0.0);
    }
    // New GCPs: the frame moves 100 m east; the reload is a fresh open.
    let source = open(&path, "whole");
    let mut moved = frame;
    moved[0] += 100.0;
    std::thread::sleep(std::time::Duration::from_millis(20));
    write_plane(&path, &moved, &Georef::Gcps { frame: moved, cols: 4, rows: 3 }, 0.0);
    let Refresh::Changed { source: new, .. } = source.refresh(&grid()).unwrap() else {
        panic!("the new GCPs were not seen");
    };
    let (before, after) = (source.info().extent.unwrap(), new.info().extent.unwrap());
    assert!((after.min_x - before.min_x - 100.0).abs() < 1e-6, "{before:?} -> {after:?}");
    let point = apply(&moved, 100.0, 100.0);
    let h = heights_at_dyn(new.as_ref(), &[point])[0].unwrap();
    assert!((h - plane(point.0, point.1)).abs() < TOLERANCE_M, "{h} after the move");
}

#[test]
fn a_gcp_colour_raster_is_transparent_outside_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let frame = rotated(30.0);
    let georef = Georef::Gcps { frame, cols: 2, rows: 2 };
    let rgb = dir.path().join("rgb.tif");
    let palette = dir.path().join("palette.tif");
    {
        let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
        for (path, bands) in [(&rgb, 3usize), (&palette, 1)] {
            let mut ds = driver.create_with_band_type::<u8, _>(path, SIZE.0, SIZE.1, bands).unwrap();
            set_georef(&mut ds, &georef);
            for b in 1..=bands {
                let mut band = ds.rasterband(b).unwrap();
                let value = [200u8, 100, 50][b - 1];
                if bands == 1 {
                    let (black, white) = (ColorEntry::rgba(0, 0, 0, 255), ColorEntry::rgba(255, 255, 255, 255));
                    let table = ColorTable::color_ramp(0, &black, 255, &white).unwrap();
                    band.set_color_table(&table);
                }
                band.write((0, 0), SIZE, &mut Buffer::new(SIZE, vec![value; SIZE.0 * SIZE.1])).unwrap();
            }
        }
    }
    let grid = grid();
    let quality = Quality::default();
    let ctx = GenerateContext { grid: &grid, quality: &quality, inputs: &NoInputs };
    let inverse = invert(&frame);
    for (path, colour) in [(&rgb, [200u8, 100, 50]), (&palette, [200, 200, 200])] {
        let source = open(path, "whole");
        assert!(source.info().details["georeferencing"].contains("4 GCPs"), "{:?}", source.info().details);
        let (mut inside, mut outside) = (0usize, 0usize);
        for key in grid.keys_overlapping(1, &source.info().extent.unwrap()) {
            let Payload::Color(tile) = source.generate(key, &ctx).unwrap() else { panic!("not colour") };
            let lattice = grid.lattice(key, SampleKind::TexelWithBorder);
            for j in 0..lattice.rows {
                for i in 0..lattice.cols {
                    let (p, l) = apply(&inverse, lattice.x(i), lattice.y(j));
                    let (w, h) = (SIZE.0 as f64, SIZE.1 as f64);
                    let rgba = &tile.rgba[(j * lattice.cols + i) * 4..][..4];
                    if p > 3.0 && l > 3.0 && p < w - 3.0 && l < h - 3.0 {
                        assert_eq!(
                            rgba,
                            [colour[0], colour[1], colour[2], 255],
                            "{}: inside at ({p}, {l})",
                            path.display()
                        );
                        inside += 1;
                    } else if p < -3.0 || l < -3.0 || p > w + 3.0 || l > h + 3.0 {
                        assert_eq!(rgba[3], 0, "{}: outside at ({p}, {l})", path.display());
                        outside += 1;
                    }
                }
            }
        }
        assert!(inside > 1000 && outside > 1000, "{}: {inside} inside, {outside} outside", path.display());
    }
}

#[test]
fn a_gcp_raster_in_degrees_serves_its_plane_on_the_geodetic_grid() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("degrees.tif");
    // 0.001-degree pixels turned 20 degrees, from (9 E, 45 N). 6 GCPs on
    // two lines: GDAL's default second order is undetermined (gdalwarp
    // refuses the file); relief fits the first order.
    let (s, c) = 20f64.to_radians().sin_cos();
    let frame = [9.0, 1e-3 * c, 1e-3 * s, 45.0, 1e-3 * s, -1e-3 * c];
    let surface = |lon: f64, lat: f64| 100.0 + 1000.0 * (lon - 9.0) + 500.0 * (lat - 45.0);
    {
        let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
        let ds = driver.create_with_band_type::<f32, _>(&path, SIZE.0, SIZE.1, 1).unwrap();
        let mut gcps = Vec::new();
        for (p, l) in [(0.0, 0.0), (200.0, 0.0), (400.0, 0.0), (0.0, 300.0), (200.0, 300.0), (400.0, 300.0)] {
            let (x, y) = apply(&frame, p, l);
            let id = format!("{}", gcps.len() + 1);
            gcps.push(gdal::Gcp { id, info: String::new(), pixel: p, line: l, x, y, z: 0.0 });
        }
        ds.set_gcps(gcps, &SpatialRef::from_epsg(4326).unwrap()).unwrap();
        let values: Vec<f32> = (0..SIZE.0 * SIZE.1)
            .map(|k| {
                let (x, y) = apply(&frame, (k % SIZE.0) as f64 + 0.5, (k / SIZE.0) as f64 + 0.5);
                surface(x, y) as f32
            })
            .collect();
        ds.rasterband(1).unwrap().write((0, 0), SIZE, &mut Buffer::new(SIZE, values)).unwrap();
    }
    let source = GdalSource::open(&spec(&path, "whole"), &TileGrid::geodetic(256).unwrap()).unwrap();
    let georeferencing = &source.info().details["georeferencing"];
    assert!(georeferencing.starts_with("6 GCPs, fitted by a first-order polynomial"), "{georeferencing}");
    assert!(georeferencing.contains("gdalwarp -order 1"), "{georeferencing}");
    assert!(georeferencing.contains("pixels of 0.00100000 degrees"), "{georeferencing}");
    let points = inner_points(&frame, 2.0);
    let geodetic: Vec<GeodeticPoint> =
        points.iter().map(|&(lon, lat)| GeodeticPoint { lon_deg: lon, lat_deg: lat }).collect();
    let heights = source.sample_heights(&geodetic, &Quality::default()).unwrap();
    let worst = points
        .iter()
        .zip(heights)
        .map(|(&(x, y), h)| (h.unwrap_or_else(|| panic!("no height at ({x}, {y})")) - surface(x, y)).abs())
        .fold(0.0, f64::max);
    assert!(worst < TOLERANCE_M, "heights differ from the plane by {worst} m");
    eprintln!("degrees: worst error {worst:.2e} m at points");
}
