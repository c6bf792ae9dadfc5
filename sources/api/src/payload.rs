//! Tile payloads: what a source produces for one tile.

use std::collections::BTreeMap;

/// The type of a source's output, checked when the source graph is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PayloadKind {
    Height,
    Color,
    Mask,
    Features,
    Instances,
    Mesh,
}

impl PayloadKind {
    pub fn name(self) -> &'static str {
        match self {
            Self::Height => "height",
            Self::Color => "color",
            Self::Mask => "mask",
            Self::Features => "features",
            Self::Instances => "instances",
            Self::Mesh => "mesh",
        }
    }
}

impl std::fmt::Display for PayloadKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Heights in metres on the corner-aligned lattice, row-major from the
/// north-west sample. NaN marks nodata.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeightTile {
    pub size: usize,
    pub heights: Vec<f32>,
}

impl HeightTile {
    /// The height of sample (i, j), `i` growing east and `j` south.
    pub fn get(&self, i: usize, j: usize) -> f32 {
        self.heights[j * self.size + i]
    }
}

/// RGBA8 texels (not premultiplied) on the texel-centred lattice, border included.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColorTile {
    pub size: usize,
    pub rgba: Vec<u8>,
}

/// One byte per texel (0 = outside, 255 = inside), border included.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MaskTile {
    pub size: usize,
    pub coverage: Vec<u8>,
}

/// Geometry in the grid's CRS: x, y and z (NaN when the source has none).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Geometry {
    Points(Vec<[f64; 3]>),
    Lines(Vec<Vec<[f64; 3]>>),
    /// Polygons, each its exterior ring first, then its holes.
    Polygons(Vec<Vec<Vec<[f64; 3]>>>),
}

impl Geometry {
    /// The bounding box of each part (point, line or polygon), so a
    /// feature split at the antimeridian is not one box round the planet.
    pub fn part_extents(&self) -> Vec<crate::Extent> {
        fn bbox<'a>(points: impl Iterator<Item = &'a [f64; 3]>) -> Option<crate::Extent> {
            points.filter(|p| p[0].is_finite() && p[1].is_finite()).fold(None, |e: Option<crate::Extent>, p| {
                let point = crate::Extent::new(p[0], p[1], p[0], p[1]);
                Some(e.map_or(point, |e| e.union(&point)))
            })
        }
        match self {
            Self::Points(ps) => ps.iter().filter_map(|p| bbox(std::iter::once(p))).collect(),
            Self::Lines(ls) => ls.iter().filter_map(|l| bbox(l.iter())).collect(),
            Self::Polygons(polys) => polys.iter().filter_map(|rings| bbox(rings.iter().take(1).flatten())).collect(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Feature {
    pub id: u64,
    pub geometry: Geometry,
    pub properties: BTreeMap<String, String>,
}

#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct FeatureTile {
    pub features: Vec<Feature>,
}

/// A feature an op left out of its tile, and why (a bad attribute value,
/// a degenerate footprint): the tile says so instead of failing whole.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Skipped {
    pub feature_id: u64,
    pub reason: String,
}

/// What an instance places: a 3D model or a camera-facing billboard.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum InstanceKind {
    Model,
    Billboard,
}

/// A placed model or billboard. Position in the grid's CRS, height in
/// metres; rotation clockwise from north about the vertical.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Instance {
    pub feature_id: u64,
    pub position: [f64; 3],
    pub kind: InstanceKind,
    pub model: String,
    pub scale: f64,
    pub rotation_deg: f64,
}

#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct InstanceTile {
    pub instances: Vec<Instance>,
    pub skipped: Vec<Skipped>,
}

/// The triangles of one feature in a mesh tile: `index_count` indices from
/// `first_index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MeshPart {
    pub feature_id: u64,
    pub first_index: u32,
    pub index_count: u32,
    /// The feature's colour, straight RGBA8.
    pub color: [u8; 4],
    /// True: heights are relative, and the renderer sets the feature's
    /// lowest vertex on the terrain as it draws it (extruded buildings,
    /// MultiPatch with `z = "relative"`); false: heights as written.
    pub on_ground: bool,
}

/// Triangle meshes (extruded buildings, MultiPatch surfaces). Positions are grid-CRS x and y
/// with the height in metres, kept in f64: a renderer subtracts its eye
/// position before going to f32. Triangles wind counter-clockwise seen
/// from outside.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct MeshTile {
    pub positions: Vec<[f64; 3]>,
    pub indices: Vec<u32>,
    pub parts: Vec<MeshPart>,
    pub skipped: Vec<Skipped>,
}

/// What a source generated for one tile.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Payload {
    Height(HeightTile),
    Color(ColorTile),
    Mask(MaskTile),
    Features(FeatureTile),
    Instances(InstanceTile),
    Mesh(MeshTile),
}

impl Payload {
    pub fn kind(&self) -> PayloadKind {
        match self {
            Self::Height(_) => PayloadKind::Height,
            Self::Color(_) => PayloadKind::Color,
            Self::Mask(_) => PayloadKind::Mask,
            Self::Features(_) => PayloadKind::Features,
            Self::Instances(_) => PayloadKind::Instances,
            Self::Mesh(_) => PayloadKind::Mesh,
        }
    }

    /// Approximate memory held, for the cache's budget.
    pub fn size_bytes(&self) -> usize {
        match self {
            Self::Height(t) => t.heights.len() * 4,
            Self::Color(t) => t.rgba.len(),
            Self::Mask(t) => t.coverage.len(),
            Self::Features(t) => t.features.len() * 128,
            // Each instance and its model's name (a scattered forest tile
            // holds tens of thousands).
            Self::Instances(t) => t.instances.iter().map(|i| size_of::<Instance>() + i.model.capacity()).sum(),
            Self::Mesh(t) => t.positions.len() * 24 + t.indices.len() * 4 + t.parts.len() * 16,
        }
    }

    /// A hash of the payload's content, stable across runs and machines: a
    /// rebuilt tile with the same hash stops dirt from propagating.
    pub fn content_hash(&self) -> u64 {
        use xxhash_rust::xxh3::Xxh3;
        let mut h = Xxh3::new();
        h.update(self.kind().name().as_bytes());
        match self {
            Self::Height(t) => {
                // All NaNs hash alike; one update for the whole tile.
                let canonical: Vec<u8> =
                    t.heights.iter().flat_map(|v| if v.is_nan() { f32::NAN } else { *v }.to_le_bytes()).collect();
                h.update(&canonical);
            }
            Self::Color(t) => h.update(&t.rgba),
            Self::Mask(t) => h.update(&t.coverage),
            Self::Features(t) => {
                let mut b = Bytes::default();
                b.len(t.features.len());
                for f in &t.features {
                    b.u64(f.id);
                    let (tag, parts): (u8, Vec<&[[f64; 3]]>) = match &f.geometry {
                        Geometry::Points(p) => (0, vec![p.as_slice()]),
                        Geometry::Lines(ls) => (1, ls.iter().map(Vec::as_slice).collect()),
                        Geometry::Polygons(ps) => {
                            b.len(ps.len());
                            for rings in ps {
                                b.len(rings.len());
                            }
                            (2, ps.iter().flatten().map(Vec::as_slice).collect())
                        }
                    };
                    b.0.push(tag);
                    b.len(parts.len());
                    for part in parts {
                        b.len(part.len());
                        part.iter().flatten().for_each(|v| b.f64(*v));
                    }
                    b.len(f.properties.len());
                    for (k, v) in &f.properties {
                        b.text(k);
                        b.text(v);
                    }
                }
                h.update(&b.0);
            }
            Self::Instances(t) => {
                let mut b = Bytes::default();
                b.len(t.instances.len());
                for i in &t.instances {
                    b.u64(i.feature_id);
                    i.position.iter().for_each(|v| b.f64(*v));
                    b.0.push(u8::from(i.kind == InstanceKind::Model));
                    b.text(&i.model);
                    b.f64(i.scale);
                    b.f64(i.rotation_deg);
                }
                b.skipped(&t.skipped);
                h.update(&b.0);
            }
            Self::Mesh(t) => {
                let positions: Vec<u8> = t.positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
                h.update(&positions);
                let indices: Vec<u8> = t.indices.iter().flat_map(|v| v.to_le_bytes()).collect();
                h.update(&indices);
                let mut b = Bytes::default();
                b.len(t.parts.len());
                for p in &t.parts {
                    b.u64(p.feature_id);
                    b.u64(u64::from(p.first_index));
                    b.u64(u64::from(p.index_count));
                    b.0.extend(p.color);
                    b.0.push(u8::from(p.on_ground));
                }
                b.skipped(&t.skipped);
                h.update(&b.0);
            }
        }
        h.digest()
    }
}

/// A payload's values in one fixed byte layout for its content hash:
/// little-endian, every list's length before it, all NaNs alike.
#[derive(Default)]
struct Bytes(Vec<u8>);

impl Bytes {
    fn u64(&mut self, v: u64) {
        self.0.extend(v.to_le_bytes());
    }

    fn len(&mut self, n: usize) {
        self.u64(n as u64);
    }

    fn f64(&mut self, v: f64) {
        self.0.extend(if v.is_nan() { f64::NAN } else { v }.to_le_bytes());
    }

    fn text(&mut self, s: &str) {
        self.len(s.len());
        self.0.extend(s.as_bytes());
    }

    fn skipped(&mut self, list: &[Skipped]) {
        self.len(list.len());
        for s in list {
            self.u64(s.feature_id);
            self.text(&s.reason);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_hash_ignores_nan_payload_bits_and_sees_values() {
        let a = Payload::Height(HeightTile { size: 2, heights: vec![1.0, f32::NAN, 3.0, 4.0] });
        let b = Payload::Height(HeightTile { size: 2, heights: vec![1.0, f32::from_bits(0x7fc0_0001), 3.0, 4.0] });
        let c = Payload::Height(HeightTile { size: 2, heights: vec![1.0, f32::NAN, 3.0, 4.5] });
        assert_eq!(a.content_hash(), b.content_hash());
        assert_ne!(a.content_hash(), c.content_hash());
    }

    #[test]
    fn feature_hashes_see_every_value_and_no_layout_accident() {
        let feature = |id: u64, geometry: Geometry, name: &str| Feature {
            id,
            geometry,
            properties: [("name".to_owned(), name.to_owned())].into(),
        };
        let tile = |features: Vec<Feature>| Payload::Features(FeatureTile { features });
        let square = vec![vec![[0.0, 0.0, f64::NAN], [1.0, 0.0, f64::NAN], [1.0, 1.0, f64::NAN], [0.0, 0.0, f64::NAN]]];
        let base = tile(vec![feature(1, Geometry::Polygons(vec![square.clone()]), "a")]);
        assert_eq!(base.content_hash(), base.clone().content_hash(), "stable");
        let mut other_nan = square.clone();
        other_nan[0][0][2] = f64::from_bits(0x7ff8_0000_0000_0001);
        assert_eq!(
            base.content_hash(),
            tile(vec![feature(1, Geometry::Polygons(vec![other_nan]), "a")]).content_hash()
        );
        let mut moved = square.clone();
        moved[0][1][0] = 1.000_000_1;
        for changed in [
            tile(vec![feature(2, Geometry::Polygons(vec![square.clone()]), "a")]),
            tile(vec![feature(1, Geometry::Polygons(vec![moved]), "a")]),
            tile(vec![feature(1, Geometry::Polygons(vec![square.clone()]), "b")]),
            tile(vec![feature(1, Geometry::Lines(square.clone()), "a")]),
            // The same vertices as two rings of one polygon, not one ring each of two.
            tile(vec![feature(1, Geometry::Polygons(vec![vec![square[0].clone(), square[0].clone()]]), "a")]),
            tile(vec![feature(1, Geometry::Polygons(vec![square.clone(), square.clone()]), "a")]),
        ] {
            assert_ne!(changed.content_hash(), base.content_hash(), "{changed:?}");
        }
        let two_rings =
            tile(vec![feature(1, Geometry::Polygons(vec![vec![square[0].clone(), square[0].clone()]]), "a")]);
        let two_polygons = tile(vec![feature(1, Geometry::Polygons(vec![square.clone(), square]), "a")]);
        assert_ne!(two_rings.content_hash(), two_polygons.content_hash());
    }
}
