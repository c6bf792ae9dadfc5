//! Loading users' glTF files: transforms, buffers, and every error a user
//! can meet, each naming the file in plain words.

use std::path::Path;

use relief_models::{ModelError, from_slice, load, stock_glb};
use serde_json::{Value, json};

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let n = chunk.iter().enumerate().fold(0u32, |n, (i, &b)| n | u32::from(b) << (16 - 8 * i));
        for i in 0..4 {
            let sextet = (n >> (18 - 6 * i)) & 63;
            out.push(if i <= chunk.len() { ALPHABET[sextet as usize] as char } else { '=' });
        }
    }
    out
}

fn floats(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64(bytes))
}

/// One triangle on the ground, counter-clockwise seen from above, as a
/// glTF document whose single buffer is `uri` (its bytes: `triangle_bytes`).
fn triangle_gltf(uri: &str, nodes: Value, extra: Value) -> Value {
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "meshes": [{ "name": "tri", "primitives": [{ "attributes": { "POSITION": 0 } }] }],
        "buffers": [{ "uri": uri, "byteLength": 36 }],
        "bufferViews": [{ "buffer": 0, "byteLength": 36 }],
        "accessors": [{ "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                        "min": [0.0, 0.0, -1.0], "max": [1.0, 0.0, 0.0] }],
    });
    doc["nodes"] = nodes;
    if let Value::Object(extra) = extra {
        for (key, value) in extra {
            doc[key] = value;
        }
    }
    doc
}

fn triangle_bytes() -> Vec<u8> {
    floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0])
}

fn one_node() -> Value {
    json!([{ "mesh": 0 }])
}

fn bytes_of(doc: &Value) -> Vec<u8> {
    serde_json::to_vec(doc).expect("a JSON value serialises")
}

/// The error's message names `path`, and shows no Rust Debug output.
fn assert_plain(error: &ModelError, path: &str) -> String {
    let message = error.to_string();
    assert!(message.contains(path), "message does not name {path}: {message}");
    assert!(!message.contains('{') && !message.contains("Os {"), "Debug output in: {message}");
    message
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("the test folder is writable");
    path
}

#[test]
fn a_missing_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("oak.glb");
    let error = load(&path).unwrap_err();
    assert!(matches!(error, ModelError::Read { .. }), "{error:?}");
    let message = assert_plain(&error, &path.display().to_string());
    assert!(message.starts_with("cannot read model file "), "{message}");
}

#[test]
fn random_bytes_are_not_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let mut state = 0x2545_f491_u32;
    let noise: Vec<u8> = (0..4096)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as u8
        })
        .collect();
    let path = write(dir.path(), "oak.glb", &noise);
    let error = load(&path).unwrap_err();
    assert!(matches!(error, ModelError::NotGltf { .. }), "{error:?}");
    assert!(assert_plain(&error, &path.display().to_string()).contains("is not a glTF 2.0 file"));
}

#[test]
fn a_truncated_glb_is_not_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let whole = stock_glb("conifer").unwrap();
    for cut in [7, 40, whole.len() / 2, whole.len() - 4] {
        let path = write(dir.path(), "conifer.glb", &whole[..cut]);
        let error = load(&path).unwrap_err();
        assert!(matches!(error, ModelError::NotGltf { .. }), "cut at {cut}: {error:?}");
        assert_plain(&error, &path.display().to_string());
    }
}

#[test]
fn gltf_1_and_other_json_are_refused_in_plain_words() {
    let old = json!({ "asset": { "version": "1.0" }, "meshes": { "tree": { "primitives": [] } } });
    let error = from_slice("/x/old.gltf", &bytes_of(&old)).unwrap_err();
    assert!(matches!(error, ModelError::NotGltf { .. }), "{error:?}");
    assert!(assert_plain(&error, "/x/old.gltf").contains("glTF 1.0"));

    let geojson = json!({ "type": "FeatureCollection", "features": [] });
    let error = from_slice("/x/roads.json", &bytes_of(&geojson)).unwrap_err();
    assert!(matches!(error, ModelError::NotGltf { .. }), "{error:?}");
    assert!(assert_plain(&error, "/x/roads.json").contains("asset"));
}

#[test]
fn a_lines_primitive_is_refused_naming_mesh_and_primitive() {
    let mut doc = triangle_gltf(&data_uri(&triangle_bytes()), one_node(), json!({}));
    doc["meshes"][0]["name"] = json!("wires");
    doc["meshes"][0]["primitives"][0]["mode"] = json!(1);
    let error = from_slice("/x/wires.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(matches!(error, ModelError::NotTriangles { .. }), "{error:?}");
    assert_eq!(
        assert_plain(&error, "/x/wires.gltf"),
        "/x/wires.gltf: mesh 'wires' primitive 0 uses mode Lines: only triangles are drawn"
    );
}

#[test]
fn a_file_without_meshes_has_no_triangles() {
    let empty = json!({ "asset": { "version": "2.0" }, "scenes": [{ "nodes": [] }] });
    let error = from_slice("/x/empty.gltf", &bytes_of(&empty)).unwrap_err();
    assert!(matches!(error, ModelError::NoTriangles { .. }), "{error:?}");
    assert_eq!(assert_plain(&error, "/x/empty.gltf"), "/x/empty.gltf has no triangles");
}

#[test]
fn node_translation_and_scale_apply_through_the_tree() {
    // A parent moves, its child scales: world = translate * scale.
    let nodes = json!([{ "translation": [10.0, 0.0, -5.0], "children": [1] }, { "scale": [2.0, 3.0, 2.0], "mesh": 0 }]);
    let extra = json!({ "materials": [{ "pbrMetallicRoughness": { "baseColorFactor": [0.214_041, 0.214_041, 0.214_041, 0.5] } }] });
    let mut doc = triangle_gltf(&data_uri(&triangle_bytes()), nodes, extra);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    let model = from_slice("tri.gltf", &bytes_of(&doc)).unwrap();
    assert_eq!(model.positions, [[10.0, 0.0, -5.0], [12.0, 0.0, -5.0], [10.0, 0.0, -7.0]]);
    assert_eq!(model.indices, [0, 1, 2]);
    assert_eq!(model.triangle_count(), 1);
    for n in &model.normals {
        assert!((n[1] - 1.0).abs() < 1e-6, "computed normal {n:?}");
    }
    for c in &model.colors {
        // Linear 0.214 is sRGB 0.5; alpha is not encoded.
        assert!((c[0] - 0.5).abs() < 1e-3 && c[3] == 0.5, "colour {c:?}");
    }
    assert_eq!(model.bounds.min, [10.0, 0.0, -7.0]);
    assert_eq!(model.bounds.max, [12.0, 0.0, -5.0]);
}

#[test]
fn a_mirroring_node_keeps_triangles_facing_out() {
    let mut bytes = triangle_bytes();
    bytes.extend(floats(&[0.0, 1.0, 0.0].repeat(3)));
    let mut doc = triangle_gltf(&data_uri(&bytes), json!([{ "scale": [-1.0, 1.0, 1.0], "mesh": 0 }]), json!({}));
    doc["buffers"][0]["byteLength"] = json!(72);
    doc["bufferViews"][0]["byteLength"] = json!(72);
    doc["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3" }));
    doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(1);
    let model = from_slice("mirror.gltf", &bytes_of(&doc)).unwrap();
    let [a, b, c] = [0, 1, 2].map(|k| model.positions[model.indices[k] as usize]);
    let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
    let face_y = u[2] * v[0] - u[0] * v[2];
    assert!(face_y > 0.0, "the mirrored triangle faces down");
    assert_eq!(model.normals, [[0.0, 1.0, 0.0]; 3]);
}

#[test]
fn strips_and_fans_become_lists_and_vertex_colours_multiply() {
    // Four corners of a unit square on the ground, as a strip and as a fan.
    let square = floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, -1.0]);
    let mut bytes = square.clone();
    bytes.extend([255, 0, 0, 255, 255, 255, 0, 255, 0, 0, 255, 255, 255, 128, 0, 0]); // COLOR_0, normalized u8 RGBA
    for (mode, order) in [(5, [0usize, 1, 2, 3]), (6, [0, 1, 3, 2])] {
        let mut ordered: Vec<u8> = order.iter().flat_map(|&i| square[12 * i..12 * i + 12].to_vec()).collect();
        ordered.extend(&bytes[48..]);
        let mut doc = triangle_gltf(&data_uri(&ordered), one_node(), json!({}));
        doc["buffers"][0]["byteLength"] = json!(64);
        doc["bufferViews"][0]["byteLength"] = json!(64);
        doc["accessors"][0]["count"] = json!(4);
        doc["accessors"]
            .as_array_mut()
            .unwrap()
            .push(json!({ "bufferView": 0, "byteOffset": 48, "componentType": 5121, "normalized": true, "count": 4, "type": "VEC4" }));
        doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(1);
        doc["meshes"][0]["primitives"][0]["mode"] = json!(mode);
        let model = from_slice("square.gltf", &bytes_of(&doc)).unwrap();
        assert_eq!(model.triangle_count(), 2, "mode {mode}");
        for t in model.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| model.positions[t[k] as usize]);
            let face_y = (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]);
            assert!(face_y > 0.0, "mode {mode}: triangle {t:?} faces down");
        }
        assert_eq!(model.colors[0], [1.0, 0.0, 0.0, 1.0]);
        assert!((model.colors[3][3] - 0.0).abs() < 1e-6);
    }
}

#[test]
fn an_external_bin_beside_the_gltf_loads() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "tri data.bin", &triangle_bytes());
    let doc = triangle_gltf("tri%20data.bin", one_node(), json!({}));
    let path = write(dir.path(), "tri.gltf", &bytes_of(&doc));
    let model = load(&path).unwrap();
    assert_eq!(model.positions, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]);

    // The same JSON given as bytes has no folder to look in.
    let error = from_slice("tri.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(matches!(error, ModelError::Buffer { .. }), "{error:?}");
    assert_plain(&error, "tri.gltf");
}

#[test]
fn a_missing_bin_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let doc = triangle_gltf("tree.bin", one_node(), json!({}));
    let path = write(dir.path(), "oak.gltf", &bytes_of(&doc));
    let error = load(&path).unwrap_err();
    assert!(matches!(error, ModelError::Buffer { index: 0, .. }), "{error:?}");
    let message = assert_plain(&error, &path.display().to_string());
    assert!(message.contains("buffer 0 refers to 'tree.bin', which cannot be read"), "{message}");
}

#[test]
fn a_short_buffer_or_accessor_is_refused() {
    let doc = triangle_gltf(&data_uri(&triangle_bytes()[..24]), one_node(), json!({}));
    let error = from_slice("short.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(assert_plain(&error, "short.gltf").contains("fewer than the 36 it declares"), "{error}");

    let mut doc = triangle_gltf(&data_uri(&triangle_bytes()), one_node(), json!({}));
    doc["accessors"][0]["byteOffset"] = json!(12);
    let error = from_slice("offset.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(matches!(error, ModelError::Invalid { .. }), "{error:?}");
    assert!(assert_plain(&error, "offset.gltf").contains("mesh 'tri' primitive 0"), "{error}");
}

#[test]
fn a_position_that_is_not_a_number_is_refused() {
    let bytes = floats(&[0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, 0.0, -1.0]);
    let doc = triangle_gltf(&data_uri(&bytes), one_node(), json!({}));
    let error = from_slice("nan.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(assert_plain(&error, "nan.gltf").contains("not a finite number"), "{error}");
}

#[test]
fn an_index_past_the_last_vertex_is_refused() {
    let mut bytes = triangle_bytes();
    bytes.extend([0u32, 1, 7].iter().flat_map(|i| i.to_le_bytes()));
    let mut doc = triangle_gltf(&data_uri(&bytes), one_node(), json!({}));
    doc["buffers"][0]["byteLength"] = json!(48);
    doc["bufferViews"].as_array_mut().unwrap().push(json!({ "buffer": 0, "byteOffset": 36, "byteLength": 12 }));
    doc["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR" }));
    doc["meshes"][0]["primitives"][0]["indices"] = json!(1);
    let error = from_slice("index.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(assert_plain(&error, "index.gltf").contains("index 7 but only 3 vertices"), "{error}");
}

#[test]
fn more_than_a_million_vertices_are_refused_before_reading() {
    // A sparse accessor declares the vertices without storing them.
    let mut doc = triangle_gltf(&data_uri(&[0; 16]), one_node(), json!({}));
    doc["buffers"][0]["byteLength"] = json!(16);
    doc["bufferViews"][0]["byteLength"] = json!(16);
    doc["accessors"][0] = json!({
        "componentType": 5126, "count": 3_000_000, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0],
        "sparse": { "count": 1, "indices": { "bufferView": 0, "componentType": 5125 }, "values": { "bufferView": 0, "byteOffset": 4 } },
    });
    let error = from_slice("/x/oak.glb", &bytes_of(&doc)).unwrap_err();
    assert!(matches!(error, ModelError::TooManyVertices { vertices: 3_000_000, .. }), "{error:?}");
    assert_eq!(assert_plain(&error, "/x/oak.glb"), "/x/oak.glb has 3000000 vertices: at most 1000000 are drawn");
}

#[test]
fn a_file_over_256_mib_is_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.glb");
    std::fs::File::create(&path).unwrap().set_len(257 << 20).unwrap();
    let error = load(&path).unwrap_err();
    assert!(matches!(error, ModelError::TooLarge { .. }), "{error:?}");
    assert!(assert_plain(&error, &path.display().to_string()).contains("257 MiB"), "{error}");
}

#[test]
fn required_extensions_that_change_geometry_are_refused() {
    let draco = json!({ "extensionsRequired": ["KHR_draco_mesh_compression"], "extensionsUsed": ["KHR_draco_mesh_compression"] });
    let doc = triangle_gltf(&data_uri(&triangle_bytes()), one_node(), draco);
    let error = from_slice("draco.glb", &bytes_of(&doc)).unwrap_err();
    assert!(matches!(error, ModelError::UnsupportedExtension { .. }), "{error:?}");
    assert!(assert_plain(&error, "draco.glb").contains("KHR_draco_mesh_compression"));

    // A material extension changes nothing drawn here: the model loads.
    let unlit = json!({ "extensionsRequired": ["KHR_materials_unlit"], "extensionsUsed": ["KHR_materials_unlit"] });
    let doc = triangle_gltf(&data_uri(&triangle_bytes()), one_node(), unlit);
    assert_eq!(from_slice("unlit.glb", &bytes_of(&doc)).unwrap().triangle_count(), 1);
}

#[test]
fn a_node_cycle_is_refused_not_followed() {
    let nodes = json!([{ "children": [1] }, { "children": [0], "mesh": 0 }]);
    let doc = triangle_gltf(&data_uri(&triangle_bytes()), nodes, json!({}));
    let error = from_slice("cycle.gltf", &bytes_of(&doc)).unwrap_err();
    assert_plain(&error, "cycle.gltf");
}

#[test]
fn a_position_accessor_that_does_not_exist_is_refused() {
    let mut doc = triangle_gltf(&data_uri(&triangle_bytes()), one_node(), json!({}));
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9);
    let error = from_slice("dangling.gltf", &bytes_of(&doc)).unwrap_err();
    assert!(matches!(error, ModelError::NotGltf { .. }), "{error:?}");
    assert_plain(&error, "dangling.gltf");
}

#[test]
fn buffers_that_nothing_drawn_uses_are_not_read() {
    // Texture coordinates in a .bin that is not there: textures are not drawn.
    let mut doc = triangle_gltf(&data_uri(&triangle_bytes()), one_node(), json!({}));
    doc["buffers"].as_array_mut().unwrap().push(json!({ "uri": "uv.bin", "byteLength": 24 }));
    doc["bufferViews"].as_array_mut().unwrap().push(json!({ "buffer": 1, "byteLength": 24 }));
    doc["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2" }));
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(1);
    assert_eq!(from_slice("uv.gltf", &bytes_of(&doc)).unwrap().triangle_count(), 1);
}

#[test]
fn corrupted_stock_files_give_errors_not_panics() {
    let whole = stock_glb("house").unwrap();
    let json_end = 20 + u32::from_le_bytes(whole[12..16].try_into().unwrap()) as usize;
    let digits: Vec<usize> = (20..json_end).filter(|&i| whole[i].is_ascii_digit()).collect();
    let mut state = 0x9e37_79b9_u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as usize
    };
    for round in 0..3000 {
        let mut bytes = whole.clone();
        for _ in 0..=(round % 3) {
            if next() % 2 == 0 {
                // A different digit in the JSON: counts, offsets, indices and lengths change.
                let at = digits[next() % digits.len()];
                bytes[at] = b'0' + (next() % 10) as u8;
            } else {
                let at = next() % bytes.len();
                bytes[at] = next() as u8;
            }
        }
        if let Err(error) = from_slice("house.glb", &bytes) {
            assert!(error.to_string().contains("house.glb"), "{error}");
        }
    }
}
