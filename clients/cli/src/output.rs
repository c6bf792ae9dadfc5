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

/// A message in the proto3 JSON mapping (camelCase names, enums by name,
/// 64-bit integers as strings, zero and default fields left out): what
/// reliefd's HTTP transport answers, made by the same generated code.
pub fn proto_json<T: serde::Serialize>(message: &T) -> Value {
    serde_json::to_value(message).unwrap_or(Value::Null)
}

pub fn state_json(s: &pb::SceneState) -> Value {
    proto_json(s)
}

/// The generation, and the parameters calls have set beside the manifest's.
pub fn parameters_text(s: &pb::SceneState) -> String {
    let mut out = format!("generation {}\n", s.generation);
    parameter_lines(&mut out, s);
    out
}

fn parameter_lines(out: &mut String, s: &pb::SceneState) {
    for p in &s.parameters {
        let manifest = p.manifest_value.as_deref().unwrap_or("its default");
        let _ = writeln!(out, "  {} {} = {} (set by a call; the manifest: {manifest})", p.target, p.name, p.value);
    }
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
    parameter_lines(&mut out, s);
    out
}

pub fn event_json(e: &pb::SceneEvent) -> Value {
    proto_json(e)
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
    proto_json(c)
}

pub fn camera_text(c: &pb::Camera) -> String {
    format!(
        "{},{},{},{},{},{} (lon, lat, altitude m, heading, pitch, roll), fov {} deg",
        c.lon_deg, c.lat_deg, c.altitude_m, c.heading_deg, c.pitch_deg, c.roll_deg, c.vertical_fov_deg
    )
}

/// The tile's answer without its payload (written to `path`), and the path.
pub fn tile_json(t: &pb::GetTileResponse, path: &std::path::Path) -> Value {
    with_path(proto_json(&pb::GetTileResponse { payload: None, ..t.clone() }), path)
}

/// `value` (a JSON object) with the file the command wrote as `path`.
fn with_path(mut value: Value, path: &std::path::Path) -> Value {
    if let Value::Object(map) = &mut value {
        map.insert("path".into(), json!(path.display().to_string()));
    }
    value
}

/// The render's answer without its image (written to `path`), and the path.
pub fn frame_json(f: &pb::RenderResponse, path: &std::path::Path) -> Value {
    let mut without_image = f.clone();
    without_image.image.clear();
    with_path(proto_json(&without_image), path)
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
