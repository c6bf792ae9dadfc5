//! An instance tile (trees, houses placed from points or scattered over
//! land cover) as 3D Tiles 1.1 glTF content: one mesh and one node per
//! model, each placed once per instance with `EXT_mesh_gpu_instancing`.

use std::collections::{BTreeMap, HashMap};

use relief_source::geodesy::{ecef_from_geodetic, enu_axes, geodetic_from_ecef};
use relief_source::{Instance, InstanceTile, TileGrid, TileKey};
use serde_json::json;

use super::document::{Document, Target};
use super::frame::{RegionBounds, box_centre, color_u16, translation, y_up};
use crate::{Glb, StandardTileError};

/// How far the region is grown round the corners of each instance's box:
/// it holds the box's faces too, whose middles sag below the corners by
/// the planet's curvature (under 0.1 mm for a 30 m model).
const REGION_PAD_M: f64 = 0.01;
const REGION_PAD_DEG: f64 = 1e-7;

/// A model as the instances' content draws it: plain triangles in metres,
/// in glTF's axes as relief-models' `Model` holds them (x east, y up, z
/// south on the ground), the origin where the model stands.
///
/// The daemon fills it from a `relief_models::Model` field by field:
///
/// ```text
/// let models = |name: &str| {
///     scene_model(name).map(|m: Arc<relief_models::Model>| ModelMesh {
///         positions: m.positions.clone(),
///         normals: m.normals.clone(),
///         colors: m.colors.clone(),
///         indices: m.indices.clone(),
///     })
/// };
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelMesh {
    pub positions: Vec<[f32; 3]>,
    /// One per vertex (normalized when written; a zero normal points up).
    pub normals: Vec<[f32; 3]>,
    /// One per vertex: straight RGBA with sRGB-encoded 0..1 values.
    pub colors: Vec<[f32; 4]>,
    /// A triangle list.
    pub indices: Vec<u32>,
}

/// An instance tile's content and what it left out.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InstancesGlb {
    /// None when no instance could be placed.
    pub glb: Option<Glb>,
    /// Instances left out, by model name: `models` does not know the
    /// model, or it has no triangles.
    pub skipped: BTreeMap<String, usize>,
}

/// An instance tile as GLB.
///
/// Each instance stands at its position (longitude, latitude in degrees,
/// `z` absolute height above the ellipsoid in metres: the instance
/// sources add the ground before they hand the tile over), upright in the
/// east-north-up frame there, turned `rotation_deg` clockwise from north
/// seen from above (as the renderer turns it) and scaled by `scale`.
///
/// Billboard instances are drawn as the model they name, in full: a
/// billboard is the renderer's cheap picture of that same model, and 3D
/// Tiles has no such impostor. Instances of a model `models` does not know
/// (or one with no triangles) are left out and counted in
/// [`InstancesGlb::skipped`], as the renderer leaves them out.
///
/// Each instance carries a feature id (`_FEATURE_ID_0` of
/// `EXT_instance_features`: the instances' distinct `feature_id`s numbered
/// from 0 in the order they first come, each given its `feature_id` by a
/// property table of `EXT_structural_metadata`), so a client can pick it.
pub fn instances_glb(
    tile: &InstanceTile,
    models: &dyn Fn(&str) -> Option<ModelMesh>,
    grid: &TileGrid,
    key: TileKey,
) -> Result<InstancesGlb, StandardTileError> {
    if !grid.is_geodetic() {
        return Err(StandardTileError::NotGeodetic { crs: grid.crs().to_owned() });
    }
    if !grid.contains_key(key) {
        return Err(StandardTileError::KeyOutsideGrid { key });
    }
    for instance in &tile.instances {
        check_instance(instance)?;
    }
    // The models in the order they first come, each with its instances.
    let mut groups: Vec<(&str, Vec<&Instance>)> = Vec::new();
    for instance in &tile.instances {
        match groups.iter_mut().find(|(name, _)| *name == instance.model) {
            Some((_, list)) => list.push(instance),
            None => groups.push((&instance.model, vec![instance])),
        }
    }
    let mut skipped = BTreeMap::new();
    let mut placed: Vec<(&str, ModelMesh, Vec<&Instance>)> = Vec::new();
    for (name, list) in groups {
        match models(name) {
            Some(model) if !model.indices.is_empty() => {
                check_model(name, &model)?;
                placed.push((name, model, list));
            }
            _ => {
                skipped.insert(name.to_owned(), list.len());
            }
        }
    }
    if placed.is_empty() {
        return Ok(InstancesGlb { glb: None, skipped });
    }

    let extent = grid.tile_extent(key);
    let mut region = RegionBounds::new(f64::midpoint(extent.min_x, extent.max_x));
    let centre = box_centre(placed.iter().flat_map(|(_, _, list)| list.iter().map(|i| ecef_of(i))));
    let mut features: HashMap<u64, usize> = HashMap::new();
    for instance in placed.iter().flat_map(|(_, _, list)| list) {
        let next = features.len();
        features.entry(instance.feature_id).or_insert(next);
    }
    if features.len() > 1 << 24 {
        return Err(StandardTileError::BadMesh {
            reason: format!("{} instance features, more than a float feature id holds exactly (2^24)", features.len()),
        });
    }
    let mut relief_ids = vec![0u64; features.len()];
    for (&id, &k) in &features {
        relief_ids[k] = id;
    }
    let mut doc = Document::default();
    doc.uses("EXT_mesh_gpu_instancing", true);
    doc.uses("EXT_instance_features", false);
    let table = doc.feature_table(&relief_ids);
    for (name, model, list) in &placed {
        let corners = box_corners(model);
        let (mut translations, mut rotations, mut scales, mut ids) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for instance in list {
            let p = ecef_of(instance);
            let axes = model_axes(instance);
            grow(&mut region, p, &axes, instance.scale, &corners);
            translations.push(y_up([p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]]).map(|v| v as f32));
            rotations.push(quaternion(axes.map(y_up)).map(|v| v as f32));
            scales.push([instance.scale as f32; 3]);
            ids.push([features[&instance.feature_id] as f32]);
        }
        let normals: Vec<[f32; 3]> = model.normals.iter().map(|&n| unit(n)).collect();
        let colors: Vec<[u16; 4]> = model.colors.iter().map(|&c| color_u16(c)).collect();
        let attributes = json!({
            "POSITION": doc.floats(&model.positions, Target::Vertices, true),
            "NORMAL": doc.floats(&normals, Target::Vertices, false),
            "COLOR_0": doc.unorm16x4(&colors),
        });
        let indices = doc.indices(&model.indices);
        let mesh = doc.mesh(json!({
            "name": name,
            "primitives": [{ "attributes": attributes, "indices": indices, "material": 0, "mode": 4 }],
        }));
        let instancing = json!({
            "TRANSLATION": doc.floats(&translations, Target::Other, false),
            "ROTATION": doc.floats(&rotations, Target::Other, false),
            "SCALE": doc.floats(&scales, Target::Other, false),
            "_FEATURE_ID_0": doc.floats(&ids, Target::Other, false),
        });
        doc.node(json!({
            "name": name,
            "mesh": mesh,
            "extensions": {
                "EXT_mesh_gpu_instancing": { "attributes": instancing },
                "EXT_instance_features": { "featureIds": [{ "featureCount": features.len(), "attribute": 0, "propertyTable": table }] },
            },
        }));
    }
    region.pad(REGION_PAD_DEG, REGION_PAD_M);
    let region = region.region().expect("at least one instance was placed");
    Ok(InstancesGlb { glb: Some(Glb { bytes: doc.glb()?, transform: translation(centre), region }), skipped })
}

fn ecef_of(instance: &Instance) -> [f64; 3] {
    let [lon, lat, h] = instance.position;
    ecef_from_geodetic(lon, lat, h)
}

/// Where the model's x, y and z axes point in ECEF at the instance (unit
/// vectors): x east turned clockwise by the rotation, y up, z south turned
/// likewise, as the renderer places them.
fn model_axes(instance: &Instance) -> [[f64; 3]; 3] {
    let [east, north, up] = enu_axes(instance.position[0], instance.position[1]);
    let (sin, cos) = instance.rotation_deg.to_radians().sin_cos();
    let x = [0, 1, 2].map(|k| cos * east[k] - sin * north[k]);
    let z = [0, 1, 2].map(|k| -(sin * east[k] + cos * north[k]));
    [x, up, z]
}

/// The unit quaternion (x, y, z, w) of the rotation taking the unit axes
/// to `columns` (a proper rotation), by Shepperd's method.
fn quaternion(columns: [[f64; 3]; 3]) -> [f64; 4] {
    // m[r][c]: row r of column c.
    let m = |r: usize, c: usize| columns[c][r];
    let trace = m(0, 0) + m(1, 1) + m(2, 2);
    let q = if trace > 0.0 {
        let s = (trace + 1.0).sqrt() * 2.0;
        [(m(2, 1) - m(1, 2)) / s, (m(0, 2) - m(2, 0)) / s, (m(1, 0) - m(0, 1)) / s, s / 4.0]
    } else if m(0, 0) > m(1, 1) && m(0, 0) > m(2, 2) {
        let s = (1.0 + m(0, 0) - m(1, 1) - m(2, 2)).sqrt() * 2.0;
        [s / 4.0, (m(0, 1) + m(1, 0)) / s, (m(0, 2) + m(2, 0)) / s, (m(2, 1) - m(1, 2)) / s]
    } else if m(1, 1) > m(2, 2) {
        let s = (1.0 + m(1, 1) - m(0, 0) - m(2, 2)).sqrt() * 2.0;
        [(m(0, 1) + m(1, 0)) / s, s / 4.0, (m(1, 2) + m(2, 1)) / s, (m(0, 2) - m(2, 0)) / s]
    } else {
        let s = (1.0 + m(2, 2) - m(0, 0) - m(1, 1)).sqrt() * 2.0;
        [(m(0, 2) + m(2, 0)) / s, (m(1, 2) + m(2, 1)) / s, s / 4.0, (m(1, 0) - m(0, 1)) / s]
    };
    let length = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / length)
}

/// The eight corners of the box round a model's positions.
fn box_corners(model: &ModelMesh) -> [[f64; 3]; 8] {
    let first = model.positions.first().copied().unwrap_or_default();
    let (lo, hi) = model.positions.iter().fold((first, first), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])], [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])])
    });
    std::array::from_fn(|k| {
        let pick = |bit: usize, axis: usize| f64::from(if k >> bit & 1 == 0 { lo[axis] } else { hi[axis] });
        [pick(0, 0), pick(1, 1), pick(2, 2)]
    })
}

/// Grows the region by one instance's box. An instance whose box reaches
/// round the polar axis takes every longitude and the pole.
fn grow(region: &mut RegionBounds, p: [f64; 3], axes: &[[f64; 3]; 3], scale: f64, corners: &[[f64; 3]; 8]) {
    let reach = corners.iter().map(|c| c.iter().map(|v| v * v).sum::<f64>().sqrt()).fold(0.0, f64::max) * scale;
    for c in corners {
        let q = [0, 1, 2].map(|k| p[k] + scale * (c[0] * axes[0][k] + c[1] * axes[1][k] + c[2] * axes[2][k]));
        let (lon, lat, h) = geodetic_from_ecef(q);
        region.add(lon, lat, h);
    }
    if p[0].hypot(p[1]) <= reach {
        let (_, lat, h) = geodetic_from_ecef(p);
        region.add_every_longitude();
        region.add(0.0, 90f64.copysign(lat), h);
    }
}

/// A unit vector in f32 (up, +y, for a zero or broken one).
fn unit(n: [f32; 3]) -> [f32; 3] {
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if length.is_finite() && length > 1e-12 { n.map(|v| v / length) } else { [0.0, 1.0, 0.0] }
}

fn check_instance(instance: &Instance) -> Result<(), StandardTileError> {
    let bad = |reason: String| Err(StandardTileError::BadInstance { feature_id: instance.feature_id, reason });
    if !instance.position.iter().all(|v| v.is_finite()) {
        return bad(format!("position {:?} is not finite", instance.position));
    }
    if !(instance.scale.is_finite() && instance.scale > 0.0) {
        return bad(format!("scale {} is not a finite number more than 0", instance.scale));
    }
    if !instance.rotation_deg.is_finite() {
        return bad(format!("rotation {} is not finite", instance.rotation_deg));
    }
    Ok(())
}

fn check_model(name: &str, model: &ModelMesh) -> Result<(), StandardTileError> {
    let bad = |reason: String| Err(StandardTileError::BadModel { model: name.to_owned(), reason });
    let n = model.positions.len();
    if model.normals.len() != n || model.colors.len() != n {
        return bad(format!(
            "{n} positions but {} normals and {} colours (one each per vertex)",
            model.normals.len(),
            model.colors.len()
        ));
    }
    if !model.positions.iter().flatten().all(|v| v.is_finite()) {
        return bad("a position is not finite".into());
    }
    if !model.indices.len().is_multiple_of(3) {
        return bad(format!("{} indices are not whole triangles", model.indices.len()));
    }
    if let Some(i) = model.indices.iter().find(|&&i| i as usize >= n) {
        return bad(format!("index {i} is past the {n} vertices"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use relief_source::geodesy::{enu_from_geodetic, geodetic_from_ecef};
    use relief_source::{Instance, InstanceKind, InstanceTile, TileGrid, TileKey};

    use super::{ModelMesh, instances_glb};
    use crate::StandardTileError;
    use crate::gltf::read::{ecef_of, read, region_holds};

    /// Four corners: the origin, 3 m east, 5 m up, 2 m north (z south is
    /// -2), as four triangles.
    fn spike(color: [f32; 4]) -> ModelMesh {
        ModelMesh {
            positions: vec![[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, -2.0]],
            normals: vec![[0.0, 2.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]],
            colors: vec![color; 4],
            indices: vec![0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2],
        }
    }

    fn models(name: &str) -> Option<ModelMesh> {
        match name {
            "spike" => Some(spike([0.2, 0.5, 0.2, 1.0])),
            "house" => Some(spike([0.9, 0.8, 0.7, 1.0])),
            "empty" => Some(ModelMesh::default()),
            _ => None,
        }
    }

    fn instance(feature_id: u64, position: [f64; 3], model: &str, scale: f64, rotation_deg: f64) -> Instance {
        Instance { feature_id, position, kind: InstanceKind::Model, model: model.into(), scale, rotation_deg }
    }

    fn grid() -> TileGrid {
        TileGrid::geodetic(256).unwrap()
    }

    /// The quaternion (x, y, z, w) applied to v.
    fn rotate(q: [f32; 4], v: [f64; 3]) -> [f64; 3] {
        let [x, y, z, w] = q.map(f64::from);
        let t = [2.0 * (y * v[2] - z * v[1]), 2.0 * (z * v[0] - x * v[2]), 2.0 * (x * v[1] - y * v[0])];
        [
            v[0] + w * t[0] + (y * t[2] - z * t[1]),
            v[1] + w * t[1] + (z * t[0] - x * t[2]),
            v[2] + w * t[2] + (x * t[1] - y * t[0]),
        ]
    }

    /// Every model vertex of every instance, as written, within 1 cm of
    /// where it belongs in the east-north-up frame of the instance; the
    /// region holds them all. Returns the instances read, by model.
    fn assert_placed(tile: &InstanceTile, glb: &crate::Glb) -> BTreeMap<String, usize> {
        let r = read(&glb.bytes);
        let mut counts = BTreeMap::new();
        for node in r.json["nodes"].as_array().unwrap() {
            let name = node["name"].as_str().unwrap();
            let model = models(name).unwrap();
            let attributes = &node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
            let translations: Vec<[f32; 3]> = r.values(&attributes["TRANSLATION"]);
            let rotations: Vec<[f32; 4]> = r.values(&attributes["ROTATION"]);
            let scales: Vec<[f32; 3]> = r.values(&attributes["SCALE"]);
            let ids: Vec<f32> = r.values(&attributes["_FEATURE_ID_0"]);
            let mesh = &r.json["meshes"][node["mesh"].as_u64().unwrap() as usize];
            let positions: Vec<[f32; 3]> = r.values(&mesh["primitives"][0]["attributes"]["POSITION"]);
            assert_eq!(positions, model.positions);
            let placed: Vec<&Instance> = tile.instances.iter().filter(|i| i.model == name).collect();
            for list in [translations.len(), rotations.len(), scales.len(), ids.len()] {
                assert_eq!(list, placed.len(), "one entry per instance of {name}");
            }
            for (k, instance) in placed.iter().enumerate() {
                let q = rotations[k];
                assert!((q.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-6);
                let (sin, cos) = instance.rotation_deg.to_radians().sin_cos();
                let s = instance.scale;
                for p in &model.positions {
                    let v = rotate(q, p.map(|c| f64::from(c) * f64::from(scales[k][0])));
                    // The instance's origin back in ECEF, plus the turned
                    // vertex with y-up undone.
                    let origin = ecef_of(glb, translations[k]);
                    let world = [origin[0] + v[0], origin[1] - v[2], origin[2] + v[1]];
                    let (lon, lat, h) = geodetic_from_ecef(world);
                    let enu = enu_from_geodetic(instance.position, [lon, lat, h]);
                    let [x, y, z] = p.map(f64::from);
                    // Model x is east turned clockwise, -z north turned
                    // likewise, y up.
                    let want = [s * (x * cos - z * sin), s * (-x * sin - z * cos), s * y];
                    let off = (0..3).map(|i| (enu[i] - want[i]).powi(2)).sum::<f64>().sqrt();
                    assert!(off < 0.01, "{name} vertex {p:?} of {instance:?} is {off} m off: {enu:?} not {want:?}");
                    assert!(region_holds(&glb.region, lon, lat, h, 0.0), "{:?} misses {lon} {lat} {h}", glb.region);
                }
            }
            counts.insert(name.to_owned(), placed.len());
        }
        counts
    }

    #[test]
    fn instances_stand_turned_and_scaled_in_their_local_frames() {
        let (lon, lat) = (7.65, 45.97);
        let mut billboard = instance(30, [lon + 0.001, lat, 1500.0], "spike", 1.0, 0.0);
        billboard.kind = InstanceKind::Billboard;
        let tile = InstanceTile {
            instances: vec![
                instance(10, [lon, lat, 1200.0], "spike", 1.0, 90.0),
                instance(11, [lon + 0.0005, lat + 0.0002, 1210.5], "spike", 2.5, 33.0),
                instance(12, [lon, lat + 0.001, 1300.0], "house", 0.5, 271.0),
                instance(13, [lon, lat, 1200.0], "missing", 1.0, 0.0),
                billboard,
                instance(10, [lon + 0.002, lat, 1250.0], "missing", 1.0, 0.0),
                instance(14, [lon, lat, 0.0], "empty", 1.0, 0.0),
            ],
            skipped: Vec::new(),
        };
        let key = grid().key_at(15, lon, lat).unwrap();
        let out = instances_glb(&tile, &models, &grid(), key).unwrap();
        assert_eq!(out.skipped, BTreeMap::from([("missing".to_owned(), 2), ("empty".to_owned(), 1)]));
        let glb = out.glb.unwrap();
        let counts = assert_placed(&tile, &glb);
        assert_eq!(counts, BTreeMap::from([("spike".to_owned(), 3), ("house".to_owned(), 1)]));

        // Turned 90 degrees clockwise, the model's east arm points south.
        let r = read(&glb.bytes);
        let attributes = &r.json["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
        let q: Vec<[f32; 4]> = r.values(&attributes["ROTATION"]);
        let arm = rotate(q[0], [3.0, 0.0, 0.0]);
        let [e, n, _] = relief_source::geodesy::enu_axes(lon, lat);
        let arm_ecef = [arm[0], -arm[2], arm[1]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        assert!((dot(arm_ecef, n) + 3.0).abs() < 1e-5 && dot(arm_ecef, e).abs() < 1e-5);

        assert_eq!(r.json["extensionsRequired"], serde_json::json!(["EXT_mesh_gpu_instancing"]));
        assert_eq!(
            r.json["extensionsUsed"],
            serde_json::json!(["EXT_mesh_gpu_instancing", "EXT_instance_features", "EXT_structural_metadata"])
        );
        assert_eq!(r.feature_table(), [10, 11, 30, 12]);
        // The instancing accessors as EXT_mesh_gpu_instancing asks: float
        // VEC3 translations and scales, float VEC4 rotations, in buffer
        // views that are not vertex or index buffers.
        for (attribute, kind) in
            [("TRANSLATION", "VEC3"), ("ROTATION", "VEC4"), ("SCALE", "VEC3"), ("_FEATURE_ID_0", "SCALAR")]
        {
            let accessor = &r.json["accessors"][attributes[attribute].as_u64().unwrap() as usize];
            assert_eq!((&accessor["type"], &accessor["componentType"]), (&kind.into(), &5126.into()), "{attribute}");
            let view = &r.json["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
            assert!(view.get("target").is_none() && view.get("byteStride").is_none());
        }
        // Feature ids over the tile: 10, 11, 30 (spike), 12 (house).
        let ids: Vec<f32> = r.values(&attributes["_FEATURE_ID_0"]);
        assert_eq!(ids, [0.0, 1.0, 2.0]);
        let features = &r.json["nodes"][1]["extensions"]["EXT_instance_features"]["featureIds"][0];
        assert_eq!((&features["featureCount"], &features["propertyTable"]), (&4.into(), &0.into()));
        // Normals written unit length (a zero one pointing up).
        let mesh = &r.json["meshes"][0]["primitives"][0];
        let normals: Vec<[f32; 3]> = r.values(&mesh["attributes"]["NORMAL"]);
        assert_eq!(normals, [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
        let indices: Vec<u32> = r.values(&mesh["indices"]);
        assert_eq!(indices, spike([0.0; 4]).indices);
        // The region's heights: from the lowest base to the highest top.
        assert!((glb.region[4] - 1200.0).abs() < 0.02 && (glb.region[5] - 1505.0).abs() < 0.02, "{:?}", glb.region);
    }

    #[test]
    fn instances_near_the_antimeridian_and_at_the_pole_stay_finite_and_exact() {
        let across = InstanceTile {
            instances: vec![
                instance(1, [179.99999, 64.0, 10.0], "spike", 3.0, 45.0),
                instance(2, [-179.99999, 64.0, 10.0], "spike", 3.0, 200.0),
            ],
            skipped: Vec::new(),
        };
        let key = grid().key_at(14, 179.99999, 64.0).unwrap();
        let glb = instances_glb(&across, &models, &grid(), key).unwrap().glb.unwrap();
        assert_placed(&across, &glb);
        assert!(glb.region[0] > glb.region[2], "across the antimeridian: {:?}", glb.region);

        let pole = InstanceTile {
            instances: vec![
                instance(1, [0.0, 90.0, 2800.0], "spike", 1.0, 0.0),
                instance(2, [120.0, 89.99999, 2800.0], "house", 1.0, 10.0),
            ],
            skipped: Vec::new(),
        };
        let key = grid().key_at(14, 120.0, 89.99999).unwrap();
        let glb = instances_glb(&pole, &models, &grid(), key).unwrap().glb.unwrap();
        assert!(glb.region.iter().chain(&glb.transform).all(|v| v.is_finite()));
        assert_placed(&pole, &glb);
        assert_eq!(glb.region[0], -std::f64::consts::PI);
        assert_eq!(glb.region[2], std::f64::consts::PI);
        assert_eq!(glb.region[3], std::f64::consts::FRAC_PI_2);
    }

    #[test]
    fn unknown_models_bad_instances_and_bad_models() {
        let key = TileKey::new(3, 8, 2);
        let empty = instances_glb(&InstanceTile::default(), &models, &grid(), key).unwrap();
        assert_eq!((empty.glb, empty.skipped.len()), (None, 0));
        let unknown = InstanceTile { instances: vec![instance(1, [0.0, 0.0, 0.0], "x", 1.0, 0.0)], skipped: vec![] };
        let out = instances_glb(&unknown, &models, &grid(), key).unwrap();
        assert_eq!((out.glb, out.skipped), (None, BTreeMap::from([("x".to_owned(), 1)])));
        for bad in [
            instance(1, [0.0, f64::NAN, 0.0], "spike", 1.0, 0.0),
            instance(1, [0.0, 0.0, 0.0], "spike", 0.0, 0.0),
            instance(1, [0.0, 0.0, 0.0], "spike", 1.0, f64::INFINITY),
        ] {
            let tile = InstanceTile { instances: vec![bad], skipped: vec![] };
            let err = instances_glb(&tile, &models, &grid(), key).unwrap_err();
            assert!(matches!(err, StandardTileError::BadInstance { feature_id: 1, .. }), "{err}");
        }
        let broken = |name: &str| {
            let mut m = spike([1.0; 4]);
            match name {
                "short" => drop(m.normals.pop()),
                "past" => m.indices[4] = 9,
                _ => m.positions[0][1] = f32::NAN,
            }
            Some(m)
        };
        for name in ["short", "past", "nan"] {
            let tile = InstanceTile { instances: vec![instance(1, [0.0, 0.0, 0.0], name, 1.0, 0.0)], skipped: vec![] };
            let err = instances_glb(&tile, &broken, &grid(), key).unwrap_err();
            assert!(matches!(err, StandardTileError::BadModel { .. }), "{err}");
        }
    }
}
