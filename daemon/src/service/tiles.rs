//! The tile calls: tiles of any source, and elevations at points.

use std::sync::Arc;

use relief_proto::v1::{
    ElevationSample, GetTileRequest, GetTileResponse, SampleElevationRequest, SampleElevationResponse,
    get_tile_response,
};
use relief_source::{GeodeticPoint, Payload};
use tonic::Status;

use crate::scene::Scene;
use crate::service::convert;
use crate::service::status::{from_tile_error, invalid_field};

/// Most points one SampleElevation call may ask for.
const MAX_POINTS: usize = 1_000_000;

pub struct TileCalls {
    scene: Arc<Scene>,
}

impl TileCalls {
    pub fn new(scene: Arc<Scene>) -> Self {
        Self { scene }
    }

    pub async fn tile(&self, r: GetTileRequest) -> Result<GetTileResponse, Status> {
        let key = convert::tile_key(r.key.as_ref())?;
        let snap = self.scene.snapshot();
        let index = snap.index_of(&r.source_id).ok_or_else(|| {
            Status::not_found(format!("no source has id '{}'", relief_source::echo::echoed(&r.source_id)))
        })?;
        let quality = convert::quality(snap.manifest.quality, r.quality.as_ref())?;
        let store = Arc::clone(&self.scene.store);
        let job_snap = Arc::clone(&snap);
        let tile = self
            .scene
            .store
            .run(move || store.tile(&job_snap, index, key, &quality))
            .await
            .map_err(|e| from_tile_error(&e))?
            .map_err(|e| from_tile_error(&e))?;
        let (size, payload) = match tile.payload.as_ref() {
            Payload::Height(h) => (
                h.size,
                get_tile_response::Payload::HeightsF32Le(h.heights.iter().flat_map(|v| v.to_le_bytes()).collect()),
            ),
            Payload::Color(c) => {
                (c.size, get_tile_response::Payload::ColorPng(convert::png(&c.rgba, c.size as u32, c.size as u32)?))
            }
            Payload::Mask(m) => (m.size, get_tile_response::Payload::MaskU8(m.coverage.clone())),
            Payload::Features(f) => {
                (f.features.len(), get_tile_response::Payload::FeaturesGeojson(convert::geojson(f)))
            }
            Payload::Mesh(m) => (m.parts.len(), get_tile_response::Payload::Mesh(convert::mesh(m))),
            Payload::Instances(i) => (i.instances.len(), get_tile_response::Payload::Instances(convert::instances(i))),
        };
        Ok(GetTileResponse {
            source_id: r.source_id,
            key: Some(convert::key(key)),
            generation: snap.generation,
            content_hash: tile.content_hash,
            kind: convert::payload_kind(tile.payload.kind()) as i32,
            width: size as u32,
            height: size as u32,
            extent: Some(convert::extent(snap.grid.tile_extent(key))),
            crs: snap.grid.crs().into(),
            payload: Some(payload),
        })
    }

    pub async fn elevation(&self, r: SampleElevationRequest) -> Result<SampleElevationResponse, Status> {
        if r.points.len() > MAX_POINTS {
            return Err(invalid_field(
                "points",
                format!("{} points is more than the limit of {MAX_POINTS}", r.points.len()),
            ));
        }
        let points = r
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                if p.lon_deg.is_finite() && p.lat_deg.is_finite() && (-90.0..=90.0).contains(&p.lat_deg) {
                    Ok(GeodeticPoint { lon_deg: p.lon_deg, lat_deg: p.lat_deg })
                } else {
                    Err(invalid_field(
                        &format!("points[{i}]"),
                        format!("({}, {}) is not a longitude, latitude in degrees", p.lon_deg, p.lat_deg),
                    ))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let snap = self.scene.snapshot();
        let id = if r.source_id.is_empty() {
            snap.manifest
                .layers
                .get("height")
                .cloned()
                .ok_or_else(|| Status::failed_precondition("the scene has no height layer; name a source_id"))?
        } else {
            r.source_id
        };
        let index = snap
            .index_of(&id)
            .ok_or_else(|| Status::not_found(format!("no source has id '{}'", relief_source::echo::echoed(&id))))?;
        let Some(source) = snap.slots[index].source.clone() else {
            return Err(Status::failed_precondition(format!(
                "source '{id}' has no data to serve: {}",
                snap.slots[index].error.clone().unwrap_or_default()
            )));
        };
        let quality = snap.manifest.quality;
        let heights = self
            .scene
            .store
            .run(move || source.sample_heights(&points, &quality))
            .await
            .map_err(|e| from_tile_error(&e))?
            .map_err(|e| match e {
                relief_source::SourceError::Unsupported(what) => {
                    Status::failed_precondition(format!("source '{id}': {what} is not supported"))
                }
                other => Status::internal(format!("source '{id}': {other}")),
            })?;
        Ok(SampleElevationResponse {
            generation: snap.generation,
            source_id: id,
            samples: heights.into_iter().map(|height_m| ElevationSample { height_m }).collect(),
        })
    }
}
