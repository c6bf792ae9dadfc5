//! Fetching a tile over gRPC and reading its payload, one way for every test.

use relief_proto::v1 as pb;
use relief_proto::v1::tile_service_client::TileServiceClient;
use tonic::transport::Channel;

/// GetTile for `source` at (level, x, y), with the scene's quality.
pub async fn get(
    channel: Channel,
    source: &str,
    (level, x, y): (u32, u32, u32),
) -> anyhow::Result<pb::GetTileResponse> {
    Ok(TileServiceClient::new(channel)
        .get_tile(pb::GetTileRequest {
            source_id: source.into(),
            key: Some(pb::TileKey { level, x, y }),
            quality: None,
        })
        .await?
        .into_inner())
}

/// A height tile's samples. Panics on another payload: a test failure.
pub fn heights(tile: &pb::GetTileResponse) -> Vec<f32> {
    match &tile.payload {
        Some(pb::get_tile_response::Payload::HeightsF32Le(b)) => {
            b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
        }
        other => panic!("expected heights, got {other:?}"),
    }
}

/// A colour tile's texels.
pub fn image(tile: &pb::GetTileResponse) -> image::RgbaImage {
    match &tile.payload {
        Some(pb::get_tile_response::Payload::ColorPng(png)) => {
            image::load_from_memory(png).expect("reliefd sends valid PNGs").to_rgba8()
        }
        other => panic!("expected a PNG, got {other:?}"),
    }
}

/// A feature tile's GeoJSON.
pub fn geojson(tile: &pb::GetTileResponse) -> serde_json::Value {
    match &tile.payload {
        Some(pb::get_tile_response::Payload::FeaturesGeojson(json)) => {
            serde_json::from_slice(json).expect("reliefd sends valid GeoJSON")
        }
        other => panic!("expected features, got {other:?}"),
    }
}

/// A mesh tile: positions (grid x, y, height m), triangle indices, and the
/// message itself for its parts and skipped features.
pub fn mesh(tile: &pb::GetTileResponse) -> (Vec<[f64; 3]>, Vec<u32>, &pb::Mesh) {
    match &tile.payload {
        Some(pb::get_tile_response::Payload::Mesh(m)) => {
            let values: Vec<f64> = m
                .positions_f64_le
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect();
            let positions = values.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
            let indices =
                m.indices_u32_le.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes"))).collect();
            (positions, indices, m)
        }
        other => panic!("expected a mesh, got {other:?}"),
    }
}

/// An instance tile.
pub fn instances(tile: &pb::GetTileResponse) -> &pb::InstanceList {
    match &tile.payload {
        Some(pb::get_tile_response::Payload::Instances(list)) => list,
        other => panic!("expected instances, got {other:?}"),
    }
}
