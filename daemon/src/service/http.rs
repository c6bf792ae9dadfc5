//! The HTTP transport, on the gRPC port: the browser viewer's page, and
//! each call as JSON (the relief.v1 messages in the proto3 JSON mapping),
//! streams as Server-Sent Events, and frames also as binary messages on a
//! WebSocket (`/api/frames/ws`). Every route parses its input, hands it
//! to the one implementation of the call and writes the answer; errors are
//! the gRPC status's code and message, with the matching HTTP status.

use std::collections::HashMap;
use std::convert::Infallible;
use std::sync::Arc;

use axum::Router;
use axum::body::Bytes;
use axum::extract::ws::WebSocketUpgrade;
use axum::extract::{Extension, Path, Query, State};
use axum::http::{HeaderValue, Method, Uri, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, patch, post};
use relief_proto::v1 as pb;
use serde::Serialize;
use serde::de::DeserializeOwned;
use tokio_stream::{Stream, StreamExt};
use tonic::Status;
use tower::ServiceExt as _;

use super::auth::{Holder, Scope};
use super::calls::Calls;
use super::status::HttpError;
use super::status::error_body;

mod tab;
mod tiles;

type Shared = State<Arc<Calls>>;

type Reply<T> = Result<axum::Json<T>, HttpError>;

fn reply<T: Serialize>(r: Result<T, Status>) -> Reply<T> {
    r.map(axum::Json).map_err(HttpError)
}

/// A request body as a relief.v1 message; an empty body is the message's
/// defaults.
fn body<T: DeserializeOwned + Default>(bytes: &Bytes, message: &str) -> Result<T, HttpError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Ok(T::default());
    }
    serde_json::from_slice(bytes)
        .map_err(|e| HttpError(Status::invalid_argument(format!("invalid JSON body for a {message}: {e}"))))
}

type Params = Query<HashMap<String, String>>;

/// A query parameter parsed as `T`, naming the parameter when it is not.
fn param<T: std::str::FromStr>(q: &HashMap<String, String>, name: &str) -> Result<Option<T>, HttpError> {
    q.get(name)
        .map(|v| {
            v.parse()
                .map_err(|_| HttpError(Status::invalid_argument(format!("invalid query parameter '{name}': '{v}'"))))
        })
        .transpose()
}

/// `sun_time=2026-06-21T15:00:00+02:00`, or `sun_azimuth_deg` and
/// `sun_elevation_deg`: the frame's sun (checked where the gRPC one is).
fn sun_param(q: &HashMap<String, String>) -> Result<Option<pb::Sun>, HttpError> {
    let (azimuth_deg, elevation_deg) = (param(q, "sun_azimuth_deg")?, param(q, "sun_elevation_deg")?);
    let time = q.get("sun_time").cloned();
    if time.is_none() && azimuth_deg.is_none() && elevation_deg.is_none() {
        return Ok(None);
    }
    Ok(Some(pb::Sun { time: time.unwrap_or_default(), azimuth_deg, elevation_deg }))
}

/// `camera=lon,lat,alt,heading,pitch,roll` and `fov=deg` (default 50).
fn camera_param(q: &HashMap<String, String>) -> Result<Option<pb::Camera>, HttpError> {
    let Some(text) = q.get("camera") else { return Ok(None) };
    let v: Vec<f64> = text.split(',').map(|p| p.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| {
        HttpError(Status::invalid_argument(format!(
            "invalid query parameter 'camera': '{text}' is not lon,lat,alt,heading,pitch,roll"
        )))
    })?;
    let [lon, lat, alt, heading, pitch, roll] = v[..] else {
        return Err(HttpError(Status::invalid_argument(format!(
            "invalid query parameter 'camera': '{text}' has {} numbers, not 6 (lon,lat,alt,heading,pitch,roll)",
            v.len()
        ))));
    };
    Ok(Some(pb::Camera {
        lon_deg: lon,
        lat_deg: lat,
        altitude_m: alt,
        heading_deg: heading,
        pitch_deg: pitch,
        roll_deg: roll,
        vertical_fov_deg: param(q, "fov")?.unwrap_or(50.0),
    }))
}

/// The `format` parameter: png (the default where `live` is not), jpeg,
/// rgba, or live (JPEG while the view is interactive, PNG at rest: the
/// default of the frames WebSocket).
fn format_param(q: &HashMap<String, String>, live: bool) -> Result<i32, HttpError> {
    match q.get("format").map(String::as_str) {
        None if live => Ok(pb::ImageFormat::Unspecified as i32),
        None | Some("png") => Ok(pb::ImageFormat::Png as i32),
        Some("jpeg") => Ok(pb::ImageFormat::Jpeg as i32),
        Some("rgba") => Ok(pb::ImageFormat::Rgba8 as i32),
        Some("live") => Ok(pb::ImageFormat::Unspecified as i32),
        Some(other) => Err(HttpError(Status::invalid_argument(format!(
            "invalid query parameter 'format': '{other}' (png, jpeg, rgba or live)"
        )))),
    }
}

/// Server-Sent Events of a call's stream: `event: NAME` with the message
/// as JSON; a failure ends the stream with `event: error`.
fn sse<T: Serialize + Send + 'static>(
    name: &'static str,
    stream: impl Stream<Item = Result<T, Status>> + Send + 'static,
) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    // The streams behind end after their first error.
    let events = stream.map(move |item| {
        let event = match item {
            Ok(message) => Event::default().event(name).json_data(message),
            Err(status) => Event::default().event("error").json_data(error_body(&status)),
        };
        Ok(event.unwrap_or_else(|e| Event::default().event("error").data(format!("cannot encode: {e}"))))
    });
    Sse::new(events).keep_alive(KeepAlive::default())
}

async fn state(State(c): Shared) -> Reply<pb::SceneState> {
    Ok(axum::Json(c.scene.state()))
}

async fn events(State(c): Shared, Query(q): Params) -> Result<impl IntoResponse, HttpError> {
    let from = param(&q, "from")?.unwrap_or(0);
    Ok(sse("scene", c.scene.watch(pb::WatchRequest { from_generation: from })))
}

async fn wait(State(c): Shared, Query(q): Params) -> Reply<pb::SceneState> {
    let min_generation = param(&q, "generation")?
        .ok_or_else(|| HttpError(Status::invalid_argument("missing query parameter 'generation'")))?;
    let timeout_ms = param(&q, "timeout_ms")?.unwrap_or(10_000);
    reply(c.scene.wait_for_generation(pb::WaitForGenerationRequest { min_generation, timeout_ms }).await)
}

async fn reload(State(c): Shared, Extension(scope): Extension<Scope>, bytes: Bytes) -> Reply<pb::SceneState> {
    reply(c.scene.reload(scope, body(&bytes, "ReloadRequest")?).await)
}

/// An S3 event notification (the JSON a bucket's webhook sends).
async fn notify(State(c): Shared, Extension(scope): Extension<Scope>, bytes: Bytes) -> Reply<pb::SceneState> {
    let event: serde_json::Value = serde_json::from_slice(&bytes).map_err(|e| {
        HttpError(Status::invalid_argument(format!("invalid JSON body for an S3 event notification: {e}")))
    })?;
    let objects = relief_engine::watcher::event_objects(&event).map_err(|e| HttpError(Status::invalid_argument(e)))?;
    reply(c.scene.notify_objects(scope, objects).await)
}

async fn set_parameter(State(c): Shared, Extension(scope): Extension<Scope>, bytes: Bytes) -> Reply<pb::SceneState> {
    reply(c.scene.set_source_parameter(scope, body(&bytes, "SetSourceParameterRequest")?).await)
}

async fn get_camera(State(c): Shared) -> Reply<pb::Camera> {
    Ok(axum::Json(c.view.camera()))
}

async fn set_camera(State(c): Shared, Extension(scope): Extension<Scope>, bytes: Bytes) -> Reply<pb::Camera> {
    let camera: pb::Camera = body(&bytes, "Camera")?;
    reply(c.view.set_camera(scope, &pb::SetCameraRequest { camera: Some(camera) }))
}

/// The image itself (PNG, JPEG, or raw RGBA with its size in headers), with the
/// generation, camera and pass timings in `x-relief-*` headers.
async fn render_image(State(c): Shared, Query(q): Params) -> Result<Response, HttpError> {
    let request = pb::RenderRequest {
        camera: camera_param(&q)?,
        width: param(&q, "width")?.unwrap_or(0),
        height: param(&q, "height")?.unwrap_or(0),
        format: format_param(&q, false)?,
        quality: None,
        sun: sun_param(&q)?,
    };
    let r = c.view.render(&request).await?;
    let mut response = r.image.clone().into_response();
    let headers = response.headers_mut();
    let content_type = match pb::ImageFormat::try_from(r.format) {
        Ok(pb::ImageFormat::Png) => "image/png",
        Ok(pb::ImageFormat::Jpeg) => "image/jpeg",
        _ => "application/octet-stream",
    };
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    let camera = r.camera.unwrap_or_default();
    let text = [
        ("x-relief-generation", r.generation.to_string()),
        ("x-relief-width", r.width.to_string()),
        ("x-relief-height", r.height.to_string()),
        (
            "x-relief-camera",
            format!(
                "{},{},{},{},{},{}",
                camera.lon_deg,
                camera.lat_deg,
                camera.altitude_m,
                camera.heading_deg,
                camera.pitch_deg,
                camera.roll_deg
            ),
        ),
        (
            "x-relief-passes",
            r.passes.iter().map(|p| format!("{}={:.2}", p.pass, p.elapsed_ms)).collect::<Vec<_>>().join(";"),
        ),
    ];
    for (name, value) in text {
        if let Ok(v) = HeaderValue::from_str(&value) {
            headers.insert(name, v);
        }
    }
    Ok(response)
}

async fn render_json(State(c): Shared, bytes: Bytes) -> Reply<pb::RenderResponse> {
    let request: pb::RenderRequest = body(&bytes, "RenderRequest")?;
    reply(c.view.render(&request).await)
}

/// A frame stream's request from its query parameters.
fn frames_request(q: &HashMap<String, String>, live: bool) -> Result<pb::StreamFramesRequest, HttpError> {
    let quality = param::<u32>(q, "jpeg_quality")?
        .map(|v| pb::QualityOverrides { frame_jpeg_quality: Some(v), ..Default::default() });
    Ok(pb::StreamFramesRequest {
        width: param(q, "width")?.unwrap_or(0),
        height: param(q, "height")?.unwrap_or(0),
        format: format_param(q, live)?,
        max_fps: param(q, "max_fps")?.unwrap_or(0.0),
        quality,
        camera: camera_param(q)?,
        view_id: q.get("view").cloned().unwrap_or_default(),
        sun: sun_param(q)?,
    })
}

async fn frames(State(c): Shared, Query(q): Params) -> Result<impl IntoResponse, HttpError> {
    let request = frames_request(&q, false)?;
    Ok(sse("frame", c.view.stream_frames(&request)?))
}

/// Frames on a WebSocket, each one binary message (`tab::ws_frame`); the
/// stream is checked before the upgrade, so a bad request is an HTTP
/// error. Ends with a text message `{"error": ...}` when the view fails.
/// With `events=1` (and `from=N`) it is a browser tab's one connection:
/// scene events and the tab's calls travel on it too (`tab.rs`).
async fn frames_ws(
    State(c): Shared,
    Extension(scope): Extension<Scope>,
    Extension(holder): Extension<Holder>,
    hold: Option<Extension<super::connections::Hold>>,
    Query(q): Params,
    ws: WebSocketUpgrade,
) -> Result<Response, HttpError> {
    let request = frames_request(&q, true)?;
    let with_events = matches!(q.get("events").map(String::as_str), Some("1" | "true"));
    let events: Option<tab::Events> = if with_events {
        let from = param(&q, "from")?.unwrap_or(0);
        Some(Box::pin(c.scene.watch(pb::WatchRequest { from_generation: from })))
    } else {
        None
    };
    let view_id = request.view_id.clone();
    let frames = c.view.stream_frames(&request)?;
    let tab = with_events.then(|| tab::Tab { calls: Arc::clone(&c), scope, holder, view_id });
    // The socket keeps its connection's place among the connections.
    Ok(ws.on_upgrade(move |socket| async move {
        let _hold = hold;
        tab::serve(socket, frames, events, tab).await;
    }))
}

async fn open_view(State(c): Shared, Extension(holder): Extension<Holder>, bytes: Bytes) -> Reply<pb::ViewState> {
    reply(c.view.open_view(holder, &body(&bytes, "OpenViewRequest")?))
}

async fn update_view(
    State(c): Shared,
    Extension(scope): Extension<Scope>,
    Extension(holder): Extension<Holder>,
    Path(id): Path<String>,
    bytes: Bytes,
) -> Reply<pb::ViewState> {
    let request = pb::UpdateViewRequest { view_id: id, ..body(&bytes, "UpdateViewRequest")? };
    reply(c.view.update_view(scope, holder, &request))
}

async fn navigate_view(
    State(c): Shared,
    Extension(scope): Extension<Scope>,
    Extension(holder): Extension<Holder>,
    Path(id): Path<String>,
    bytes: Bytes,
) -> Reply<pb::Camera> {
    let request = pb::NavigateRequest { view_id: id, ..body(&bytes, "NavigateRequest")? };
    reply(c.view.navigate(scope, holder, request).await)
}

async fn navigate_scene(
    State(c): Shared,
    Extension(scope): Extension<Scope>,
    Extension(holder): Extension<Holder>,
    bytes: Bytes,
) -> Reply<pb::Camera> {
    let request = pb::NavigateRequest { view_id: String::new(), ..body(&bytes, "NavigateRequest")? };
    reply(c.view.navigate(scope, holder, request).await)
}

async fn pick(State(c): Shared, Path(id): Path<String>, Query(q): Params) -> Reply<pb::PickResponse> {
    let request = pb::PickRequest { view_id: id, x: param(&q, "x")?.unwrap_or(0.5), y: param(&q, "y")?.unwrap_or(0.5) };
    reply(c.view.pick(&request).await)
}

/// `points=lon,lat;lon,lat` and an optional `source`.
async fn elevation_get(State(c): Shared, Query(q): Params) -> Reply<pb::SampleElevationResponse> {
    let text = q.get("points").map_or("", String::as_str);
    let points = text
        .split(';')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            let v: Vec<f64> = p.split(',').filter_map(|x| x.trim().parse().ok()).collect();
            match v[..] {
                [lon_deg, lat_deg] => Ok(pb::GeodeticPoint { lon_deg, lat_deg }),
                _ => Err(HttpError(Status::invalid_argument(format!(
                    "invalid query parameter 'points': '{p}' is not lon,lat"
                )))),
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let source_id = q.get("source").cloned().unwrap_or_default();
    reply(c.tiles.elevation(pb::SampleElevationRequest { points, source_id }).await)
}

async fn elevation_post(State(c): Shared, bytes: Bytes) -> Reply<pb::SampleElevationResponse> {
    reply(c.tiles.elevation(body(&bytes, "SampleElevationRequest")?).await)
}

async fn tile(
    State(c): Shared,
    Path((source_id, level, x, y)): Path<(String, u32, u32, u32)>,
) -> Reply<pb::GetTileResponse> {
    let request = pb::GetTileRequest { source_id, key: Some(pb::TileKey { level, x, y }), quality: None };
    reply(c.tiles.tile(request).await)
}

/// The calls this transport offers, for `curl /api`.
const ROUTES: &[(&str, &str, &str)] = &[
    ("GET", "/api/state", "SceneState"),
    ("GET", "/api/events?from=N", "SceneEvent stream (Server-Sent Events, event: scene)"),
    ("GET", "/api/wait?generation=N&timeout_ms=T", "SceneState once generation N is served"),
    ("POST", "/api/reload", "ReloadRequest -> SceneState"),
    ("POST", "/api/parameters", "SetSourceParameterRequest -> SceneState"),
    ("POST", "/api/notify", "an S3 event notification (Records[].s3.bucket.name, .object.key) -> SceneState"),
    ("GET", "/api/camera", "the scene Camera"),
    ("PUT", "/api/camera", "Camera -> Camera (SetCamera)"),
    ("GET", "/api/render?camera=lon,lat,alt,heading,pitch,roll&fov=&width=&height=&format=png|rgba", "the image"),
    ("POST", "/api/render", "RenderRequest -> RenderResponse"),
    (
        "GET",
        "/api/frames?view=ID|camera=...&width=&height=&max_fps=&format=png|jpeg|live|rgba&jpeg_quality=",
        "RenderResponse stream (SSE, event: frame)",
    ),
    (
        "GET",
        "/api/frames/ws?(as /api/frames; format defaults to live)&events=1&from=N",
        "WebSocket of binary frames: u32 LE header length, {\"frame\": RenderResponse} JSON, image bytes; \
         with events=1 also {\"scene\": SceneEvent} and the tab's calls as text",
    ),
    ("POST", "/api/views", "OpenViewRequest -> ViewState"),
    ("PATCH", "/api/views/{id}", "UpdateViewRequest -> ViewState"),
    ("POST", "/api/views/{id}/navigate", "NavigateRequest -> Camera"),
    ("POST", "/api/navigate", "NavigateRequest on the scene camera -> Camera"),
    ("GET", "/api/views/{id}/pick?x=&y=", "PickResponse"),
    ("GET", "/api/elevation?points=lon,lat;lon,lat&source=ID", "SampleElevationResponse"),
    ("POST", "/api/elevation", "SampleElevationRequest -> SampleElevationResponse"),
    ("GET", "/api/tiles/{source}/{level}/{x}/{y}", "GetTileResponse"),
];

async fn routes() -> axum::Json<serde_json::Value> {
    axum::Json(serde_json::json!(
        ROUTES
            .iter()
            .chain(tiles::ROUTES)
            .map(|(m, p, what)| serde_json::json!({"method": m, "path": p, "answer": what}))
            .collect::<Vec<_>>()
    ))
}

async fn asset(uri: Uri) -> Response {
    match relief_web::asset(uri.path()) {
        Some(a) => {
            ([(header::CONTENT_TYPE, a.content_type), (header::CACHE_CONTROL, "no-cache")], a.body).into_response()
        }
        None => not_found(&Method::GET, &uri),
    }
}

fn not_found(method: &Method, uri: &Uri) -> Response {
    HttpError(Status::not_found(format!(
        "no route {method} {}; GET /api lists the calls",
        relief_source::echo::echoed(uri.path())
    )))
    .into_response()
}

/// The HTTP routes over `calls`; what none of them takes goes to `grpc`
/// when it is a gRPC call (by its content type), else gets a 404.
pub fn router(calls: Arc<Calls>, grpc: Router) -> Router {
    let mut router = Router::new()
        .route("/api", get(routes))
        .route("/api/state", get(state))
        .route("/api/events", get(events))
        .route("/api/wait", get(wait))
        .route("/api/reload", post(reload))
        .route("/api/parameters", post(set_parameter))
        .route("/api/notify", post(notify))
        .route("/api/camera", get(get_camera).put(set_camera))
        .route("/api/render", get(render_image).post(render_json))
        .route("/api/frames", get(frames))
        .route("/api/frames/ws", get(frames_ws))
        .route("/api/views", post(open_view))
        .route("/api/views/{id}", patch(update_view))
        .route("/api/views/{id}/navigate", post(navigate_view))
        .route("/api/navigate", post(navigate_scene))
        .route("/api/views/{id}/pick", get(pick))
        .route("/api/elevation", get(elevation_get).post(elevation_post))
        .route("/api/tiles/{source}/{level}/{x}/{y}", get(tile))
        .merge(tiles::routes());
    for a in relief_web::ASSETS {
        router = router.route(a.path, get(asset));
    }
    let rest = tower::service_fn(move |request: axum::extract::Request| {
        let grpc = grpc.clone();
        async move {
            let is_grpc = request
                .headers()
                .get(header::CONTENT_TYPE)
                .and_then(|v| v.to_str().ok())
                .is_some_and(|v| v.starts_with("application/grpc"));
            if is_grpc { grpc.oneshot(request).await } else { Ok(not_found(request.method(), request.uri())) }
        }
    });
    router.fallback_service(rest).with_state(calls)
}
