//! relief's 3D Tiles glTF content (issue 40) through the Khronos glTF
//! validator (`gltf-validator` from `tests/npm`, run by node): a buildings
//! GLB and an instances GLB from hand-made tiles, each with no errors, and
//! the triangles and vertices the validator counts as written.

use std::path::Path;
use std::process::Command;

use relief_source::{Instance, InstanceKind, InstanceTile, MeshPart, MeshTile, TileGrid};
use relief_standard_tiles::{ModelMesh, buildings_glb, instances_glb};
use relief_tests::npm;
use serde_json::Value;

/// Reads a GLB with `validator.validateBytes` and prints the report.
const SCRIPT: &str = r"
const fs = require('fs');
const validator = require(process.env.RELIEF_GLTF_VALIDATOR);
validator
  .validateBytes(new Uint8Array(fs.readFileSync(process.env.RELIEF_GLB)), { maxIssues: 1000 })
  .then((report) => console.log(JSON.stringify(report)))
  .catch((error) => { console.error(String(error)); process.exit(1); });
";

/// `tests/npm/node_modules`, or None (with a note) where node or npm is
/// missing, or npm cannot install outside CI.
fn modules(test: &str) -> Option<std::path::PathBuf> {
    if !npm::available() {
        return None;
    }
    match npm::node_modules() {
        Ok(m) => Some(m),
        Err(e) if std::env::var_os("CI").is_none() => {
            eprintln!("skipping {test}: the npm packages cannot be installed here: {e:#}");
            None
        }
        Err(e) => panic!("{test}: CI must install the npm packages: {e:#}"),
    }
}

/// The validator's report on `bytes`, with its warnings and errors printed;
/// fails on any error.
fn validate(modules: &Path, name: &str, bytes: &[u8]) -> Value {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let file = dir.path().join(name);
    std::fs::write(&file, bytes).expect("the GLB written");
    let out = Command::new("node")
        .args(["-e", SCRIPT])
        .env("RELIEF_GLTF_VALIDATOR", modules.join("gltf-validator"))
        .env("RELIEF_GLB", &file)
        .output()
        .expect("node runs");
    assert!(out.status.success(), "the validator failed on {name}: {}", String::from_utf8_lossy(&out.stderr));
    let report: Value = serde_json::from_slice(&out.stdout).expect("the validator's JSON report");
    let issues = &report["issues"];
    for message in issues["messages"].as_array().into_iter().flatten() {
        eprintln!(
            "{name}: {} {}: {} at {}",
            message["severity"], message["code"], message["message"], message["pointer"]
        );
    }
    assert_eq!(issues["numErrors"], 0, "{name} has errors: {}", issues["messages"]);
    eprintln!("{name}: {} warnings, {} infos, {} hints", issues["numWarnings"], issues["numInfos"], issues["numHints"]);
    report
}

/// A closed box of 12 triangles, `size_deg` on a side, from `z.0` to
/// `z.1` metres; `inward` winds it clockwise seen from outside, as a
/// MultiPatch ring may come.
fn add_box(
    mesh: &mut MeshTile,
    at: (f64, f64),
    size_deg: f64,
    z: (f64, f64),
    part: (u64, [u8; 4], bool),
    inward: bool,
) {
    let first = mesh.positions.len() as u32;
    for h in [z.0, z.1] {
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            mesh.positions.push([at.0 + dx * size_deg, at.1 + dy * size_deg, h]);
        }
    }
    let first_index = mesh.indices.len() as u32;
    for [a, b, c, d] in [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]] {
        let quad = if inward { [a, c, b, a, d, c] } else { [a, b, c, a, c, d] };
        mesh.indices.extend(quad.map(|k| first + k));
    }
    let (feature_id, color, on_ground) = part;
    mesh.parts.push(MeshPart { feature_id, first_index, index_count: 36, color, on_ground });
}

#[test]
fn buildings_glb_passes_the_gltf_validator() {
    let Some(modules) = modules("buildings_glb_passes_the_gltf_validator") else { return };
    let grid = TileGrid::geodetic(256).unwrap();
    let (lon, lat) = (8.54, 47.37);
    let mut mesh = MeshTile::default();
    add_box(&mut mesh, (lon, lat), 0.0002, (0.0, 18.0), (101, [180, 170, 160, 255], true), false);
    add_box(&mut mesh, (lon + 0.0003, lat), 0.0001, (0.0, 9.0), (102, [120, 40, 30, 255], true), true);
    add_box(&mut mesh, (lon, lat + 0.0003), 0.0001, (420.0, 450.0), (103, [40, 90, 200, 128], false), false);
    let key = grid.key_at(16, lon, lat).unwrap();
    let glb = buildings_glb(&mesh, &grid, key, &|x, y| 408.0 + 300.0 * (x - lon) + 100.0 * (y - lat))
        .unwrap()
        .expect("three boxes");
    let report = validate(&modules, "buildings.glb", &glb.bytes);
    assert_eq!(report["info"]["totalTriangleCount"], 36);
    assert_eq!(report["info"]["totalVertexCount"], 108);
    assert_eq!(report["info"]["drawCallCount"], 1);
}

#[test]
fn instances_glb_passes_the_gltf_validator() {
    let Some(modules) = modules("instances_glb_passes_the_gltf_validator") else { return };
    let grid = TileGrid::geodetic(256).unwrap();
    let (lon, lat) = (-121.7, 46.85);
    // The stock models, filled in as the daemon fills them.
    let models = |name: &str| {
        relief_models::stock(name).map(|m| ModelMesh {
            positions: m.positions,
            normals: m.normals,
            colors: m.colors,
            indices: m.indices,
        })
    };
    let at = |k: u32| [lon + 0.0001 * f64::from(k % 7), lat + 0.0001 * f64::from(k / 7), 1500.0 + f64::from(k)];
    let mut instances: Vec<Instance> = (0..40)
        .map(|k| Instance {
            feature_id: u64::from(k / 4),
            position: at(k),
            kind: if k % 5 == 0 { InstanceKind::Billboard } else { InstanceKind::Model },
            model: ["conifer", "broadleaf", "shrub", "house"][k as usize % 4].to_owned(),
            scale: 0.5 + f64::from(k) / 20.0,
            rotation_deg: f64::from(k) * 37.0 % 360.0,
        })
        .collect();
    instances.push(Instance {
        feature_id: 99,
        position: at(41),
        kind: InstanceKind::Model,
        model: "no such model".to_owned(),
        scale: 1.0,
        rotation_deg: 0.0,
    });
    let tile = InstanceTile { instances, skipped: Vec::new() };
    let key = grid.key_at(15, lon, lat).unwrap();
    let out = instances_glb(&tile, &models, &grid, key).unwrap();
    assert_eq!(out.skipped.get("no such model"), Some(&1));
    let glb = out.glb.expect("40 instances of stock models");
    let report = validate(&modules, "instances.glb", &glb.bytes);
    // One draw per model; the validator counts each model's triangles once
    // (it does not multiply by the instances).
    let triangles: usize = ["conifer", "broadleaf", "shrub", "house"]
        .iter()
        .map(|name| relief_models::stock(name).unwrap().triangle_count())
        .sum();
    assert_eq!(report["info"]["drawCallCount"], 4);
    assert_eq!(report["info"]["totalTriangleCount"], triangles);
}

/// The GLBs reliefd serves under `/tiles/3d/` for the demo scene (its town
/// of extruded buildings and its scattered forest), found as a 3D Tiles
/// client finds them: `tileset.json`, a group's tileset, its content.
#[test]
fn served_glbs_pass_the_gltf_validator() {
    let Some(modules) = modules("served_glbs_pass_the_gltf_validator") else { return };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let manifest = relief_tests::fixtures::write_demo_scene(dir.path()).expect("the demo scene");
    let daemon = relief_tests::daemon::Reliefd::start(&manifest, &[]).expect("reliefd starts");
    let base = format!("{}/tiles/3d", daemon.url());
    let get = |url: &str| {
        let reply = relief_tests::http::get(url).expect("an answer");
        assert_eq!(reply.status, 200, "{url}: {}", String::from_utf8_lossy(&reply.body));
        reply
    };
    let tileset = get(&format!("{base}/tileset.json")).json().expect("tileset.json");
    assert_eq!(tileset["asset"]["version"], "1.1");
    let version = tileset["asset"]["tilesetVersion"].as_str().expect("a tilesetVersion").to_owned();
    let groups = tileset["root"]["children"].as_array().expect("groups");
    for layer in ["buildings", "instances"] {
        let mut checked = 0;
        for group in groups.iter().filter(|g| g["content"]["uri"].as_str().is_some_and(|u| u.starts_with(layer))) {
            let uri = group["content"]["uri"].as_str().unwrap_or_default();
            let inner = get(&format!("{base}/{uri}?v={version}")).json().expect("a group's tileset");
            for leaf in inner["root"]["children"].as_array().into_iter().flatten().take(2) {
                let content = leaf["content"]["uri"].as_str().unwrap_or_default().trim_start_matches("../../../");
                assert!(
                    content.starts_with(layer) && content.rsplit_once('.').is_some_and(|(_, e)| e == "glb"),
                    "{content}"
                );
                let glb = get(&format!("{base}/{content}?v={version}"));
                assert_eq!(glb.header("content-type"), Some("model/gltf-binary"));
                validate(&modules, &content.replace('/', "_"), &glb.body);
                checked += 1;
            }
            if checked >= 2 {
                break;
            }
        }
        assert!(checked > 0, "no {layer} content served");
    }
    daemon.stop(&[]).expect("reliefd stops");
}
