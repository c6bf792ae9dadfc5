use relief_source::{HeightTile, TileGrid, TileKey};

use crate::{EdgeVertices, EncodeOptions, Rtin, StandardTileError, encode_quantized_mesh, gzip};

/// What one tile costs and how true it is at one knob.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshStats {
    pub triangles: usize,
    pub vertices: usize,
    /// The quantized-mesh tile with `octvertexnormals`, uncompressed.
    pub bytes: usize,
    pub gzip_bytes: usize,
    /// The largest vertical distance from any (filled) sample to the mesh,
    /// before quantization (which adds up to (max - min) / 65534).
    pub max_error_m: f64,
}

/// Meshes and encodes one tile at `terrain_mesh_error_m`, for benches and
/// `make accuracy`.
pub fn mesh_stats(
    tile: &HeightTile,
    grid: &TileGrid,
    key: TileKey,
    terrain_mesh_error_m: f64,
    edges: EdgeVertices,
) -> Result<MeshStats, StandardTileError> {
    let rtin = Rtin::with_edges(tile, edges)?;
    let mesh = rtin.mesh(terrain_mesh_error_m);
    let bytes = encode_quantized_mesh(&mesh, grid, key, EncodeOptions { octvertexnormals: true, watermask: None })?;
    Ok(MeshStats {
        triangles: mesh.triangles.len(),
        vertices: mesh.vertices.len(),
        bytes: bytes.len(),
        gzip_bytes: gzip(&bytes).len(),
        max_error_m: mesh.max_error_m(rtin.heights()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_count_what_the_mesh_and_the_encoder_made() {
        let grid = TileGrid::geodetic(32).unwrap();
        let key = TileKey::new(5, 7, 9);
        let size = 33;
        let heights = (0..size * size).map(|k| ((k % size) as f32 * 0.4).sin() * 30.0 + (k / size) as f32).collect();
        let tile = HeightTile { size, heights };
        let loose = mesh_stats(&tile, &grid, key, 20.0, EdgeVertices::AsNeeded).unwrap();
        let strict = mesh_stats(&tile, &grid, key, 0.5, EdgeVertices::AsNeeded).unwrap();
        let sealed = mesh_stats(&tile, &grid, key, 20.0, EdgeVertices::EverySample).unwrap();
        assert!(loose.max_error_m <= 20.0 && strict.max_error_m <= 0.5);
        assert!(loose.triangles <= strict.triangles && loose.bytes <= strict.bytes);
        assert!(sealed.triangles >= loose.triangles);
        // 88 header + 4 + 6 per vertex + 4 + 6 per triangle + edges + normals.
        assert!(strict.bytes > 88 + 8 + 8 * strict.vertices + 6 * strict.triangles);
        assert!(strict.gzip_bytes < strict.bytes);
    }
}
