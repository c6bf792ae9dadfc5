//! Conversions between relief's types and relief.v1 messages.

use relief_proto::v1 as pb;
use relief_renderer::InstanceBands;
use relief_source::{Extent, PayloadKind, Quality, TileGrid, TileKey};
use tonic::Status;

use crate::frames::FrameHub;
use crate::manifest::EFFECTS;
use crate::scene::{EventKind, Scene, SceneEvent};
use crate::service::status::invalid_field;
use crate::standard::StandardTiles;

pub fn extent(e: Extent) -> pb::Extent {
    pb::Extent { min_x: e.min_x, min_y: e.min_y, max_x: e.max_x, max_y: e.max_y }
}

pub fn payload_kind(kind: PayloadKind) -> pb::PayloadKind {
    match kind {
        PayloadKind::Height => pb::PayloadKind::Height,
        PayloadKind::Color => pb::PayloadKind::Color,
        PayloadKind::Mask => pb::PayloadKind::Mask,
        PayloadKind::Features => pb::PayloadKind::Features,
        PayloadKind::Instances => pb::PayloadKind::Instances,
        PayloadKind::Mesh => pb::PayloadKind::Mesh,
    }
}

pub fn tile_key(key: Option<&pb::TileKey>) -> Result<TileKey, Status> {
    let key = key.ok_or_else(|| invalid_field("key", "missing"))?;
    let level = u8::try_from(key.level).ok().filter(|l| *l <= relief_source::MAX_LEVEL).ok_or_else(|| {
        invalid_field("key.level", format!("{} is above the finest level {}", key.level, relief_source::MAX_LEVEL))
    })?;
    Ok(TileKey::new(level, key.x, key.y))
}

pub fn key(k: TileKey) -> pb::TileKey {
    pb::TileKey { level: u32::from(k.level), x: k.x, y: k.y }
}

/// The scene's quality with a request's overrides applied.
pub fn quality(base: Quality, overrides: Option<&pb::QualityOverrides>) -> Result<Quality, Status> {
    let mut q = base;
    let Some(o) = overrides else { return Ok(q) };
    if let Some(r) = &o.resampling {
        q.resampling = r.parse().map_err(|e: String| invalid_field("quality.resampling", e))?;
    }
    if let Some(e) = o.reprojection_error_px {
        if !(e.is_finite() && (0.0..=16.0).contains(&e)) {
            return Err(invalid_field("quality.reprojection_error_px", format!("{e} is not between 0 and 16")));
        }
        q.reprojection_error_px = e;
    }
    Ok(q)
}

fn join(values: &[f64]) -> String {
    values.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

/// A request's distance bands for the instances layer, when it overrides
/// any of them (the rest from the manifest's); each checked.
pub fn bands(base: InstanceBands, o: &pb::QualityOverrides) -> Result<Option<InstanceBands>, Status> {
    let three = |field: &str, values: &[f64]| -> Result<Option<[f64; 3]>, Status> {
        match values {
            [] => Ok(None),
            [a, b, c] => Ok(Some([*a, *b, *c])),
            _ => Err(invalid_field(field, format!("{} values given: give three (one per band) or none", values.len()))),
        }
    };
    let edges = three("quality.instance_bands_m", &o.instance_bands_m)?;
    let densities = three("quality.instance_band_densities", &o.instance_band_densities)?;
    if edges.is_none() && densities.is_none() && o.instance_model_distance_m.is_none() {
        return Ok(None);
    }
    let bands = InstanceBands {
        edges_m: edges.unwrap_or(base.edges_m),
        densities: densities.unwrap_or(base.densities),
        model_distance_m: o.instance_model_distance_m.unwrap_or(base.model_distance_m),
    };
    bands.validate().map_err(|(field, message)| invalid_field(&format!("quality.{field}"), message))?;
    Ok(Some(bands))
}

fn grid_info(grid: &TileGrid) -> pb::GridInfo {
    let (cols, rows) = grid.tiles_at(0);
    pb::GridInfo {
        kind: if grid.is_geodetic() { "geodetic" } else { "projected" }.into(),
        crs: grid.crs().into(),
        tile_size: grid.tile_size(),
        extent: Some(extent(grid.extent())),
        level0_columns: cols,
        level0_rows: rows,
    }
}

/// The whole state of `scene` at its current generation.
pub fn scene_state(scene: &Scene, hub: &FrameHub, standard: &StandardTiles) -> pb::SceneState {
    let snap = &*scene.snapshot();
    let store = &scene.store;
    let manifest_error = scene.manifest_error();
    let reads_retried = scene.reads_retried();
    let source_reads = scene.source_reads();
    let sources = snap
        .slots
        .iter()
        .map(|slot| {
            let info = slot.source.as_ref().map(|s| s.info()).unwrap_or_default();
            let status = match (&slot.source, &slot.error) {
                (Some(_), None) => pb::SourceStatus::Ready,
                (Some(_), Some(_)) => pb::SourceStatus::Error,
                (None, _) => pb::SourceStatus::Failed,
            };
            pb::SourceState {
                id: slot.spec.id.clone(),
                kind: slot.spec.kind.clone(),
                output: slot.source.as_ref().map_or(pb::PayloadKind::Unspecified, |s| payload_kind(s.output())) as i32,
                inputs: slot.spec.inputs.clone(),
                status: status as i32,
                error: slot.error.clone().unwrap_or_default(),
                files: if info.files.is_empty() { &slot.spec.paths } else { &info.files }
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect(),
                version: slot.version,
                active: slot.active,
                extent: info.extent.map(extent),
                crs: info.crs,
                vertical_datum: info.vertical_datum,
                vertical_units: info.vertical_units,
                tiles_generated: store.generated_for(&slot.spec.id),
                details: info
                    .details
                    .into_iter()
                    .chain(slot.content.get().map(|a| ("content_address".to_owned(), format!("{a:032x}"))))
                    .collect(),
                warnings: info.warnings,
                instance_classes: info
                    .classes
                    .iter()
                    .map(|c| pb::InstanceClass {
                        class: c.class,
                        has_rule: c.has_rule,
                        instances: c.instances,
                        samples: c.samples,
                    })
                    .collect(),
            }
        })
        .collect();
    let m = &snap.manifest;
    let picture = crate::picture::Picture::of(m);
    let ran = hub.viewer().effects_ran();
    let effects = m
        .effects
        .iter()
        .map(|name| {
            let layers = EFFECTS.iter().find(|(e, _)| e == name).map(|(_, l)| *l).unwrap_or_default();
            pb::EffectState {
                name: name.clone(),
                sources: layers.iter().filter_map(|l| m.layers.get(*l).cloned()).collect(),
                ran: ran.contains_key(name),
                last_cost_ms: ran.get(name).copied().unwrap_or(0.0),
            }
        })
        .collect();
    let c = store.counters();
    let frames = hub.counters();
    let passes = pass_states(&hub.viewer().passes());
    pb::SceneState {
        name: m.name.clone(),
        generation: snap.generation,
        grid: Some(grid_info(&snap.grid)),
        sources,
        effects,
        layers: m.layers.clone().into_iter().collect(),
        quality: [
            ("resampling".to_string(), m.quality.resampling.to_string()),
            ("reprojection_error_px".to_string(), m.quality.reprojection_error_px.to_string()),
            ("tile_size".to_string(), snap.grid.tile_size().to_string()),
            ("clipmap_grid_size".to_string(), picture.clipmap.n.to_string()),
            ("clipmap_levels".to_string(), picture.clipmap.levels.to_string()),
            ("color_detail".to_string(), picture.clipmap.color_detail.to_string()),
            ("interactive_scale".to_string(), picture.interactive_scale.to_string()),
            ("frame_jpeg_quality".to_string(), picture.frame_jpeg_quality.to_string()),
            ("instance_bands_m".to_string(), join(&picture.bands.edges_m)),
            ("instance_band_densities".to_string(), join(&picture.bands.densities)),
            ("instance_model_distance_m".to_string(), picture.bands.model_distance_m.to_string()),
            ("terrain_mesh_error_m".to_string(), picture.terrain_mesh_error_m.to_string()),
        ]
        .into_iter()
        .chain(picture.effect_settings.quality())
        .collect(),
        counters: Some(pb::Counters {
            tiles_generated: c.tiles_generated,
            cache_hits: c.hits,
            cache_misses: c.misses,
            cache_entries: c.entries,
            cache_bytes: c.bytes,
            cache_budget_bytes: c.budget_bytes,
            frames_rendered: hub.viewer().frames_rendered(),
            reads_retried,
            source_reads,
            frame_views: frames.views as u64,
            frame_streams: frames.streams as u64,
            open_views: frames.open_views as u64,
            stream_frames_rendered: frames.frames_rendered,
            outer_stores: store
                .backing_counters()
                .into_iter()
                .map(|b| pb::OuterStore { name: b.name.into(), hits: b.hits, misses: b.misses, writes: b.writes })
                .collect(),
            raster_cache_bytes: relief_source_gdal::cached_bytes(),
            raster_cache_budget_bytes: relief_source_gdal::block_budget(),
            object_bytes_read: relief_source_gdal::objects::bytes_read(),
            object_version_checks: relief_source_gdal::objects::version_checks(),
            stream_frames_carried_over: frames.frames_carried_over,
            memory: [
                ("tile cache", c.bytes),
                ("raster blocks", relief_source_gdal::cached_bytes()),
                ("standard tiles", standard.state().encoded_bytes),
            ]
            .into_iter()
            .map(|(n, b)| (n.to_owned(), b))
            .chain(hub.viewer().held_bytes().into_iter().map(|(n, b)| (format!("renderer: {n}"), b)))
            .chain(std::iter::once(("frames held for streams".to_owned(), hub.held_bytes())))
            .map(|(name, bytes)| pb::MemoryUse { name, bytes })
            .collect(),
            standard_tiles: Some(standard.state()),
            renderer_caches: Some({
                let w = hub.viewer().cache_work();
                pb::CacheWork {
                    level_samples_written: w.level_samples_written,
                    water_coverage_texels: w.water_coverage_texels,
                    shadow_maps_drawn: w.shadow_maps_drawn,
                    shadow_maps_redrawn_in_part: w.shadow_maps_redrawn_in_part,
                    shadow_maps_kept: w.shadow_maps_kept,
                    shadow_regions: w.shadow_regions,
                    shadow_texels: w.shadow_texels,
                    building_tiles_built: w.building_tiles_built,
                    instance_tiles_built: w.instance_tiles_built,
                    detail_fits: w.detail_fits,
                }
            }),
        }),
        manifest: m.path.display().to_string(),
        manifest_error: manifest_error.unwrap_or_default(),
        passes,
        parameters: scene
            .parameters()
            .into_iter()
            .map(|p| pb::Parameter {
                target: p.target,
                name: p.name,
                value: p.value,
                manifest_value: p.manifest_value,
                origin: "call".into(),
            })
            .collect(),
    }
}

pub fn scene_event(e: SceneEvent) -> pb::SceneEvent {
    let event = match e.kind {
        EventKind::Generation { changed_sources, dirty, stats, elapsed_ms, reason } => {
            pb::scene_event::Event::GenerationChanged(pb::GenerationEvent {
                changed_sources,
                dirty: dirty
                    .into_iter()
                    .map(|d| pb::DirtyRegion {
                        source_id: d.source_id,
                        extents: d.extents.into_iter().map(extent).collect(),
                    })
                    .collect(),
                tiles_rebuilt: stats.rebuilt,
                tiles_invalidated: stats.invalidated,
                tiles_carried_over: stats.carried,
                tiles_cut_off: stats.cut_off,
                elapsed_ms,
                reason,
            })
        }
        EventKind::ManifestError { error } => pb::scene_event::Event::ManifestError(pb::ManifestErrorEvent { error }),
        EventKind::SourceError { source_id, error, kept_last_good } => {
            pb::scene_event::Event::SourceError(pb::SourceErrorEvent { source_id, error, kept_last_good })
        }
    };
    pb::SceneEvent { generation: e.generation, event: Some(event) }
}

/// A feature tile as a GeoJSON FeatureCollection (coordinates in the grid's
/// CRS; z where the source has it).
pub fn geojson(tile: &relief_source::FeatureTile) -> Vec<u8> {
    use relief_source::Geometry;
    use serde_json::{Value, json};
    let position = |p: &[f64; 3]| if p[2].is_nan() { json!([p[0], p[1]]) } else { json!([p[0], p[1], p[2]]) };
    let line = |l: &Vec<[f64; 3]>| Value::Array(l.iter().map(position).collect());
    let features: Vec<Value> = tile
        .features
        .iter()
        .map(|f| {
            let geometry = match &f.geometry {
                Geometry::Points(ps) if ps.len() == 1 => json!({"type": "Point", "coordinates": position(&ps[0])}),
                Geometry::Points(ps) => json!({"type": "MultiPoint", "coordinates": ps.iter().map(position).collect::<Vec<_>>()}),
                Geometry::Lines(ls) => json!({"type": "MultiLineString", "coordinates": ls.iter().map(line).collect::<Vec<_>>()}),
                Geometry::Polygons(polys) => json!({
                    "type": "MultiPolygon",
                    "coordinates": polys.iter().map(|rings| rings.iter().map(line).collect::<Vec<_>>()).collect::<Vec<_>>(),
                }),
            };
            json!({"type": "Feature", "id": f.id, "geometry": geometry, "properties": f.properties})
        })
        .collect();
    serde_json::to_vec(&json!({"type": "FeatureCollection", "features": features})).unwrap_or_default()
}

fn skipped(list: &[relief_source::Skipped]) -> Vec<pb::SkippedFeature> {
    list.iter().map(|s| pb::SkippedFeature { feature_id: s.feature_id, reason: s.reason.clone() }).collect()
}

pub fn mesh(m: &relief_source::MeshTile) -> pb::Mesh {
    pb::Mesh {
        positions_f64_le: m.positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
        indices_u32_le: m.indices.iter().flat_map(|v| v.to_le_bytes()).collect(),
        parts: m
            .parts
            .iter()
            .map(|p| pb::MeshPart {
                feature_id: p.feature_id,
                first_index: p.first_index,
                index_count: p.index_count,
                rgba: u32::from_be_bytes(p.color),
                on_ground: p.on_ground,
            })
            .collect(),
        skipped: skipped(&m.skipped),
    }
}

pub fn instances(t: &relief_source::InstanceTile) -> pb::InstanceList {
    let instances = t
        .instances
        .iter()
        .map(|i| pb::Instance {
            feature_id: i.feature_id,
            x: i.position[0],
            y: i.position[1],
            z: i.position[2],
            kind: match i.kind {
                relief_source::InstanceKind::Model => pb::InstanceKind::Model,
                relief_source::InstanceKind::Billboard => pb::InstanceKind::Billboard,
            } as i32,
            model: i.model.clone(),
            scale: i.scale,
            rotation_deg: i.rotation_deg,
        })
        .collect();
    pb::InstanceList { instances, skipped: skipped(&t.skipped) }
}

pub fn camera_from(c: &pb::Camera) -> crate::view::Camera {
    crate::view::Camera {
        lon_deg: c.lon_deg,
        lat_deg: c.lat_deg,
        altitude_m: c.altitude_m,
        heading_deg: c.heading_deg,
        pitch_deg: c.pitch_deg,
        roll_deg: c.roll_deg,
        vertical_fov_deg: c.vertical_fov_deg,
    }
}

pub fn camera_to(c: &crate::view::Camera) -> pb::Camera {
    pb::Camera {
        lon_deg: c.lon_deg,
        lat_deg: c.lat_deg,
        altitude_m: c.altitude_m,
        heading_deg: c.heading_deg,
        pitch_deg: c.pitch_deg,
        roll_deg: c.roll_deg,
        vertical_fov_deg: c.vertical_fov_deg,
    }
}

/// RGBA8 rows as a PNG.
pub fn png(rgba: &[u8], width: u32, height: u32) -> Result<Vec<u8>, tonic::Status> {
    crate::codec::png(rgba, width, height).map_err(tonic::Status::internal)
}

/// The renderer's passes in relief.v1.
pub fn pass_states(passes: &[relief_renderer::PassStats]) -> Vec<pb::PassState> {
    passes
        .iter()
        .map(|p| pb::PassState { name: p.name.into(), built: p.built, runs: p.runs, total_ms: p.total_ms })
        .collect()
}
