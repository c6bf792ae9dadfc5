//! Writing flat-shaded, single-colour parts as a `.glb` file: one mesh with
//! one primitive and one material per part.

use serde_json::json;

use crate::color::linear_from_srgb;
use crate::glb;
use crate::math::{add, cross, dot, sub};

/// One single-coloured piece of a model, built from flat facets.
pub(crate) struct Part {
    /// The material's name.
    pub name: &'static str,
    /// The colour, sRGB-encoded 0..1 (it is stored linear, as glTF wants).
    pub color: [f32; 3],
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub indices: Vec<u32>,
}

impl Part {
    pub fn new(name: &'static str, color: [f32; 3]) -> Self {
        Self { name, color, positions: Vec::new(), normals: Vec::new(), indices: Vec::new() }
    }

    /// Adds a flat convex polygon (corners in order, either way round),
    /// turned so that its front faces away from `inside`. The polygon gets
    /// its own vertices, so its edges stay hard.
    pub fn facet(&mut self, corners: &[[f32; 3]], inside: [f32; 3]) {
        let normal = corners[1..corners.len() - 1]
            .iter()
            .zip(&corners[2..])
            .map(|(&b, &c)| cross(sub(b, corners[0]), sub(c, corners[0])))
            .fold([0.0; 3], add);
        let length = dot(normal, normal).sqrt();
        let outward = dot(normal, sub(corners[0], inside)) >= 0.0;
        let normal = normal.map(|v| if outward { v / length } else { -v / length });
        let first = self.positions.len() as u32;
        self.positions.extend_from_slice(corners);
        self.normals.extend(std::iter::repeat_n(normal, corners.len()));
        for i in 1..corners.len() as u32 - 1 {
            let (b, c) = if outward { (i, i + 1) } else { (i + 1, i) };
            self.indices.extend([first, first + b, first + c]);
        }
    }
}

/// The `.glb` bytes of a model named `name` made of `parts`.
pub(crate) fn glb(name: &str, parts: &[Part]) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut primitives, mut materials) = (vec![], vec![], vec![], vec![]);
    for part in parts {
        let first_accessor = accessors.len();
        let (min, max) = bounds(&part.positions);
        for (values, target, extra) in [
            (floats(&part.positions), 34962, json!({ "type": "VEC3", "componentType": 5126, "min": min, "max": max })),
            (floats(&part.normals), 34962, json!({ "type": "VEC3", "componentType": 5126 })),
            (
                part.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
                34963,
                json!({ "type": "SCALAR", "componentType": 5125 }),
            ),
        ] {
            let mut accessor = extra;
            let count = if target == 34963 { part.indices.len() } else { part.positions.len() };
            accessor["bufferView"] = json!(views.len());
            accessor["count"] = json!(count);
            accessors.push(accessor);
            views.push(json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": values.len(), "target": target }));
            bin.extend_from_slice(&values);
        }
        primitives.push(json!({
            "attributes": { "POSITION": first_accessor, "NORMAL": first_accessor + 1 },
            "indices": first_accessor + 2,
            "material": materials.len(),
            "mode": 4,
        }));
        let [r, g, b] = part.color.map(linear_from_srgb);
        materials.push(json!({
            "name": part.name,
            "pbrMetallicRoughness": { "baseColorFactor": [r, g, b, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 },
        }));
    }
    let document = json!({
        "asset": { "version": "2.0", "generator": "relief-models" },
        "scene": 0,
        "scenes": [{ "name": name, "nodes": [0] }],
        "nodes": [{ "name": name, "mesh": 0 }],
        "meshes": [{ "name": name, "primitives": primitives }],
        "materials": materials,
        "buffers": [{ "byteLength": bin.len() }],
        "bufferViews": views,
        "accessors": accessors,
    });
    glb::assemble(document.to_string().as_bytes(), &bin)
}

fn floats(values: &[[f32; 3]]) -> Vec<u8> {
    values.iter().flatten().flat_map(|v| v.to_le_bytes()).collect()
}

fn bounds(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let b = crate::Bounds::of(positions);
    (b.min, b.max)
}
