//! A mesh tile (extruded buildings, MultiPatch surfaces) as 3D Tiles 1.1
//! glTF content.

use std::collections::HashMap;

use relief_source::geodesy::ecef_from_geodetic;
use relief_source::{MeshPart, MeshTile, TileGrid, TileKey};
use serde_json::json;

use super::document::{Document, Target};
use super::frame::{RegionBounds, box_centre, color_u16, translation, y_up};
use crate::{Glb, StandardTileError};

/// How many footprint corners of a part the ground is sampled at, as the
/// renderer does (evenly spread over the footprint's corners).
const LIFT_SAMPLES: usize = 16;

/// Triangles smaller than this (square metres) draw nothing and are left
/// out (a flat normal cannot be had from them).
const DEGENERATE_M2: f64 = 1e-9;

/// A mesh tile as GLB; `Ok(None)` when it has no triangle to write (the
/// daemon answers such a tile with no content).
///
/// Positions are the grid's longitude, latitude (degrees) and height
/// (metres above the ellipsoid). Each part is written with its colour
/// (`COLOR_0`) and a feature id (`_FEATURE_ID_0` of `EXT_mesh_features`:
/// the parts' distinct `feature_id`s numbered from 0 in the order they
/// first come), and a property table (`EXT_structural_metadata`, class
/// `feature`) gives each feature id the part's `feature_id`. Triangles
/// outside every part are not written.
///
/// `on_ground` parts are set on the terrain as the renderer sets them: the
/// part moves up or down by (lowest ground under its footprint) - (its
/// lowest vertex height), with `ground(lon_deg, lat_deg)` sampled at up to
/// 16 corners of its footprint (the vertices at its lowest height); where
/// every sample is NaN the part stays as written, as the renderer draws it
/// then.
///
/// Normals are flat (each triangle has its own three vertices), and the
/// material is double-sided, since MultiPatch rings come in either
/// winding.
pub fn buildings_glb(
    mesh: &MeshTile,
    grid: &TileGrid,
    key: TileKey,
    ground: &dyn Fn(f64, f64) -> f64,
) -> Result<Option<Glb>, StandardTileError> {
    if !grid.is_geodetic() {
        return Err(StandardTileError::NotGeodetic { crs: grid.crs().to_owned() });
    }
    if !grid.contains_key(key) {
        return Err(StandardTileError::KeyOutsideGrid { key });
    }
    check(mesh)?;
    let extent = grid.tile_extent(key);
    let mut region = RegionBounds::new(f64::midpoint(extent.min_x, extent.max_x));

    // Lifted geodetic corners, ECEF corners, colour and feature of every
    // triangle written.
    let mut triangles: Vec<([[f64; 3]; 3], [u16; 4], f32)> = Vec::new();
    let mut features: HashMap<u64, usize> = HashMap::new();
    for part in &mesh.parts {
        let next = features.len();
        let feature = *features.entry(part.feature_id).or_insert(next);
        let color = color_u16(part.color.map(|c| f32::from(c) / 255.0));
        let lift = lift_m(mesh, part, ground);
        let range = indices_of(part);
        for t in mesh.indices[range].chunks_exact(3) {
            let geodetic = [0, 1, 2].map(|k| {
                let [x, y, z] = mesh.positions[t[k] as usize];
                [x, y, z + lift]
            });
            let ecef = geodetic.map(|[lon, lat, h]| ecef_from_geodetic(lon, lat, h));
            if normal(&ecef).is_none() {
                continue;
            }
            for [lon, lat, h] in geodetic {
                region.add(lon, lat, h);
            }
            triangles.push((ecef, color, feature as f32));
        }
    }
    let Some(region) = region.region() else { return Ok(None) };
    if features.len() > 1 << 24 {
        return Err(StandardTileError::BadMesh {
            reason: format!("{} features, more than a float feature id holds exactly (2^24)", features.len()),
        });
    }

    let centre = box_centre(triangles.iter().flat_map(|t| t.0));
    let n = triangles.len() * 3;
    let (mut positions, mut normals, mut colors, mut ids) =
        (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    for (ecef, color, feature) in &triangles {
        let normal = normal(ecef).expect("degenerate triangles were left out").map(|v| v as f32);
        for p in ecef {
            positions.push(y_up([p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]]).map(|v| v as f32));
            normals.push(normal);
            colors.push(*color);
            ids.push([*feature]);
        }
    }
    let mut relief_ids = vec![0u64; features.len()];
    for (&id, &k) in &features {
        relief_ids[k] = id;
    }
    let mut doc = Document::default();
    doc.uses("EXT_mesh_features", false);
    let table = doc.feature_table(&relief_ids);
    let attributes = json!({
        "POSITION": doc.floats(&positions, Target::Vertices, true),
        "NORMAL": doc.floats(&normals, Target::Vertices, false),
        "COLOR_0": doc.unorm16x4(&colors),
        "_FEATURE_ID_0": doc.floats(&ids, Target::Vertices, false),
    });
    let mesh = doc.mesh(json!({
        "primitives": [{
            "attributes": attributes,
            "material": 0,
            "mode": 4,
            "extensions": {
                "EXT_mesh_features": { "featureIds": [{ "featureCount": features.len(), "attribute": 0, "propertyTable": table }] },
            },
        }],
    }));
    doc.node(json!({ "mesh": mesh, "name": format!("buildings {key}") }));
    Ok(Some(Glb { bytes: doc.glb()?, transform: translation(centre), region }))
}

/// The unit normal of an ECEF triangle (counter-clockwise seen from its
/// front), in glTF's y-up axes; None for a degenerate one.
fn normal(t: &[[f64; 3]; 3]) -> Option<[f64; 3]> {
    let d = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let (u, v) = (d(t[0], t[1]), d(t[0], t[2]));
    let c = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let length = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    (length.is_finite() && length / 2.0 > DEGENERATE_M2).then(|| y_up(c.map(|x| x / length)))
}

/// How far a part moves up to stand on the ground (0 for one that is not
/// `on_ground`, or where the ground is NaN at every sample).
fn lift_m(mesh: &MeshTile, part: &MeshPart, ground: &dyn Fn(f64, f64) -> f64) -> f64 {
    if !part.on_ground {
        return 0.0;
    }
    let range = indices_of(part);
    let mut used: Vec<u32> = mesh.indices[range].to_vec();
    used.sort_unstable();
    used.dedup();
    let base_m = used.iter().map(|&v| mesh.positions[v as usize][2]).fold(f64::INFINITY, f64::min);
    let mut footprint: Vec<(f64, f64)> = Vec::new();
    for &v in &used {
        let [x, y, z] = mesh.positions[v as usize];
        if z == base_m && !footprint.contains(&(x, y)) {
            footprint.push((x, y));
        }
    }
    let stride = footprint.len().div_ceil(LIFT_SAMPLES).max(1);
    let low = footprint
        .iter()
        .step_by(stride)
        .map(|&(x, y)| ground(x, y))
        .filter(|g| g.is_finite())
        .fold(f64::INFINITY, f64::min);
    if low.is_finite() { low - base_m } else { 0.0 }
}

/// The range of the mesh's indices that holds a part's triangles.
fn indices_of(part: &MeshPart) -> std::ops::Range<usize> {
    part.first_index as usize..part.first_index as usize + part.index_count as usize
}

/// The mesh's indices and parts in range, its positions finite.
fn check(mesh: &MeshTile) -> Result<(), StandardTileError> {
    let bad = |reason: String| Err(StandardTileError::BadMesh { reason });
    if let Some(v) = mesh.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return bad(format!("vertex {v} is not finite: {:?}", mesh.positions[v]));
    }
    if let Some(i) = mesh.indices.iter().find(|&&i| i as usize >= mesh.positions.len()) {
        return bad(format!("index {i} is past the {} vertices", mesh.positions.len()));
    }
    for part in &mesh.parts {
        let end = u64::from(part.first_index) + u64::from(part.index_count);
        if end > mesh.indices.len() as u64 || !part.index_count.is_multiple_of(3) {
            return bad(format!(
                "feature {}: indices {}..{end} are not whole triangles within the {} indices",
                part.feature_id,
                part.first_index,
                mesh.indices.len()
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use relief_source::geodesy::ecef_from_geodetic;
    use relief_source::{MeshPart, MeshTile, TileGrid, TileKey};

    use super::buildings_glb;
    use crate::StandardTileError;
    use crate::gltf::read::{distance, ecef_of, read, region_holds};

    /// A closed box, `size_deg` on a side, from `z0` to `z1` metres:
    /// 8 corners, 12 triangles.
    fn add_box(mesh: &mut MeshTile, at: (f64, f64), size_deg: f64, z: (f64, f64), part: (u64, [u8; 4], bool)) {
        let first = mesh.positions.len() as u32;
        for &h in &[z.0, z.1] {
            for &(dx, dy) in &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                mesh.positions.push([at.0 + dx * size_deg, at.1 + dy * size_deg, h]);
            }
        }
        let first_index = mesh.indices.len() as u32;
        let quads = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]];
        for [a, b, c, d] in quads {
            mesh.indices.extend([a, b, c, a, c, d].map(|k| first + k));
        }
        mesh.parts.push(MeshPart {
            feature_id: part.0,
            first_index,
            index_count: 36,
            color: part.1,
            on_ground: part.2,
        });
    }

    fn grid() -> TileGrid {
        TileGrid::geodetic(256).unwrap()
    }

    fn key_at(lon: f64, lat: f64) -> TileKey {
        grid().key_at(16, lon, lat).unwrap()
    }

    /// Every written vertex back in ECEF within 1 cm of where its input
    /// vertex (lifted by `lift` of its part) is, in triangle order.
    fn assert_positions(mesh: &MeshTile, glb: &crate::Glb, lift: &[f64]) {
        let r = read(&glb.bytes);
        let primitive = &r.json["meshes"][0]["primitives"][0];
        let positions: Vec<[f32; 3]> = r.values(&primitive["attributes"]["POSITION"]);
        let expected: Vec<[f64; 3]> = (mesh.parts.iter().zip(lift))
            .flat_map(|(part, lift)| {
                let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
                mesh.indices[range].iter().map(move |&i| {
                    let [x, y, z] = mesh.positions[i as usize];
                    [x, y, z + lift]
                })
            })
            .collect();
        assert_eq!(positions.len(), expected.len());
        for (stored, [lon, lat, h]) in positions.iter().zip(&expected) {
            let got = ecef_of(glb, *stored);
            assert!(got.iter().all(|v| v.is_finite()));
            let off = distance(got, ecef_from_geodetic(*lon, *lat, *h));
            assert!(off < 0.01, "vertex at {lon}, {lat}, {h} is {off} m off");
            assert!(region_holds(&glb.region, *lon, *lat, *h, 1e-6), "{:?} misses {lon} {lat} {h}", glb.region);
        }
    }

    #[test]
    fn boxes_round_trip_in_ecef_with_colours_features_and_lifts() {
        let (lon, lat) = (11.3, 46.5);
        let mut mesh = MeshTile::default();
        add_box(&mut mesh, (lon, lat), 0.0002, (0.0, 12.0), (7, [200, 60, 30, 255], true));
        add_box(&mut mesh, (lon + 0.0004, lat), 0.0001, (300.0, 320.0), (9, [10, 128, 250, 255], false));
        // Ground rising to the east: the first box's lowest ground is at
        // its west corners.
        let ground = |x: f64, _y: f64| 250.0 + 1000.0 * (x - lon);
        let glb = buildings_glb(&mesh, &grid(), key_at(lon, lat), &ground).unwrap().unwrap();
        assert_positions(&mesh, &glb, &[250.0, 0.0]);

        // The gltf crate reads it, validated whole, and its primitive
        // reader finds every vertex.
        let gltf = ::gltf::Gltf::from_slice(&glb.bytes).unwrap();
        let blob = gltf.blob.as_deref().unwrap();
        let primitive = gltf.document.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(primitive.mode(), ::gltf::mesh::Mode::Triangles);
        let reader = primitive.reader(|_| Some(blob));
        assert_eq!(reader.read_positions().unwrap().count(), 72);
        assert!(primitive.material().double_sided());

        let r = read(&glb.bytes);
        let primitive = &r.json["meshes"][0]["primitives"][0];
        let attributes = &primitive["attributes"];
        assert_eq!(r.json["extensionsUsed"], serde_json::json!(["EXT_mesh_features", "EXT_structural_metadata"]));
        assert!(r.json.get("extensionsRequired").is_none());
        let feature_ids = &primitive["extensions"]["EXT_mesh_features"]["featureIds"][0];
        assert_eq!((&feature_ids["featureCount"], &feature_ids["propertyTable"]), (&2.into(), &0.into()));
        assert_eq!(r.feature_table(), [7, 9]);
        let ids: Vec<f32> = r.values(&attributes["_FEATURE_ID_0"]);
        assert_eq!(ids, [vec![0.0; 36], vec![1.0; 36]].concat());
        // Colours: linear in COLOR_0, back to the sRGB bytes given.
        let colors: Vec<[u16; 4]> = r.values(&attributes["COLOR_0"]);
        let srgb = |c: u16| {
            let l = f64::from(c) / 65535.0;
            255.0 * if l <= 0.003_130_8 { 12.92 * l } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
        };
        for (k, c) in colors.iter().enumerate() {
            let want = if k < 36 { [200, 60, 30, 255] } else { [10, 128, 250, 255] };
            for i in 0..3 {
                assert!((srgb(c[i]) - f64::from(want[i])).abs() < 0.05, "{c:?} is not {want:?}");
            }
            assert_eq!(c[3], 65535);
        }
        // Flat normals: unit, across each triangle's edges, facing out of
        // the boxes (they wind counter-clockwise seen from outside).
        let positions: Vec<[f32; 3]> = r.values(&attributes["POSITION"]);
        let normals: Vec<[f32; 3]> = r.values(&attributes["NORMAL"]);
        for (t, n) in positions.chunks_exact(3).zip(normals.chunks_exact(3)) {
            assert!(n[0] == n[1] && n[1] == n[2]);
            let n = n[0].map(f64::from);
            assert!((n.iter().map(|v| v * v).sum::<f64>() - 1.0).abs() < 1e-6);
            for (a, b) in [(0, 1), (1, 2)] {
                let e = [0, 1, 2].map(|k| f64::from(t[b][k] - t[a][k]));
                let len = e.iter().map(|v| v * v).sum::<f64>().sqrt();
                assert!((e[0] * n[0] + e[1] * n[1] + e[2] * n[2]).abs() / len < 1e-3);
            }
        }
        // The roof of the first box (its second face) faces up.
        let centre = ecef_from_geodetic(lon, lat, 0.0);
        let up = centre.map(|v| v / distance(centre, [0.0; 3]));
        let roof = normals[6].map(f64::from);
        let roof_ecef = [roof[0], -roof[2], roof[1]];
        assert!(roof_ecef.iter().zip(up).map(|(a, b)| a * b).sum::<f64>() > 0.99);
        // Heights of the region: the lifted box's base to the top of the
        // other.
        assert!((glb.region[4] - 250.0).abs() < 1e-9 && (glb.region[5] - 320.0).abs() < 1e-9);
        // The transform is a translation to near the content.
        assert_eq!(glb.transform[..12], [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        assert!(distance([glb.transform[12], glb.transform[13], glb.transform[14]], centre) < 1000.0);
    }

    #[test]
    fn a_part_on_ground_sits_its_lowest_vertex_on_the_lowest_ground() {
        // Heights relative but not from 0 (a MultiPatch with z = relative):
        // the base at 5 m goes to the ground, not 5 m above it.
        let (lon, lat) = (-122.4, 37.7);
        let mut mesh = MeshTile::default();
        add_box(&mut mesh, (lon, lat), 0.0001, (5.0, 9.0), (1, [255; 4], true));
        let glb = buildings_glb(&mesh, &grid(), key_at(lon, lat), &|_, _| 40.0).unwrap().unwrap();
        assert_positions(&mesh, &glb, &[35.0]);
        assert!((glb.region[4] - 40.0).abs() < 1e-9);
        // No ground there (NaN everywhere): drawn as written.
        let glb = buildings_glb(&mesh, &grid(), key_at(lon, lat), &|_, _| f64::NAN).unwrap().unwrap();
        assert_positions(&mesh, &glb, &[0.0]);
    }

    #[test]
    fn near_the_antimeridian_and_the_pole_positions_stay_finite_and_exact() {
        // A box reaching past 180 degrees east.
        let mut mesh = MeshTile::default();
        add_box(&mut mesh, (179.9998, -16.5), 0.0004, (0.0, 8.0), (1, [90, 90, 90, 255], false));
        let glb = buildings_glb(&mesh, &grid(), key_at(179.9999, -16.5), &|_, _| 0.0).unwrap().unwrap();
        assert_positions(&mesh, &glb, &[0.0]);
        // The region crosses: west is east of east.
        assert!(glb.region[0] > glb.region[2], "{:?}", glb.region);
        assert!(glb.region.iter().all(|v| v.is_finite()));
        assert!(glb.region[2] > -std::f64::consts::PI && glb.region[0] < std::f64::consts::PI);

        // A box reaching the north pole: its corners there are one point,
        // and the triangles that collapse (the north wall's two, one each
        // of the floor and the roof) are left out.
        let mut touching = MeshTile::default();
        add_box(&mut touching, (45.0, 89.9998), 0.0002, (0.0, 8.0), (1, [90, 90, 90, 255], true));
        let glb = buildings_glb(&touching, &grid(), key_at(45.0, 89.9999), &|_, _| 0.0).unwrap().unwrap();
        let r = read(&glb.bytes);
        assert_eq!(r.json["accessors"][0]["count"], 3 * (12 - 4));
        // A box a few metres from the north pole.
        let mut mesh = MeshTile::default();
        add_box(&mut mesh, (45.0, 89.9997), 0.0002, (0.0, 8.0), (1, [90, 90, 90, 255], true));
        let glb = buildings_glb(&mesh, &grid(), key_at(45.0, 89.9999), &|_, _| 2800.0).unwrap().unwrap();
        assert_positions(&mesh, &glb, &[2800.0]);
        assert!(glb.region.iter().chain(&glb.transform).all(|v| v.is_finite()));
        assert!(glb.region[3] <= std::f64::consts::FRAC_PI_2);
    }

    #[test]
    fn empty_degenerate_and_broken_meshes() {
        let (lon, lat) = (2.35, 48.85);
        let key = key_at(lon, lat);
        assert_eq!(buildings_glb(&MeshTile::default(), &grid(), key, &|_, _| 0.0).unwrap(), None);
        // A part whose triangles have no area writes nothing.
        let flat = MeshTile {
            positions: vec![[lon, lat, 0.0], [lon + 0.0001, lat, 0.0], [lon + 0.0001, lat, 0.0]],
            indices: vec![0, 1, 2],
            parts: vec![MeshPart { feature_id: 1, first_index: 0, index_count: 3, color: [0; 4], on_ground: false }],
            skipped: Vec::new(),
        };
        assert_eq!(buildings_glb(&flat, &grid(), key, &|_, _| 0.0).unwrap(), None);
        let mut broken = flat.clone();
        broken.indices[2] = 3;
        let err = buildings_glb(&broken, &grid(), key, &|_, _| 0.0).unwrap_err();
        assert!(matches!(err, StandardTileError::BadMesh { .. }), "{err}");
        let mut broken = flat.clone();
        broken.parts[0].index_count = 6;
        assert!(matches!(buildings_glb(&broken, &grid(), key, &|_, _| 0.0), Err(StandardTileError::BadMesh { .. })));
        let mut broken = flat;
        broken.positions[0][2] = f64::NAN;
        assert!(matches!(buildings_glb(&broken, &grid(), key, &|_, _| 0.0), Err(StandardTileError::BadMesh { .. })));

        let projected = TileGrid::new(
            relief_source::GridKind::Projected(relief_source::ProjectedGrid {
                crs: "EPSG:32633".into(),
                min_x: 0.0,
                min_y: 0.0,
                size: 1.0e6,
            }),
            256,
        )
        .unwrap();
        let err = buildings_glb(&MeshTile::default(), &projected, TileKey::new(0, 0, 0), &|_, _| 0.0);
        assert!(matches!(err, Err(StandardTileError::NotGeodetic { .. })));
        let err = buildings_glb(&MeshTile::default(), &grid(), TileKey::new(1, 9, 0), &|_, _| 0.0);
        assert!(matches!(err, Err(StandardTileError::KeyOutsideGrid { .. })));
    }
}
