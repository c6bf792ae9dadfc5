//! A glTF 2.0 document built up accessor by accessor into one binary
//! buffer, and written as GLB: the 12-byte header, the JSON chunk padded
//! with spaces to 4 bytes, the BIN chunk padded with zeros.

use serde_json::{Value, json};

use crate::StandardTileError;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const GLB_VERSION: u32 = 2;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// glTF's component types and buffer-view targets.
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// What a buffer view holds: vertex attributes, triangle indices, or
/// neither (per-instance data of `EXT_mesh_gpu_instancing`).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Target {
    Vertices,
    Indices,
    Other,
}

/// The document so far. Every accessor has a buffer view of its own, each
/// starting on a 4-byte boundary of the one buffer.
#[derive(Default)]
pub(crate) struct Document {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
    used: Vec<&'static str>,
    required: Vec<&'static str>,
    /// The buffer view and count of the feature table's `feature_id`s.
    feature_table: Option<(usize, usize)>,
}

impl Document {
    /// Declares an extension in `extensionsUsed`, and in
    /// `extensionsRequired` when the content cannot be drawn without it.
    pub(crate) fn uses(&mut self, extension: &'static str, required: bool) {
        if !self.used.contains(&extension) {
            self.used.push(extension);
        }
        if required && !self.required.contains(&extension) {
            self.required.push(extension);
        }
    }

    fn view(&mut self, bytes: &[u8], target: Target) -> usize {
        self.view_aligned(bytes, target, 4)
    }

    fn view_aligned(&mut self, bytes: &[u8], target: Target, align: usize) -> usize {
        while !self.bin.len().is_multiple_of(align) {
            self.bin.push(0);
        }
        let mut view = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        match target {
            Target::Vertices => view["target"] = json!(ARRAY_BUFFER),
            Target::Indices => view["target"] = json!(ELEMENT_ARRAY_BUFFER),
            Target::Other => {}
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    fn accessor(&mut self, mut accessor: Value) -> usize {
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// Float vectors (VEC3 or VEC4 by `N`), with their min and max when
    /// asked (POSITION must have them).
    pub(crate) fn floats<const N: usize>(&mut self, data: &[[f32; N]], target: Target, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        self.view(&bytes, target);
        let kind = match N {
            1 => "SCALAR",
            2 => "VEC2",
            3 => "VEC3",
            _ => "VEC4",
        };
        let mut accessor = json!({ "componentType": FLOAT, "count": data.len(), "type": kind });
        if bounds {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in data {
                for k in 0..N {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            accessor["min"] = json!(lo.iter().map(|&v| f64::from(v)).collect::<Vec<_>>());
            accessor["max"] = json!(hi.iter().map(|&v| f64::from(v)).collect::<Vec<_>>());
        }
        self.accessor(accessor)
    }

    /// Normalized unsigned shorts, VEC4 (colours).
    pub(crate) fn unorm16x4(&mut self, data: &[[u16; 4]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        self.view(&bytes, Target::Vertices);
        self.accessor(json!({
            "componentType": UNSIGNED_SHORT, "normalized": true, "count": data.len(), "type": "VEC4",
        }))
    }

    /// Triangle indices, as unsigned ints.
    pub(crate) fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.view(&bytes, Target::Indices);
        self.accessor(json!({ "componentType": UNSIGNED_INT, "count": data.len(), "type": "SCALAR" }))
    }

    /// The property table (`EXT_structural_metadata`) that gives each
    /// feature id its relief `feature_id`: `ids[k]` for feature id k.
    /// Returns the table's index, for a feature id set's `propertyTable`.
    pub(crate) fn feature_table(&mut self, ids: &[u64]) -> usize {
        let bytes: Vec<u8> = ids.iter().flat_map(|v| v.to_le_bytes()).collect();
        // The extension asks for 8-byte alignment of its buffer views.
        let view = self.view_aligned(&bytes, Target::Other, 8);
        self.feature_table = Some((view, ids.len()));
        self.uses("EXT_structural_metadata", false);
        0
    }

    pub(crate) fn mesh(&mut self, mesh: Value) -> usize {
        self.meshes.push(mesh);
        self.meshes.len() - 1
    }

    pub(crate) fn node(&mut self, node: Value) {
        self.nodes.push(node);
    }

    /// The GLB: one scene of every node, one material (see [`material`]).
    pub(crate) fn glb(self) -> Result<Vec<u8>, StandardTileError> {
        let mut root = json!({
            "asset": { "version": "2.0", "generator": concat!("relief-standard-tiles ", env!("CARGO_PKG_VERSION")) },
            "scene": 0,
            "scenes": [{ "nodes": (0..self.nodes.len()).collect::<Vec<_>>() }],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": [material()],
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{ "byteLength": self.bin.len() }],
        });
        if let Some((view, count)) = self.feature_table {
            root["extensions"] = json!({ "EXT_structural_metadata": {
                "schema": {
                    "id": "relief",
                    "classes": { "feature": {
                        "description": "A feature of relief's sources.",
                        "properties": { "feature_id": {
                            "description": "The feature's id in its relief source (`feature_id` of relief's tiles).",
                            "type": "SCALAR",
                            "componentType": "UINT64",
                            "required": true,
                        } },
                    } },
                },
                "propertyTables": [{ "class": "feature", "count": count, "properties": { "feature_id": { "values": view } } }],
            } });
        }
        if !self.used.is_empty() {
            root["extensionsUsed"] = json!(self.used);
        }
        if !self.required.is_empty() {
            root["extensionsRequired"] = json!(self.required);
        }
        let text = serde_json::to_vec(&root).expect("a JSON value with string keys always serializes");
        container(&text, &self.bin)
    }
}

/// The one material: white, so `COLOR_0` alone gives the colour; fully
/// rough and not metallic, as the renderer lights buildings and models;
/// double-sided, since MultiPatch rings and user models come in either
/// winding.
fn material() -> Value {
    json!({
        "pbrMetallicRoughness": { "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 },
        "doubleSided": true,
    })
}

/// Header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).
fn container(json: &[u8], bin: &[u8]) -> Result<Vec<u8>, StandardTileError> {
    let json_len = json.len().next_multiple_of(4);
    let bin_len = bin.len().next_multiple_of(4);
    let total = 12 + 8 + json_len + 8 + bin_len;
    let too_large = |size: usize| StandardTileError::TooLarge { what: "the GLB", size: size as u64 };
    let total_u32 = u32::try_from(total).map_err(|_| too_large(total))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(GLB_MAGIC);
    out.extend_from_slice(&GLB_VERSION.to_le_bytes());
    out.extend_from_slice(&total_u32.to_le_bytes());
    // Both fit: each is less than the total.
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(20 + json_len, b' ');
    out.extend_from_slice(&(bin_len as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(bin);
    out.resize(total, 0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glb_chunks_are_padded_and_lengths_add_up() {
        let mut doc = Document::default();
        let a = doc.floats(&[[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], Target::Vertices, true);
        let m = doc.mesh(json!({ "primitives": [{ "attributes": { "POSITION": a }, "material": 0 }] }));
        doc.node(json!({ "mesh": m }));
        let glb = doc.glb().unwrap();
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(json_len % 4, 0);
        let bin_at = 20 + json_len;
        let bin_len = u32::from_le_bytes(glb[bin_at..bin_at + 4].try_into().unwrap()) as usize;
        assert_eq!(bin_len % 4, 0);
        assert_eq!(bin_at + 8 + bin_len, glb.len());
        assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
        let parsed = ::gltf::Gltf::from_slice(&glb).unwrap();
        let accessor = parsed.accessors().next().unwrap();
        assert_eq!(accessor.count(), 3);
        assert_eq!(accessor.max(), Some(json!([1.0, 1.0, 0.0])));
    }
}
