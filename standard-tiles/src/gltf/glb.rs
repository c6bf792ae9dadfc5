//! What a tile's glTF content is handed back as.

/// One tile's content as a GLB, with what its tileset entry needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Glb {
    /// The GLB file: glTF 2.0, y-up, positions as f32 offsets from the
    /// tile's centre.
    pub bytes: Vec<u8>,
    /// The tile transform, column-major: a translation to the centre the
    /// positions are offsets from, in ECEF metres (WGS84).
    pub transform: [f64; 16],
    /// 3D Tiles' `boundingVolume.region` of what was written: west, south,
    /// east, north (radians; west east of east across the antimeridian)
    /// and the lowest and highest height above the ellipsoid (metres).
    pub region: [f64; 6],
}
