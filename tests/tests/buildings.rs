//! Extruded buildings, instances and attribute styling against a real
//! reliefd, on the analytic Gaussian hill (`fixtures::hill`) so every
//! ground height has a known answer.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_source::geodesy;
use relief_tests::daemon::{Reliefd, relief};
use relief_tests::vectors::{shapefile, squares};
use relief_tests::{fixtures, tiles};

/// Every fixture sits in this level-10 tile (10.195..10.371 E, 45.176..45.352 N).
const TILE: (u32, u32, u32) = (10, 1082, 254);
const SIDE: f64 = 0.0005;
/// The ground is interpolated twice on the hill's curvature (up to ~1.9e5
/// m per square degree): the DEM's 0.00125-degree pixels to level-10
/// samples with the default bilinear kernel (h^2/8 f'' <= 0.045 m), then
/// bilinear between those samples 0.00069 degrees apart (<= 0.03 m).
const GROUND_TOLERANCE_M: f64 = 0.1;

fn hill_dem(dir: &Path) -> PathBuf {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap()
}

fn start(dir: &Path, sources: &str) -> Reliefd {
    let text = format!(
        "[scene]\nname = \"town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{}\"\n{sources}",
        hill_dem(dir).display()
    );
    Reliefd::start(&fixtures::write_manifest(dir, &text).unwrap(), &[]).unwrap()
}

/// The triangles of one feature, as ENU metres round `origin`.
fn feature_triangles(tile: &pb::GetTileResponse, id: u64, origin: [f64; 3]) -> Vec<[[f64; 3]; 3]> {
    let (positions, indices, mesh) = tiles::mesh(tile);
    let part = mesh.parts.iter().find(|p| p.feature_id == id).unwrap_or_else(|| panic!("no part for {id}: {mesh:?}"));
    let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
    indices[range]
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| geodesy::enu_from_geodetic(origin, positions[t[k] as usize])))
        .collect()
}

/// Volume under the mesh down to `base` (divergence theorem; the open floor
/// adds area times base), and the roof's footprint area.
fn volume_and_area(triangles: &[[[f64; 3]; 3]], base: f64) -> (f64, f64) {
    let (mut v, mut area) = (0.0, 0.0);
    for [a, b, c] in triangles {
        let nz = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / 2.0;
        v += nz * (a[2] + b[2] + c[2]) / 3.0;
        area += nz;
    }
    (v - area * base, area)
}

fn geodesic_area(outer: &[(f64, f64)], hole: Option<&[(f64, f64)]>) -> f64 {
    use geo::{GeodesicArea, Orient};
    let holes = hole.map(|h| vec![geo::LineString::from(h.to_vec())]).unwrap_or_default();
    geo::Polygon::new(geo::LineString::from(outer.to_vec()), holes)
        .orient(geo::orient::Direction::Default)
        .geodesic_area_unsigned()
}

fn square(w: f64, s: f64, d: f64) -> Vec<(f64, f64)> {
    vec![(w, s), (w + d, s), (w + d, s + d), (w, s + d), (w, s)]
}

/// Feature ids are record numbers in file order.
const BUILDINGS: &[(&str, f64, f64, f64)] = &[
    (r#"{"name": "A", "height": "20"}"#, 10.30, 45.26, SIDE),
    (r#"{"name": "B", "height": "abc"}"#, 10.28, 45.20, SIDE),
    (r#"{"name": "C", "height": ""}"#, 10.32, 45.22, SIDE),
];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn footprints_become_closed_buildings_standing_on_the_terrain() {
    let dir = tempfile::tempdir().unwrap();
    // A courtyard building besides the squares: 0.001 deg with a 0.0004 hole.
    let outer = square(10.25, 45.30, 0.001);
    let hole = square(10.2503, 45.3003, 0.0004);
    let ring = |r: &[(f64, f64)]| r.iter().map(|(x, y)| format!("[{x}, {y}]")).collect::<Vec<_>>().join(", ");
    let mut geojson = squares(BUILDINGS);
    geojson.truncate(geojson.len() - 2);
    let _ = write!(
        geojson,
        r#", {{"type": "Feature", "properties": {{"name": "D", "height": "15"}}, "geometry": {{"type": "Polygon", "coordinates": [[{}], [{}]]}}}}]}}"#,
        ring(&outer),
        ring(&hole)
    );
    let shp = shapefile(dir.path(), "footprints", &geojson).unwrap();
    let daemon = start(
        dir.path(),
        &format!(
            "\n[[source]]\nid = \"footprints\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"buildings\"\nkind = \"extrude\"\ninputs = [\"footprints\", \"dem\"]\nheight_attribute = \"height\"\nheight = 8\nmin_level = 8\n\n[layers]\nheight = \"dem\"\nbuildings = \"buildings\"\n",
            shp.display()
        ),
    );
    let channel = daemon.channel().await.unwrap();
    let tile = tiles::get(channel.clone(), "buildings", TILE).await.unwrap();
    let (positions, indices, mesh) = tiles::mesh(&tile);
    assert_eq!(pb::PayloadKind::try_from(tile.kind), Ok(pb::PayloadKind::Mesh));
    assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
    // B's height is not a number: left out, named, the others built.
    assert_eq!(mesh.skipped.len(), 1, "{:?}", mesh.skipped);
    assert_eq!(mesh.skipped[0].feature_id, 1);
    assert!(mesh.skipped[0].reason.contains("'height' is 'abc'"), "{}", mesh.skipped[0].reason);
    let ids: Vec<u64> = mesh.parts.iter().map(|p| p.feature_id).collect();
    assert_eq!(ids, [0, 2, 3]);

    // (feature, footprint, hole, height above the lowest corner): A from its
    // attribute, C from the default (its attribute is empty), D with a courtyard.
    type Case = (u64, Vec<(f64, f64)>, Option<Vec<(f64, f64)>>, f64);
    let cases: [Case; 3] = [
        (0, square(10.30, 45.26, SIDE), None, 20.0),
        (2, square(10.32, 45.22, SIDE), None, 8.0),
        (3, outer.clone(), Some(hole.clone()), 15.0),
    ];
    for (id, footprint, courtyard, height) in cases {
        let base = footprint.iter().map(|&(x, y)| fixtures::hill(x, y)).fold(f64::INFINITY, f64::min);
        let origin = [footprint[0].0, footprint[0].1, 0.0];
        let triangles = feature_triangles(&tile, id, origin);
        let (_, _, m) = tiles::mesh(&tile);
        let part = m.parts.iter().find(|p| p.feature_id == id).unwrap();
        let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
        let zs: Vec<f64> = indices[range].iter().map(|&i| positions[i as usize][2]).collect();
        let (lo, hi) = zs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &z| (lo.min(z), hi.max(z)));
        assert!((lo - base).abs() < GROUND_TOLERANCE_M, "feature {id}: base {lo} vs analytic {base}");
        assert!((hi - lo - height).abs() < 1e-9, "feature {id}: {} m tall, expected {height}", hi - lo);
        // Closed above the ground: the volume is the geodesic footprint
        // area times the height (ENU metres, so within 1%).
        let (volume, _) = volume_and_area(&triangles, lo - origin[2]);
        let truth = geodesic_area(&footprint, courtyard.as_deref()) * height;
        assert!((volume - truth).abs() / truth < 0.01, "feature {id}: volume {volume:.1} m3 vs {truth:.1} m3");
    }

    // One tile owns each building: the tiles round it have none of them.
    for (dx, dy) in [(-1i32, 0i32), (1, 0), (0, -1), (0, 1)] {
        let key = (TILE.0, TILE.1.wrapping_add_signed(dx), TILE.2.wrapping_add_signed(dy));
        let around = tiles::get(channel.clone(), "buildings", key).await.unwrap();
        let (_, _, m) = tiles::mesh(&around);
        assert!(m.parts.is_empty(), "{key:?} has {:?}", m.parts);
    }
    // Below min_level nothing is meshed, and the state says why.
    let coarse = tiles::get(channel.clone(), "buildings", (7, 135, 31)).await.unwrap();
    assert!(tiles::mesh(&coarse).0.is_empty());
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let details = &state.sources.iter().find(|s| s.id == "buildings").unwrap().details;
    assert_eq!((details["min_level"].as_str(), details["ground"].as_str()), ("8", "dem"));

    // The CLI writes the tile as OBJ, one object per building.
    let obj = dir.path().join("town.obj");
    let (code, _, stderr) =
        relief(&daemon, &["tile", "buildings", "10", "1082", "254", "-o", obj.to_str().unwrap()]).unwrap();
    assert_eq!(code, 0, "{stderr}");
    let text = std::fs::read_to_string(&obj).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), positions.len());
    assert_eq!(text.lines().filter(|l| l.starts_with("o feature_")).count(), 3);
    assert_eq!(text.lines().filter(|l| l.starts_with("f ")).count(), indices.len() / 3);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kml_extrude_and_altitude_modes_give_the_roof() {
    let dir = tempfile::tempdir().unwrap();
    let polygon = |name: &str, mode: &str, w: f64, s: f64, z: f64| {
        let ring: Vec<String> = square(w, s, SIDE).iter().map(|(x, y)| format!("{x},{y},{z}")).collect();
        format!(
            "<Placemark><name>{name}</name><Polygon><extrude>1</extrude><altitudeMode>{mode}</altitudeMode><outerBoundaryIs><LinearRing><coordinates>{}</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>",
            ring.join(" ")
        )
    };
    let kml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<kml xmlns=\"http://www.opengis.net/kml/2.2\"><Document>{}{}{}</Document></kml>",
        polygon("tower", "absolute", 10.22, 45.21, 2100.0),
        polygon("shed", "relativeToGround", 10.24, 45.33, 25.0),
        polygon("sunk", "absolute", 10.34, 45.30, 900.0),
    );
    let path = dir.path().join("town.kml");
    std::fs::write(&path, kml).unwrap();
    let daemon = start(
        dir.path(),
        &format!(
            "\n[[source]]\nid = \"town\"\nkind = \"kml\"\npath = \"{}\"\n\n[[source]]\nid = \"buildings\"\nkind = \"extrude\"\ninputs = [\"town\", \"dem\"]\n",
            path.display()
        ),
    );
    let tile = tiles::get(daemon.channel().await.unwrap(), "buildings", TILE).await.unwrap();
    let (positions, _, mesh) = tiles::mesh(&tile);
    let top = |id: u64| {
        let p = mesh.parts.iter().find(|p| p.feature_id == id).unwrap();
        let (_, indices, _) = tiles::mesh(&tile);
        indices[p.first_index as usize..(p.first_index + p.index_count) as usize]
            .iter()
            .map(|&i| positions[i as usize][2])
            .fold(f64::NEG_INFINITY, f64::max)
    };
    assert!((top(0) - 2100.0).abs() < 1e-9, "absolute: the roof at the stated altitude");
    let ground = square(10.24, 45.33, SIDE).iter().map(|&(x, y)| fixtures::hill(x, y)).fold(f64::INFINITY, f64::min);
    assert!((top(1) - (ground + 25.0)).abs() < GROUND_TOLERANCE_M, "relative: {} vs {}", top(1), ground + 25.0);
    // 900 m is under the hill there (~1650 m): skipped, and it says so.
    assert_eq!(mesh.skipped.len(), 1, "{:?}", mesh.skipped);
    assert!(mesh.skipped[0].reason.contains("not above the ground"), "{}", mesh.skipped[0].reason);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn points_become_instances_from_their_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let point = |props: &str, x: f64, y: f64| {
        format!(
            r#"{{"type": "Feature", "properties": {props}, "geometry": {{"type": "Point", "coordinates": [{x}, {y}]}}}}"#
        )
    };
    let geojson = format!(
        r#"{{"type": "FeatureCollection", "features": [{}, {}, {}, {}]}}"#,
        point(r#"{"species": "oak", "scale": "1.5", "heading": "90"}"#, 10.31, 45.27),
        point(r#"{"species": "", "scale": "big", "heading": "0"}"#, 10.26, 45.25),
        point(r#"{"species": "", "scale": "", "heading": "-30"}"#, 10.35, 45.19),
        point(r#"{"species": "palm", "scale": "", "heading": "0"}"#, 10.33, 45.21),
    );
    let shp = shapefile(dir.path(), "trees", &geojson).unwrap();
    // The user's own model: a glTF file named by its stem.
    std::fs::write(dir.path().join("oak.glb"), relief_models::stock_glb("broadleaf").unwrap()).unwrap();
    let daemon = start(
        dir.path(),
        &format!(
            "\n[[source]]\nid = \"trees\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"planted\"\nkind = \"instances\"\ninputs = [\"trees\", \"dem\"]\npaths = [\"oak.glb\"]\nrender_as = \"billboard\"\nmodel_attribute = \"species\"\nmodel = \"conifer\"\nscale_attribute = \"scale\"\nscale = 2\nrotation_attribute = \"heading\"\n",
            shp.display()
        ),
    );
    let tile = tiles::get(daemon.channel().await.unwrap(), "planted", TILE).await.unwrap();
    let list = tiles::instances(&tile);
    let got: Vec<(u64, &str, f64, f64)> =
        list.instances.iter().map(|i| (i.feature_id, i.model.as_str(), i.scale, i.rotation_deg)).collect();
    assert_eq!(got, [(0, "oak", 1.5, 90.0), (2, "conifer", 2.0, 330.0)]);
    for i in &list.instances {
        assert_eq!(pb::InstanceKind::try_from(i.kind), Ok(pb::InstanceKind::Billboard));
        assert!((i.z - fixtures::hill(i.x, i.y)).abs() < GROUND_TOLERANCE_M, "{i:?}");
    }
    assert_eq!(list.skipped.len(), 2, "{:?}", list.skipped);
    assert_eq!(list.skipped[0].feature_id, 1);
    assert!(list.skipped[0].reason.contains("'scale' is 'big'"), "{}", list.skipped[0].reason);
    assert_eq!(list.skipped[1].feature_id, 3);
    assert!(list.skipped[1].reason.contains("model 'palm' is not known"), "{}", list.skipped[1].reason);
    // And as GeoJSON through the CLI.
    let out = dir.path().join("trees.geojson");
    let (code, _, stderr) =
        relief(&daemon, &["tile", "planted", "10", "1082", "254", "-o", out.to_str().unwrap()]).unwrap();
    assert_eq!(code, 0, "{stderr}");
    let fc: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(fc["features"].as_array().unwrap().len(), 2);
    assert_eq!(fc["features"][0]["properties"]["model"], "oak");
    daemon.stop(&[]).unwrap();
}

/// The texel of tile `TILE` (border included) whose centre is nearest (lon, lat).
fn texel(lon: f64, lat: f64) -> (u32, u32) {
    let span = 180.0 / f64::from(1u32 << TILE.0);
    let (west, north) = (-180.0 + f64::from(TILE.1) * span, 90.0 - f64::from(TILE.2) * span);
    let step = span / 256.0;
    (((lon - west) / step).floor() as u32 + 1, ((north - lat) / step).floor() as u32 + 1)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn polygons_are_coloured_by_attribute_and_by_their_kml_style() {
    let dir = tempfile::tempdir().unwrap();
    let d = 0.01;
    let parcels = squares(&[
        (r#"{"landuse": "park"}"#, 10.20, 45.20, d),
        (r#"{"landuse": "park"}"#, 10.25, 45.20, d),
        (r#"{"landuse": "farm"}"#, 10.30, 45.20, d),
    ]);
    let shp = shapefile(dir.path(), "parcels", &parcels).unwrap();
    let ring: Vec<String> = square(10.22, 45.30, d).iter().map(|(x, y)| format!("{x},{y}")).collect();
    let kml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<kml xmlns=\"http://www.opengis.net/kml/2.2\"><Document><Style id=\"s\"><LineStyle><color>ff0000ff</color><width>3</width></LineStyle><PolyStyle><color>7f00ff00</color></PolyStyle></Style><Placemark><styleUrl>#s</styleUrl><Polygon><outerBoundaryIs><LinearRing><coordinates>{}</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark></Document></kml>",
        ring.join(" ")
    );
    let kml_path = dir.path().join("zone.kml");
    std::fs::write(&kml_path, kml).unwrap();
    let daemon = start(
        dir.path(),
        &format!(
            "\n[[source]]\nid = \"parcels\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"landuse\"\nkind = \"rasterize\"\ninputs = [\"parcels\"]\ncolor_by = \"landuse\"\nstroke = \"none\"\n\n[[source]]\nid = \"zone\"\nkind = \"kml\"\npath = \"{}\"\n\n[[source]]\nid = \"zoned\"\nkind = \"rasterize\"\ninputs = [\"zone\"]\n",
            shp.display(),
            kml_path.display()
        ),
    );
    let channel = daemon.channel().await.unwrap();
    let img = tiles::image(&tiles::get(channel.clone(), "landuse", TILE).await.unwrap());
    let at = |img: &image::RgbaImage, lon: f64, lat: f64| {
        let (i, j) = texel(lon, lat);
        img.get_pixel(i, j).0
    };
    let (park1, park2, farm) = (at(&img, 10.205, 45.205), at(&img, 10.255, 45.205), at(&img, 10.305, 45.205));
    assert_eq!(park1, park2, "one value, one colour");
    assert_ne!(park1[..3], farm[..3], "another value, another colour");
    assert_eq!((park1[3], farm[3]), (179, 179), "palette fills are 70% opaque");
    assert_eq!(at(&img, 10.215, 45.205)[3], 0, "nothing between parcels");

    // KML: PolyStyle aabbggrr 7f00ff00 is half-opaque green inside; the
    // LineStyle's opaque red (ff0000ff) draws the outline.
    let img = tiles::image(&tiles::get(channel, "zoned", TILE).await.unwrap());
    assert_eq!(at(&img, 10.225, 45.305), [0, 255, 0, 127]);
    let edge = at(&img, 10.225, 45.30);
    assert!(edge[0] > 200 && edge[1] < 100 && edge[3] > 200, "outline {edge:?}");
    daemon.stop(&[]).unwrap();
}
