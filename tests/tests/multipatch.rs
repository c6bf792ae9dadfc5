//! MultiPatch buildings against a real reliefd, on the analytic hill: a
//! MultiPatch shapefile written by GDAL (`SHPT=MULTIPATCH`) and the same
//! patches in a file geodatabase (OpenFileGDB) are drawn as the `buildings`
//! layer, with the triangles OGR gives and pixels changed against the scene
//! without them; every patch type (strips, fans, outer and inner rings,
//! first ring and rings) written with the `shapefile` crate, holes, both
//! `z` policies, and degenerate patches skipped and counted.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use gdal::vector::{Geometry, LayerAccess};
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_source::geodesy;
use relief_tests::arcgis::{self, GdbEditor, LayerSpec};
use relief_tests::daemon::Reliefd;
use relief_tests::{fixtures, scenes, tiles};
use serde_json::json;
use shapefile::{Multipatch, Patch, PointZ};

/// The level-10 tile that holds every fixture.
const TILE: (u32, u32, u32) = (10, 1082, 254);
const LON: f64 = 10.25;
const LAT: f64 = 45.25;

/// Degrees per metre east and north at the fixtures.
fn per_m() -> (f64, f64) {
    let m = geodesy::MEAN_RADIUS_M.to_radians();
    (1.0 / (m * LAT.to_radians().cos()), 1.0 / m)
}

/// A point `e` metres east and `n` north of (LON, LAT), `z` metres up.
fn at(e: f64, n: f64, z: f64) -> [f64; 3] {
    let (dx, dy) = per_m();
    [LON + e * dx, LAT + n * dy, z]
}

fn ring_wkt(points: &[[f64; 3]]) -> String {
    let mut all = points.to_vec();
    all.push(points[0]);
    format!("({})", all.iter().map(|p| format!("{} {} {}", p[0], p[1], p[2])).collect::<Vec<_>>().join(","))
}

/// A 40 x 20 m block, 12 m high, with a 10 x 6 m courtyard, standing on
/// the hill at `ground`: four walls as triangles (a TIN) and the roof as a
/// polygon with its hole, the way ArcGIS stores a building.
fn block_wkt(ground: f64) -> String {
    let top = ground + 12.0;
    let corners = [(-20.0, -10.0), (20.0, -10.0), (20.0, 10.0), (-20.0, 10.0)];
    let mut walls = Vec::new();
    for k in 0..4 {
        let ((e0, n0), (e1, n1)) = (corners[k], corners[(k + 1) % 4]);
        let (a, b, c, d) = (at(e0, n0, ground), at(e1, n1, ground), at(e1, n1, top), at(e0, n0, top));
        walls.push(format!("({})", ring_wkt(&[a, b, c])));
        walls.push(format!("({})", ring_wkt(&[a, c, d])));
    }
    let roof: Vec<[f64; 3]> = corners.iter().map(|&(e, n)| at(e, n, top)).collect();
    let hole: Vec<[f64; 3]> =
        [(-5.0, -3.0), (-5.0, 3.0), (5.0, 3.0), (5.0, -3.0)].iter().map(|&(e, n)| at(e, n, top)).collect();
    format!(
        "GEOMETRYCOLLECTION Z (TIN Z ({}),MULTIPOLYGON Z (({},{})))",
        walls.join(","),
        ring_wkt(&roof),
        ring_wkt(&hole)
    )
}

/// OGR's reading of a layer's first feature: its polygons (rings of
/// points), whatever collection holds them.
fn ogr_polygons(path: &Path, layer: Option<&str>) -> Vec<Vec<Vec<[f64; 3]>>> {
    fn walk(g: &Geometry, out: &mut Vec<Vec<Vec<[f64; 3]>>>) {
        use gdal::vector::OGRwkbGeometryType as W;
        match gdal::vector::geometry_type_flatten(g.geometry_type()) {
            W::wkbPolygon | W::wkbTriangle => out.push(
                (0..g.geometry_count())
                    .map(|i| {
                        let mut points = Vec::new();
                        g.get_geometry(i).get_points(&mut points);
                        points.into_iter().map(|(x, y, z)| [x, y, z]).collect()
                    })
                    .collect(),
            ),
            _ => (0..g.geometry_count()).for_each(|i| walk(&g.get_geometry(i), out)),
        }
    }
    let ds = gdal::Dataset::open(path).unwrap();
    let mut layer = match layer {
        Some(name) => ds.layer_by_name(name).unwrap(),
        None => ds.layer(0).unwrap(),
    };
    let feature = layer.features().next().unwrap();
    let mut out = Vec::new();
    walk(feature.geometry().unwrap(), &mut out);
    out
}

/// A triangle's corners as metres (ENU about the fixtures), rounded to a
/// millimetre and sorted: the same triangle whatever its winding or start.
fn key(t: [[f64; 3]; 3]) -> [[i64; 3]; 3] {
    let mut k = t.map(|p| geodesy::enu_from_geodetic([LON, LAT, 0.0], p).map(|v| (v * 1000.0).round() as i64));
    k.sort_unstable();
    k
}

fn area(t: [[f64; 3]; 3]) -> f64 {
    let [a, b, c] = t.map(|p| geodesy::enu_from_geodetic([LON, LAT, 0.0], p));
    let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() / 2.0
}

/// The triangles reliefd serves for feature `id` of `source`.
async fn served(channel: &tonic::transport::Channel, source: &str, id: u64) -> (Vec<[[f64; 3]; 3]>, pb::MeshPart) {
    let tile = tiles::get(channel.clone(), source, TILE).await.unwrap();
    let (positions, indices, mesh) = tiles::mesh(&tile);
    let part = *mesh.parts.iter().find(|p| p.feature_id == id).unwrap_or_else(|| panic!("no feature {id}: {mesh:?}"));
    let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
    (indices[range].chunks_exact(3).map(|t| [0, 1, 2].map(|k| positions[t[k] as usize])).collect(), part)
}

/// OGR's triangles must all be served; every other OGR polygon's area
/// (holes taken out) must be covered by the rest. Returns the served area.
fn check_against_ogr(ogr: &[Vec<Vec<[f64; 3]>>], served: &[[[f64; 3]; 3]]) -> f64 {
    let served_keys: Vec<_> = served.iter().map(|t| key(*t)).collect();
    let mut expected_area = 0.0;
    for polygon in ogr {
        let ring = |r: &Vec<[f64; 3]>| -> f64 {
            // The area of a planar ring: fan triangles' vector areas, summed.
            let metres: Vec<[f64; 3]> = r.iter().map(|p| geodesy::enu_from_geodetic([LON, LAT, 0.0], *p)).collect();
            let mut n = [0.0; 3];
            for k in 1..metres.len().saturating_sub(1) {
                let (a, b, c) = (metres[0], metres[k], metres[k + 1]);
                let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
                n = [
                    n[0] + u[1] * v[2] - u[2] * v[1],
                    n[1] + u[2] * v[0] - u[0] * v[2],
                    n[2] + u[0] * v[1] - u[1] * v[0],
                ];
            }
            (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() / 2.0
        };
        if polygon.len() == 1 && polygon[0].len() == 4 {
            let t = [polygon[0][0], polygon[0][1], polygon[0][2]];
            assert!(served_keys.contains(&key(t)), "OGR's triangle {t:?} is not served");
        }
        expected_area += ring(&polygon[0]) - polygon[1..].iter().map(ring).sum::<f64>();
    }
    let got: f64 = served.iter().map(|t| area(*t)).sum();
    assert!((got - expected_area).abs() < 1e-3 * expected_area, "served {got} m2, OGR's polygons {expected_area} m2");
    got
}

fn manifest(dir: &Path, sources: &str, buildings: Option<&str>) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let layer = buildings.map(|b| format!("buildings = \"{b}\"\n")).unwrap_or_default();
    fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"patches\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n{sources}\n\
             [layers]\nheight = \"dem\"\n{layer}\n[effects]\nlighting = {{}}\n"
        ),
    )
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gdal_multipatch_shapefile_and_the_same_patches_in_a_geodatabase_are_drawn_as_buildings() {
    if !arcgis::available("a_gdal_multipatch_shapefile_and_a_geodatabase") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let ground = fixtures::hill(LON, LAT);
    let wkt = block_wkt(ground);
    let shp = dir.path().join("block.shp");
    arcgis::write_multipatch_shapefile(&shp, &[(wkt.clone(), "school")]).unwrap();
    let gdb = dir.path().join("city.gdb");
    GdbEditor::start(&gdb)
        .unwrap()
        .create(&[LayerSpec {
            name: "blocks",
            geom: "multipatch",
            fields: &["use"],
            features: vec![(wkt, json!({"use": "school"}))],
        }])
        .unwrap();
    let sources = "[[source]]\nid = \"shp\"\nkind = \"shapefile\"\npath = \"block.shp\"\ncolor_by = \"use\"\n\n\
                   [[source]]\nid = \"gdb\"\nkind = \"ogr\"\npath = \"city.gdb\"\nlayer = \"blocks\"\n";
    let with = Reliefd::start(&manifest(dir.path(), sources, Some("shp")), &[]).unwrap();
    let channel = with.channel().await.unwrap();
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    for id in ["shp", "gdb"] {
        let s = state.sources.iter().find(|s| s.id == id).unwrap();
        assert!(s.error.is_empty(), "{s:#?}");
        assert_eq!(s.output, pb::PayloadKind::Mesh as i32, "{s:#?}");
        assert_eq!(s.details["z"], "absolute");
        assert_eq!(s.details["skipped_patches"], "0", "{s:#?}");
    }
    // Each source's triangles are OGR's: its triangles, and its roof cut
    // round the courtyard. Walls 2 x (40 + 20) x 12 m, roof 800 - 60 m2.
    let (shp_triangles, part) = served(&channel, "shp", 0).await;
    let shp_area = check_against_ogr(&ogr_polygons(&shp, None), &shp_triangles);
    // (The fixture's metres are on a sphere, ENU's on the ellipsoid: 0.3%.)
    assert!((shp_area / (2.0 * 60.0 * 12.0 + 800.0 - 60.0) - 1.0).abs() < 0.005, "{shp_area}");
    assert!(!part.on_ground, "absolute heights are drawn as written");
    assert_ne!(part.rgba, 0xd9d1_c2ff, "coloured by its 'use'");
    let (gdb_triangles, _) = served(&channel, "gdb", 1).await;
    let gdb_area = check_against_ogr(&ogr_polygons(&gdb, Some("blocks")), &gdb_triangles);
    // A geodatabase keeps coordinates on its XY resolution grid (1e-9 degrees here).
    assert!((gdb_area - shp_area).abs() < 0.05, "{gdb_area} vs {shp_area}");
    // Heights as written: the walls stand on the hill, the roof 12 m up.
    let zs: Vec<f64> = shp_triangles.iter().flatten().map(|p| p[2]).collect();
    let (low, high) = zs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), z| (l.min(*z), h.max(*z)));
    assert!((low - ground).abs() < 1e-6 && (high - ground - 12.0).abs() < 1e-6, "{low} {high}");

    // Drawn: the frame differs from the same scene without the building.
    let camera = scenes::camera(LON, LAT - 0.0012, ground + 45.0, 0.0, -12.0);
    let drawn = scenes::render_rgba(&channel, camera, (320, 180)).await.unwrap();
    assert!(drawn.drawn.as_ref().is_some_and(|d| d.buildings > 0), "{:?}", drawn.drawn);
    with.stop(&[]).unwrap();
    let without = Reliefd::start(&manifest(dir.path(), sources, None), &[]).unwrap();
    let bare = scenes::render_rgba(&without.channel().await.unwrap(), camera, (320, 180)).await.unwrap();
    without.stop(&[]).unwrap();
    let changed = drawn.image.chunks_exact(4).zip(bare.image.chunks_exact(4)).filter(|(a, b)| a != b).count();
    // The block is about 60 x 24 pixels from here.
    assert!(changed > 1000, "only {changed} pixels changed");
}

fn p(e: f64, n: f64, z: f64) -> PointZ {
    let [x, y, z] = at(e, n, z);
    PointZ::new(x, y, z, shapefile::NO_DATA)
}

/// Every patch type, written with the `shapefile` crate (GDAL writes only
/// rings): feature 0 a strip, 1 a fan, 2 an outer ring with an inner one,
/// 3 a first ring with a ring, 4 only degenerate patches.
fn every_patch_type(shp: &Path) {
    let strip =
        Patch::TriangleStrip(vec![p(0., 0., 0.), p(0., 0., 5.), p(10., 0., 0.), p(10., 0., 5.), p(20., 0., 0.)]);
    let fan =
        Patch::TriangleFan(vec![p(50., 50., 8.), p(45., 45., 3.), p(55., 45., 3.), p(55., 55., 3.), p(45., 55., 3.)]);
    let outer =
        Patch::OuterRing(vec![p(100., 0., 6.), p(100., 30., 6.), p(130., 30., 6.), p(130., 0., 6.), p(100., 0., 6.)]);
    let inner = Patch::InnerRing(vec![
        p(110., 10., 6.),
        p(120., 10., 6.),
        p(120., 20., 6.),
        p(110., 20., 6.),
        p(110., 10., 6.),
    ]);
    let first =
        Patch::FirstRing(vec![p(-60., 0., 4.), p(-60., 20., 4.), p(-40., 20., 4.), p(-40., 0., 4.), p(-60., 0., 4.)]);
    let ring = Patch::Ring(vec![p(-55., 5., 4.), p(-45., 5., 4.), p(-45., 15., 4.), p(-55., 15., 4.), p(-55., 5., 4.)]);
    let two_points = Patch::OuterRing(vec![p(0., -50., 1.), p(5., -50., 1.), p(5., -50., 1.), p(0., -50., 1.)]);
    let collinear = Patch::TriangleFan(vec![p(0., -60., 1.), p(5., -60., 1.), p(10., -60., 1.)]);
    let shapes = [
        Multipatch::with_parts(vec![strip]),
        Multipatch::with_parts(vec![fan]),
        Multipatch::with_parts(vec![outer, inner]),
        Multipatch::with_parts(vec![first, ring]),
        Multipatch::with_parts(vec![two_points, collinear]),
    ];
    let table = shapefile::dbase::TableWriterBuilder::new().add_character_field("name".try_into().unwrap(), 10);
    let mut writer = shapefile::Writer::from_path(shp, table).unwrap();
    for (k, shape) in shapes.iter().enumerate() {
        let mut record = shapefile::dbase::Record::default();
        record.insert("name".into(), shapefile::dbase::FieldValue::Character(Some(format!("f{k}"))));
        writer.write_shape_and_record(shape, &record).unwrap();
    }
    std::fs::write(
        shp.with_extension("prj"),
        gdal::spatial_ref::SpatialRef::from_epsg(4326).unwrap().to_wkt().unwrap(),
    )
    .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_patch_type_and_its_holes_become_ogrs_triangles_and_degenerate_patches_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let shp = dir.path().join("kinds.shp");
    every_patch_type(&shp);
    let sources = "[[source]]\nid = \"kinds\"\nkind = \"shapefile\"\npath = \"kinds.shp\"\nz = \"relative\"\n\n\
                   [[source]]\nid = \"ogr-kinds\"\nkind = \"ogr\"\npath = \"kinds.shp\"\n";
    let daemon = Reliefd::start(&manifest(dir.path(), sources, Some("kinds")), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let kinds = state.sources.iter().find(|s| s.id == "kinds").unwrap();
    assert_eq!(kinds.details["z"], "relative");
    // Polygons, as OGR counts them: 3 + 3 triangles, 2 rings with holes, 2 degenerate.
    assert_eq!(kinds.details["patches"], "10", "{kinds:#?}");
    assert_eq!(kinds.details["skipped_patches"], "2", "{kinds:#?}");
    assert_eq!(kinds.details["skipped_patches.a patch with fewer than three distinct points"], "1", "{kinds:#?}");
    assert_eq!(kinds.details["skipped_patches.a patch without area (its points are collinear)"], "1", "{kinds:#?}");
    assert!(kinds.warnings.iter().any(|w| w.contains("2 of 10 MultiPatch patches were degenerate")), "{kinds:#?}");

    let ds = gdal::Dataset::open(&shp).unwrap();
    let mut layer = ds.layer(0).unwrap();
    let ogr: Vec<Vec<Vec<Vec<[f64; 3]>>>> = layer
        .features()
        .map(|f| {
            let g = f.geometry().unwrap();
            (0..g.geometry_count())
                .map(|i| {
                    let polygon = g.get_geometry(i);
                    (0..polygon.geometry_count())
                        .map(|r| {
                            let mut points = Vec::new();
                            polygon.get_geometry(r).get_points(&mut points);
                            points.into_iter().map(|(x, y, z)| [x, y, z]).collect()
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    // A strip of five points and a fan of five: three triangles each, OGR's.
    for (id, source) in [(0, "kinds"), (1, "kinds"), (0, "ogr-kinds"), (1, "ogr-kinds")] {
        let (triangles, part) = served(&channel, source, id).await;
        assert_eq!(triangles.len(), 3, "{source} feature {id}");
        check_against_ogr(&ogr[id as usize], &triangles);
        assert_eq!(part.on_ground, source == "kinds", "relative heights are set on the ground");
    }
    // Rings with holes, typed and untyped: 30 x 30 less 10 x 10, and 20 x 20 less 10 x 10.
    let (outer, _) = served(&channel, "kinds", 2).await;
    assert!((check_against_ogr(&ogr[2], &outer) / 800.0 - 1.0).abs() < 0.005);
    let (first, _) = served(&channel, "kinds", 3).await;
    assert!((check_against_ogr(&ogr[3], &first) / 300.0 - 1.0).abs() < 0.005);
    // The feature of degenerate patches is no part, and the tile says why.
    let tile = tiles::get(channel.clone(), "kinds", TILE).await.unwrap();
    let (_, _, mesh) = tiles::mesh(&tile);
    assert!(mesh.parts.iter().all(|p| p.feature_id != 4));
    let reasons: Vec<&str> = mesh.skipped.iter().filter(|s| s.feature_id == 4).map(|s| s.reason.as_str()).collect();
    assert_eq!(reasons.len(), 2, "{:?}", mesh.skipped);

    // Drawn where the buildings pass draws.
    let camera = scenes::camera(LON + 0.0004, LAT - 0.0015, fixtures::hill(LON, LAT) + 80.0, 0.0, -20.0);
    let frame = scenes::render_rgba(&channel, camera, (320, 180)).await.unwrap();
    assert!(frame.drawn.as_ref().is_some_and(|d| d.buildings > 0), "{:?}", frame.drawn);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_multipatch_options_are_refused_on_a_layer_of_footprints() {
    let dir = tempfile::tempdir().unwrap();
    relief_tests::vectors::shapefile(
        dir.path(),
        "plain",
        &relief_tests::vectors::squares(&[(r#"{"name": "a"}"#, LON, LAT, 0.001)]),
    )
    .unwrap();
    let sources = "[[source]]\nid = \"plain\"\nkind = \"shapefile\"\npath = \"plain.shp\"\nz = \"relative\"\n";
    let (code, text) = relief_tests::daemon::check(&manifest(dir.path(), sources, None)).unwrap();
    assert_ne!(code, 0, "{text}");
    assert!(text.contains("source 'plain', field 'z'") && text.contains("MultiPatch"), "{text}");
}
