//! Edits the way GIS tools make them: GDAL updating a window in place,
//! a rename into place, a slow writer, helpers to follow the scene.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use gdal::raster::Buffer;
use gdal::{Dataset, DatasetOptions, GdalOpenFlags};
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use tokio_stream::StreamExt;
use tonic::transport::Channel;

/// Rewrites pixels [x, x+w) x [y, y+h) of band 1 through GDAL in update
/// mode (as QGIS' raster calculator or a GDAL script would), then closes.
pub fn rewrite_window(
    path: &Path,
    x: usize,
    y: usize,
    w: usize,
    h: usize,
    value: impl Fn(usize, usize, f32) -> f32,
) -> anyhow::Result<()> {
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_UPDATE | GdalOpenFlags::GDAL_OF_RASTER,
        ..DatasetOptions::default()
    };
    let ds = Dataset::open_ex(path, options).with_context(|| format!("cannot open {} for update", path.display()))?;
    let mut band = ds.rasterband(1)?;
    let old = band.read_as::<f32>((x as isize, y as isize), (w, h), (w, h), None)?.into_shape_and_vec().1;
    let new: Vec<f32> =
        (0..h).flat_map(|j| (0..w).map(move |i| (i, j))).map(|(i, j)| value(x + i, y + j, old[j * w + i])).collect();
    band.write((x as isize, y as isize), (w, h), &mut Buffer::new((w, h), new))?;
    ds.close()?;
    Ok(())
}

/// Every event of a Watch stream, collected in the background.
#[derive(Clone, Default)]
pub struct Events(Arc<Mutex<Vec<pb::SceneEvent>>>);

impl Events {
    pub async fn follow(channel: Channel) -> anyhow::Result<Self> {
        let mut stream =
            SceneServiceClient::new(channel).watch(pb::WatchRequest { from_generation: 0 }).await?.into_inner();
        let events = Self::default();
        let sink = events.clone();
        // The first message is the snapshot: take it before returning, so
        // nothing that follows is missed.
        if let Some(first) = stream.next().await {
            sink.0.lock().expect("events lock").push(first?);
        }
        tokio::spawn(async move {
            while let Some(Ok(e)) = stream.next().await {
                sink.0.lock().expect("events lock").push(e);
            }
        });
        Ok(events)
    }

    pub fn all(&self) -> Vec<pb::SceneEvent> {
        self.0.lock().expect("events lock").clone()
    }

    pub fn generations(&self) -> Vec<(u64, pb::GenerationEvent)> {
        self.all()
            .into_iter()
            .filter_map(|e| match e.event {
                Some(pb::scene_event::Event::GenerationChanged(g)) => Some((e.generation, g)),
                _ => None,
            })
            .collect()
    }

    pub fn errors(&self) -> Vec<pb::SourceErrorEvent> {
        self.all()
            .into_iter()
            .filter_map(|e| match e.event {
                Some(pb::scene_event::Event::SourceError(s)) => Some(s),
                _ => None,
            })
            .collect()
    }

    /// Waits until a generation event for `generation` has arrived.
    pub async fn generation(&self, generation: u64) -> anyhow::Result<pb::GenerationEvent> {
        for _ in 0..400 {
            if let Some((_, g)) = self.generations().into_iter().find(|(n, _)| *n == generation) {
                return Ok(g);
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        anyhow::bail!("no event for generation {generation}: {:#?}", self.all())
    }
}

/// WaitForGeneration, up to 20 s.
pub async fn wait_for(channel: Channel, generation: u64) -> anyhow::Result<pb::SceneState> {
    Ok(SceneServiceClient::new(channel)
        .wait_for_generation(pb::WaitForGenerationRequest { min_generation: generation, timeout_ms: 20_000 })
        .await?
        .into_inner())
}

/// The content hash of a tile.
pub async fn tile_hash(channel: Channel, source: &str, key: (u32, u32, u32)) -> anyhow::Result<u64> {
    Ok(crate::tiles::get(channel, source, key).await?.content_hash)
}

/// One height from the scene's height layer.
pub async fn height_at(channel: Channel, lon: f64, lat: f64) -> anyhow::Result<Option<f64>> {
    Ok(TileServiceClient::new(channel)
        .sample_elevation(pb::SampleElevationRequest {
            points: vec![pb::GeodeticPoint { lon_deg: lon, lat_deg: lat }],
            source_id: String::new(),
        })
        .await?
        .into_inner()
        .samples[0]
        .height_m)
}

/// Polls GetState until source `id` has `status`, up to 20 s; the state then.
pub async fn wait_for_status(
    scene: &mut SceneServiceClient<Channel>,
    id: &str,
    status: pb::SourceStatus,
) -> anyhow::Result<pb::SceneState> {
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    loop {
        let state = scene.get_state(pb::GetStateRequest {}).await?.into_inner();
        if state.sources.iter().any(|s| s.id == id && s.status == status as i32) {
            return Ok(state);
        }
        anyhow::ensure!(std::time::Instant::now() < deadline, "source '{id}' never became {status:?}: {state:#?}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// The version of source `id` in `state` (0 when there is no such source).
pub fn version(state: &pb::SceneState, id: &str) -> u64 {
    state.sources.iter().find(|s| s.id == id).map_or(0, |s| s.version)
}

/// Moves every polygon of `layer` in the GeoPackage at `path` by (dx, dy)
/// in one transaction, as a GIS commits an edit of a whole layer (QGIS'
/// "move features" on a selection of all); returns how many it moved.
pub fn move_every_polygon(path: &Path, layer: &str, (dx, dy): (f64, f64)) -> anyhow::Result<usize> {
    use gdal::vector::{Geometry, LayerAccess};
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_UPDATE | GdalOpenFlags::GDAL_OF_VECTOR,
        ..DatasetOptions::default()
    };
    let mut ds =
        Dataset::open_ex(path, options).with_context(|| format!("cannot open {} for update", path.display()))?;
    let txn = ds.start_transaction()?;
    let moved = {
        let mut lyr = txn.layer_by_name(layer)?;
        let fids: Vec<u64> = lyr.features().filter_map(|f| f.fid()).collect();
        for &fid in &fids {
            let mut feature = lyr.feature(fid).with_context(|| format!("feature {fid} is gone"))?;
            let Some(geometry) = feature.geometry() else { continue };
            let rings: Vec<String> = (0..geometry.geometry_count())
                .map(|r| {
                    let ring = geometry.get_geometry(r);
                    let points: Vec<String> = (0..ring.point_count())
                        .map(|i| {
                            let (x, y, _) = ring.get_point(i as i32);
                            format!("{} {}", x + dx, y + dy)
                        })
                        .collect();
                    format!("({})", points.join(","))
                })
                .collect();
            feature.set_geometry(Geometry::from_wkt(&format!("POLYGON({})", rings.join(",")))?)?;
            lyr.set_feature(feature)?;
        }
        fids.len()
    };
    txn.commit()?;
    ds.close()?;
    Ok(moved)
}
