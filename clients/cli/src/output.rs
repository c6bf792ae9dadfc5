//! Text for people and JSON for scripts, from the same answers.

use std::fmt::Write as _;

use relief_proto::v1 as pb;
use serde_json::{Value, json};

#[expect(clippy::print_stdout, reason = "the CLI's output")]
pub fn emit(as_json: bool, value: &Value, text: impl FnOnce() -> String) {
    if as_json {
        println!("{value}");
    } else {
        println!("{}", text());
    }
}

fn status_name(status: i32) -> &'static str {
    match pb::SourceStatus::try_from(status) {
        Ok(pb::SourceStatus::Ready) => "ready",
        Ok(pb::SourceStatus::Error) => "error",
        Ok(pb::SourceStatus::Failed) => "failed",
        _ => "unknown",
    }
}

fn payload_name(kind: i32) -> &'static str {
    match pb::PayloadKind::try_from(kind) {
        Ok(pb::PayloadKind::Height) => "height",
        Ok(pb::PayloadKind::Color) => "color",
        Ok(pb::PayloadKind::Mask) => "mask",
        Ok(pb::PayloadKind::Features) => "features",
        Ok(pb::PayloadKind::Instances) => "instances",
        Ok(pb::PayloadKind::Mesh) => "mesh",
        _ => "unknown",
    }
}

fn extent_json(e: Option<&pb::Extent>) -> Value {
    e.map_or(Value::Null, |e| json!([e.min_x, e.min_y, e.max_x, e.max_y]))
}

pub fn state_json(s: &pb::SceneState) -> Value {
    let sources: Vec<Value> = s
        .sources
        .iter()
        .map(|src| {
            json!({
                "id": src.id, "kind": src.kind, "output": payload_name(src.output), "inputs": src.inputs,
                "status": status_name(src.status), "error": (!src.error.is_empty()).then_some(&src.error),
                "files": src.files, "version": src.version, "active": src.active,
                "extent": extent_json(src.extent.as_ref()), "crs": src.crs,
                "vertical_datum": src.vertical_datum, "vertical_units": src.vertical_units,
                "tiles_generated": src.tiles_generated, "details": src.details,
                "instance_classes": src.instance_classes.iter().map(|k| json!({
                    "class": k.class, "has_rule": k.has_rule, "instances": k.instances, "samples": k.samples,
                })).collect::<Vec<Value>>(),
            })
        })
        .collect();
    let grid = s.grid.as_ref().map(|g| {
        json!({"kind": g.kind, "crs": g.crs, "tile_size": g.tile_size, "extent": extent_json(g.extent.as_ref()),
               "level0_columns": g.level0_columns, "level0_rows": g.level0_rows})
    });
    let effects: Vec<Value> = s
        .effects
        .iter()
        .map(|e| json!({"name": e.name, "sources": e.sources, "ran": e.ran, "last_cost_ms": e.last_cost_ms}))
        .collect();
    let c = s.counters.clone().unwrap_or_default();
    json!({
        "name": s.name, "generation": s.generation, "manifest": s.manifest, "grid": grid,
        "sources": sources, "layers": s.layers, "effects": effects, "quality": s.quality,
        "counters": {"tiles_generated": c.tiles_generated, "cache_hits": c.cache_hits, "cache_misses": c.cache_misses,
                     "cache_entries": c.cache_entries, "cache_bytes": c.cache_bytes, "cache_budget_bytes": c.cache_budget_bytes,
                     "reads_retried": c.reads_retried},
    })
}

pub fn state_text(s: &pb::SceneState) -> String {
    let mut out = format!("scene '{}' at generation {}\n  manifest: {}\n", s.name, s.generation, s.manifest);
    if let Some(g) = &s.grid {
        let _ = writeln!(
            out,
            "  grid: {} {} (tiles of {} samples, {}x{} at level 0)",
            g.kind, g.crs, g.tile_size, g.level0_columns, g.level0_rows
        );
    }
    out += "  sources:\n";
    for src in &s.sources {
        let _ = writeln!(
            out,
            "    {:<12} {:<10} {:<7} {:<6} v{} {}{} tiles={}",
            src.id,
            src.kind,
            payload_name(src.output),
            status_name(src.status),
            src.version,
            if src.active { "active" } else { "idle" },
            if src.crs.is_empty() { String::new() } else { format!(" crs={}", src.crs) },
            src.tiles_generated
        );
        if !src.vertical_datum.is_empty() {
            let _ = writeln!(out, "                 heights: {}, datum {}", src.vertical_units, src.vertical_datum);
        }
        if !src.error.is_empty() {
            let _ = writeln!(out, "                 error: {}", src.error);
        }
        for k in &src.instance_classes {
            let rule = if k.has_rule { String::new() } else { " (no rule)".to_owned() };
            let _ = writeln!(
                out,
                "                 class {}{rule}: {} instances over {} samples",
                k.class, k.instances, k.samples
            );
        }
    }
    let mut layers: Vec<_> = s.layers.iter().collect();
    layers.sort();
    let _ = writeln!(out, "  layers: {}", layers.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(" "));
    let effects: Vec<String> = s
        .effects
        .iter()
        .map(|e| {
            if e.ran { format!("{} (ran in the last frame, {:.1} ms)", e.name, e.last_cost_ms) } else { e.name.clone() }
        })
        .collect();
    let _ = writeln!(out, "  effects: {}", effects.join(" "));
    let mut quality: Vec<_> = s.quality.iter().collect();
    quality.sort();
    let _ =
        writeln!(out, "  quality: {}", quality.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(" "));
    if let Some(c) = &s.counters {
        let _ = write!(
            out,
            "  cache: {} tiles, {:.1} of {:.0} MiB; {} hits, {} misses; {} tiles generated",
            c.cache_entries,
            c.cache_bytes as f64 / 1_048_576.0,
            c.cache_budget_bytes as f64 / 1_048_576.0,
            c.cache_hits,
            c.cache_misses,
            c.tiles_generated
        );
    }
    out
}

pub fn event_json(e: &pb::SceneEvent) -> Value {
    match &e.event {
        Some(pb::scene_event::Event::Snapshot(s)) => {
            json!({"generation": e.generation, "snapshot": state_json(s)})
        }
        Some(pb::scene_event::Event::GenerationChanged(g)) => json!({
            "generation": e.generation, "changed_sources": g.changed_sources, "reason": g.reason,
            "dirty": g.dirty.iter().map(|d| json!({"source": d.source_id, "extents": d.extents.iter().map(|x| extent_json(Some(x))).collect::<Vec<_>>()})).collect::<Vec<_>>(),
            "tiles_rebuilt": g.tiles_rebuilt, "tiles_invalidated": g.tiles_invalidated,
            "tiles_carried_over": g.tiles_carried_over, "tiles_cut_off": g.tiles_cut_off, "elapsed_ms": g.elapsed_ms,
        }),
        Some(pb::scene_event::Event::SourceError(err)) => json!({
            "generation": e.generation, "source_error": {"source": err.source_id, "error": err.error, "kept_last_good": err.kept_last_good},
        }),
        Some(pb::scene_event::Event::ManifestError(m)) => {
            json!({"generation": e.generation, "manifest_error": m.error})
        }
        None => json!({"generation": e.generation}),
    }
}

pub fn event_text(e: &pb::SceneEvent) -> String {
    match &e.event {
        Some(pb::scene_event::Event::Snapshot(s)) => {
            format!("[{}] {}", e.generation, state_text(s))
        }
        Some(pb::scene_event::Event::GenerationChanged(g)) => format!(
            "[{}] {}: changed {} ({} dirty regions; tiles: {} rebuilt, {} kept, {} cut off) in {:.1} ms",
            e.generation,
            g.reason,
            g.changed_sources.join(", "),
            g.dirty.iter().map(|d| d.extents.len()).sum::<usize>(),
            g.tiles_rebuilt,
            g.tiles_carried_over,
            g.tiles_cut_off,
            g.elapsed_ms
        ),
        Some(pb::scene_event::Event::SourceError(err)) => format!(
            "[{}] error on source '{}': {}{}",
            e.generation,
            err.source_id,
            err.error,
            if err.kept_last_good { " (last good version kept)" } else { "" }
        ),
        Some(pb::scene_event::Event::ManifestError(m)) => {
            format!("[{}] manifest edit not taken (the scene stays as it was): {}", e.generation, m.error)
        }
        None => format!("[{}]", e.generation),
    }
}

/// Instances as a GeoJSON FeatureCollection of points in the grid's CRS.
pub fn instances_geojson(list: &pb::InstanceList) -> Value {
    let kind = |k: i32| match pb::InstanceKind::try_from(k) {
        Ok(pb::InstanceKind::Billboard) => "billboard",
        _ => "model",
    };
    let features: Vec<Value> = list
        .instances
        .iter()
        .map(|i| {
            json!({"type": "Feature", "id": i.feature_id,
                   "geometry": {"type": "Point", "coordinates": [i.x, i.y, i.z]},
                   "properties": {"kind": kind(i.kind), "model": i.model, "scale": i.scale, "rotation_deg": i.rotation_deg}})
        })
        .collect();
    let skipped: Vec<Value> =
        list.skipped.iter().map(|s| json!({"feature_id": s.feature_id, "reason": s.reason})).collect();
    json!({"type": "FeatureCollection", "features": features, "skipped": skipped})
}

pub fn camera_json(c: &pb::Camera) -> Value {
    json!({"lon_deg": c.lon_deg, "lat_deg": c.lat_deg, "altitude_m": c.altitude_m, "heading_deg": c.heading_deg,
           "pitch_deg": c.pitch_deg, "roll_deg": c.roll_deg, "vertical_fov_deg": c.vertical_fov_deg})
}

pub fn camera_text(c: &pb::Camera) -> String {
    format!(
        "{},{},{},{},{},{} (lon, lat, altitude m, heading, pitch, roll), fov {} deg",
        c.lon_deg, c.lat_deg, c.altitude_m, c.heading_deg, c.pitch_deg, c.roll_deg, c.vertical_fov_deg
    )
}

pub fn frame_json(f: &pb::RenderResponse, path: &std::path::Path) -> Value {
    let passes: serde_json::Map<String, Value> =
        f.passes.iter().map(|p| (p.pass.clone(), json!(p.elapsed_ms))).collect();
    json!({"path": path.display().to_string(), "generation": f.generation, "width": f.width, "height": f.height,
           "passes_ms": passes, "camera": f.camera.as_ref().map(camera_json),
           "sun": f.sun.as_ref().map(|s| json!({"azimuth_deg": s.azimuth_deg, "elevation_deg": s.elevation_deg,
                                                 "source": s.source}))})
}

pub fn frame_text(f: &pb::RenderResponse, path: &std::path::Path) -> String {
    let passes: Vec<String> = f.passes.iter().map(|p| format!("{} {:.1} ms", p.pass, p.elapsed_ms)).collect();
    let sun = f.sun.as_ref().map_or_else(String::new, |s| {
        format!("; sun at azimuth {:.2}, elevation {:.2} deg ({})", s.azimuth_deg, s.elevation_deg, s.source)
    });
    format!(
        "wrote {}x{} view of generation {} to {} ({}){sun}",
        f.width,
        f.height,
        f.generation,
        path.display(),
        passes.join(", ")
    )
}
