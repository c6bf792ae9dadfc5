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
#[derive(Debug, Clone, PartialEq)]
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
#[derive(Debug, Clone, PartialEq)]
pub struct ColorTile {
    pub size: usize,
    pub rgba: Vec<u8>,
}

/// One byte per texel (0 = outside, 255 = inside), border included.
#[derive(Debug, Clone, PartialEq)]
pub struct MaskTile {
    pub size: usize,
    pub coverage: Vec<u8>,
}

/// Geometry in the grid's CRS: x, y and z (NaN when the source has none).
#[derive(Debug, Clone, PartialEq)]
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

#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    pub id: u64,
    pub geometry: Geometry,
    pub properties: BTreeMap<String, String>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureTile {
    pub features: Vec<Feature>,
}

/// A feature an op left out of its tile, and why (a bad attribute value,
/// a degenerate footprint): the tile says so instead of failing whole.
#[derive(Debug, Clone, PartialEq)]
pub struct Skipped {
    pub feature_id: u64,
    pub reason: String,
}

/// What an instance places: a 3D model or a camera-facing billboard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InstanceKind {
    Model,
    Billboard,
}

/// A placed model or billboard. Position in the grid's CRS, height in
/// metres; rotation clockwise from north about the vertical.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    pub feature_id: u64,
    pub position: [f64; 3],
    pub kind: InstanceKind,
    pub model: String,
    pub scale: f64,
    pub rotation_deg: f64,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct InstanceTile {
    pub instances: Vec<Instance>,
    pub skipped: Vec<Skipped>,
}

/// The triangles of one feature in a mesh tile: `index_count` indices from
/// `first_index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshPart {
    pub feature_id: u64,
    pub first_index: u32,
    pub index_count: u32,
    /// The feature's colour, straight RGBA8.
    pub color: [u8; 4],
}

/// Triangle meshes (extruded buildings). Positions are grid-CRS x and y
/// with the height in metres, kept in f64: a renderer subtracts its eye
/// position before going to f32. Triangles wind counter-clockwise seen
/// from outside.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshTile {
    pub positions: Vec<[f64; 3]>,
    pub indices: Vec<u32>,
    pub parts: Vec<MeshPart>,
    pub skipped: Vec<Skipped>,
}

/// What a source generated for one tile.
#[derive(Debug, Clone, PartialEq)]
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
            Self::Features(t) => h.update(format!("{:?}", t.features).as_bytes()),
            Self::Instances(t) => h.update(format!("{:?}", t.instances).as_bytes()),
            Self::Mesh(t) => {
                let positions: Vec<u8> = t.positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
                h.update(&positions);
                let indices: Vec<u8> = t.indices.iter().flat_map(|v| v.to_le_bytes()).collect();
                h.update(&indices);
                h.update(format!("{:?}{:?}", t.parts, t.skipped).as_bytes());
            }
        }
        h.digest()
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
}
