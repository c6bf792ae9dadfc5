//! The standard tiles under `/tiles/` (`crate::standard`), as HTTP: tile
//! bytes with an ETag, gzip when the client takes it, and a cache time
//! that follows the URL's version; descriptions as JSON to ask for each
//! time; change notices as Server-Sent Events. Errors are
//! `{"code": ..., "message": ...}` with 400, 404, 406 or 503.

use std::convert::Infallible;
use std::sync::Arc;

use axum::Router;
use axum::extract::{Extension, Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use tokio_stream::{Stream, StreamExt};

use crate::service::calls::Calls;

type Shared = State<Arc<Calls>>;
type Params = Query<std::collections::HashMap<String, String>>;
use crate::service::connections::Secure;
use crate::standard::{Answer, CacheRule, Content, StandardError, XyzKind};

/// The routes, for `http::router`, and what each answers, for `GET /api`.
pub const ROUTES: &[(&str, &str, &str)] = &[
    ("GET", "/tiles/terrain/layer.json", "quantized-mesh-1.0 layer (CesiumJS CesiumTerrainProvider)"),
    ("GET", "/tiles/terrain/{z}/{x}/{y}.terrain?v=VERSION", "quantized-mesh tile (TMS rows; Accept: extensions)"),
    ("GET", "/tiles/3d/tileset.json", "3D Tiles 1.1 of the buildings and instances layers (GLB content)"),
    ("GET", "/tiles/3d/{buildings|instances}/{z}/{x}/{y}.json", "a group's tileset (external tileset of tileset.json)"),
    ("GET", "/tiles/3d/{buildings|instances}/{z}/{x}/{y}.glb", "glTF 2.0 content (GLB)"),
    ("GET", "/tiles/terrarium.json", "TileJSON 3.0.0 of the heights, Terrarium-encoded (MapLibre raster-dem)"),
    ("GET", "/tiles/terrarium/{z}/{x}/{y}.png?v=VERSION", "Terrarium PNG (Web Mercator XYZ)"),
    ("GET", "/tiles/imagery.json", "TileJSON 3.0.0 of the colour layer (MapLibre raster)"),
    ("GET", "/tiles/imagery/{z}/{x}/{y}.png?v=VERSION", "RGBA PNG (Web Mercator XYZ)"),
    ("GET", "/tiles/changes", "Server-Sent Events: versions, then changes (the tiles each generation changed)"),
];

pub fn routes() -> Router<Arc<Calls>> {
    Router::new()
        .route("/tiles/terrain/layer.json", get(layer_json))
        .route("/tiles/terrain/{z}/{x}/{file}", get(terrain_tile))
        .route("/tiles/3d/tileset.json", get(tileset))
        .route("/tiles/3d/{layer}/{z}/{x}/{file}", get(tileset_content))
        .route("/tiles/terrarium.json", get(tilejson::<TERRARIUM>))
        .route("/tiles/imagery.json", get(tilejson::<IMAGERY>))
        .route("/tiles/terrarium/{z}/{x}/{file}", get(xyz_tile::<TERRARIUM>))
        .route("/tiles/imagery/{z}/{x}/{file}", get(xyz_tile::<IMAGERY>))
        .route("/tiles/changes", get(changes))
}

/// A standard-tiles error as HTTP.
struct TileError(StandardError);

impl IntoResponse for TileError {
    fn into_response(self) -> Response {
        let (status, code) = match &self.0 {
            StandardError::NotFound(_) => (StatusCode::NOT_FOUND, "NOT_FOUND"),
            StandardError::NotAcceptable(_) => (StatusCode::NOT_ACCEPTABLE, "NOT_ACCEPTABLE"),
            StandardError::Invalid(_) => (StatusCode::BAD_REQUEST, "INVALID_ARGUMENT"),
            StandardError::Unavailable(_) => (StatusCode::SERVICE_UNAVAILABLE, "UNAVAILABLE"),
            StandardError::TooMany(_) => (StatusCode::TOO_MANY_REQUESTS, "RESOURCE_EXHAUSTED"),
        };
        (status, axum::Json(serde_json::json!({"code": code, "message": self.0.to_string()}))).into_response()
    }
}

impl From<StandardError> for TileError {
    fn from(e: StandardError) -> Self {
        Self(e)
    }
}

/// A description: JSON to ask for again each time, with an ETag (a hash
/// of it) that makes asking again cheap.
fn description(value: &serde_json::Value, request: &HeaderMap) -> Response {
    let body = value.to_string();
    let etag = format!("\"{:016x}\"", xxhash_rust::xxh3::xxh3_64(body.as_bytes()));
    let matches = request
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|tags| tags.split(',').any(|t| t.trim() == etag));
    let mut headers = HeaderMap::new();
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    headers.insert(header::VARY, HeaderValue::from_static("Origin"));
    if let Ok(v) = HeaderValue::from_str(&etag) {
        headers.insert(header::ETAG, v);
    }
    if matches {
        return (StatusCode::NOT_MODIFIED, headers).into_response();
    }
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static("application/json"));
    (headers, body).into_response()
}

async fn layer_json(State(c): Shared, headers: HeaderMap) -> Result<Response, TileError> {
    Ok(description(&c.standard.layer_json()?, &headers))
}

/// A number in a tile's address, or 400 naming it.
fn number<T: std::str::FromStr>(what: &str, text: &str) -> Result<T, StandardError> {
    text.parse().map_err(|_| {
        StandardError::Invalid(format!("the tile's {what} '{}' is not a number", relief_source::echo::echoed(text)))
    })
}

/// What a tile's path names: its level, column, row and extension.
struct TilePath {
    z: u8,
    x: u32,
    y: u32,
    extension: &'static str,
}

/// A tile's path `z/x/{y}.{extension}`: 404 for a file that is not `what`
/// (one of `extensions`), 400 for a number that is not one or a level past
/// `deepest` (a `level` or a `zoom`, as `depth` names it).
fn tile_path(
    (z, x, file): (&str, &str, &str),
    what: &str,
    extensions: &[&'static str],
    (depth, deepest): (&str, u8),
) -> Result<TilePath, StandardError> {
    let found = extensions.iter().find_map(|e| Some((file.strip_suffix(e)?.strip_suffix('.')?, *e)));
    let Some((y, extension)) = found else {
        let asked: Vec<String> = extensions.iter().map(|e| format!("{{z}}/{{x}}/{{y}}.{e}")).collect();
        return Err(StandardError::NotFound(format!(
            "'{}' is not {what}: ask for {}",
            relief_source::echo::echoed(file),
            asked.join(" or ")
        )));
    };
    let z: u8 = number(depth, z)?;
    if z > deepest {
        return Err(StandardError::Invalid(format!("{depth} {z} is past the deepest, {deepest}")));
    }
    Ok(TilePath { z, x: number("column", x)?, y: number("row", y)?, extension })
}

async fn terrain_tile(
    State(c): Shared,
    Path((z, x, file)): Path<(String, String, String)>,
    Query(q): Params,
    headers: HeaderMap,
) -> Result<Response, TileError> {
    let TilePath { z, x, y, .. } =
        tile_path((&z, &x, &file), "a terrain tile", &["terrain"], ("level", relief_source::MAX_LEVEL))?;
    let accept = headers.get(header::ACCEPT).and_then(|v| v.to_str().ok());
    let answer = c.standard.terrain_tile(z, x, y, q.get("v").map(String::as_str), accept).await?;
    Ok(tile_response(&c, &answer, &headers))
}

/// This daemon as the request reached it (`http://host:port`), for the
/// URLs a TileJSON names: MapLibre takes them as they are written.
fn base_url(headers: &HeaderMap, uri: &axum::http::Uri, secure: bool) -> String {
    let host = headers
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned)
        .or_else(|| uri.authority().map(|a| a.as_str().to_owned()))
        .unwrap_or_else(|| "localhost".into());
    format!("{}://{host}", if secure { "https" } else { "http" })
}

/// The XYZ kinds, as route parameters.
const TERRARIUM: u8 = 0;
const IMAGERY: u8 = 1;

fn xyz_kind(kind: u8) -> XyzKind {
    if kind == TERRARIUM { XyzKind::Terrarium } else { XyzKind::Imagery }
}

async fn tilejson<const KIND: u8>(
    State(c): Shared,
    headers: HeaderMap,
    uri: axum::http::Uri,
    secure: Option<Extension<Secure>>,
) -> Result<Response, TileError> {
    let secure = secure.is_some_and(|Extension(s)| s.0);
    Ok(description(&c.standard.tilejson(xyz_kind(KIND), &base_url(&headers, &uri, secure))?, &headers))
}

async fn xyz_tile<const KIND: u8>(
    State(c): Shared,
    Path((z, x, file)): Path<(String, String, String)>,
    Query(q): Params,
    headers: HeaderMap,
) -> Result<Response, TileError> {
    let kind = xyz_kind(KIND);
    let what = format!("a {} tile", kind.name());
    let TilePath { z, x, y, .. } =
        tile_path((&z, &x, &file), &what, &["png"], ("zoom", relief_standard_tiles::XYZ_MAX_ZOOM))?;
    let answer = c.standard.xyz_tile(kind, z, x, y, q.get("v").map(String::as_str)).await?;
    Ok(tile_response(&c, &answer, &headers))
}

async fn tileset(State(c): Shared, headers: HeaderMap) -> Result<Response, TileError> {
    Ok(description(&c.standard.tileset().await?, &headers))
}

async fn tileset_content(
    State(c): Shared,
    Path((layer, z, x, file)): Path<(String, String, String, String)>,
    Query(q): Params,
    headers: HeaderMap,
) -> Result<Response, TileError> {
    let content = match layer.as_str() {
        "buildings" => Content::Buildings,
        "instances" => Content::Instances,
        other => {
            return Err(StandardError::NotFound(format!(
                "'{}' is not a layer of the tileset (buildings or instances)",
                relief_source::echo::echoed(other)
            ))
            .into());
        }
    };
    let path =
        tile_path((&z, &x, &file), "part of the tileset", &["glb", "json"], ("level", relief_source::MAX_LEVEL))?;
    let (key, glb) = (relief_source::TileKey::new(path.z, path.x, path.y), path.extension == "glb");
    let answer = c.standard.tileset_part(content, key, glb, q.get("v").map(String::as_str)).await?;
    Ok(tile_response(&c, &answer, &headers))
}

/// Whether `Accept-Encoding` takes gzip (not with `q=0`).
fn accepts_gzip(request: &HeaderMap) -> bool {
    let Some(text) = request.get(header::ACCEPT_ENCODING).and_then(|v| v.to_str().ok()) else { return false };
    text.split(',').any(|coding| {
        let mut parts = coding.split(';').map(str::trim);
        parts.next().is_some_and(|name| name.eq_ignore_ascii_case("gzip") || name == "*")
            && parts.all(|p| p.strip_prefix("q=").is_none_or(|q| q.parse::<f64>().is_ok_and(|q| q > 0.0)))
    })
}

/// A tile's answer: 304 when the client's ETag is the tile's, else the
/// bytes (gzipped when accepted), with its cache rule.
fn tile_response(c: &Calls, answer: &Answer, request: &HeaderMap) -> Response {
    let cache = match answer.cache {
        CacheRule::Immutable => "public, max-age=31536000, immutable",
        CacheRule::Short => "public, max-age=10",
        CacheRule::Revalidate => "no-cache",
    };
    let e = &answer.encoded;
    let gzip = e.gzip.as_ref().filter(|_| accepts_gzip(request));
    // Each encoding's bytes have their own (strong) ETag.
    let etag = if gzip.is_some() { format!("{}-gzip\"", e.etag.trim_end_matches('"')) } else { e.etag.clone() };
    let mut headers = HeaderMap::new();
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    // Origin too: an allowed page's answer carries its origin (CORS), and
    // one without none; a cache must keep them apart.
    headers.insert(header::VARY, HeaderValue::from_static("Accept, Accept-Encoding, Origin"));
    let text = [
        (header::ETAG, etag.clone()),
        (header::HeaderName::from_static("x-relief-version"), answer.version.clone()),
        (header::HeaderName::from_static("x-relief-generation"), answer.generation.to_string()),
    ];
    for (name, value) in text {
        if let Ok(v) = HeaderValue::from_str(&value) {
            headers.insert(name, v);
        }
    }
    let matches = request
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|tags| tags.split(',').any(|t| t.trim() == etag || t.trim() == "*"));
    if matches {
        c.standard.count_not_modified();
        return (StatusCode::NOT_MODIFIED, headers).into_response();
    }
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(e.content_type));
    if let Some(zipped) = gzip {
        headers.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
        (headers, zipped.clone()).into_response()
    } else {
        (headers, e.bytes.clone()).into_response()
    }
}

async fn changes(State(c): Shared) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, TileError> {
    let events = c.standard.changes()?.map(|(name, value)| {
        Ok(Event::default()
            .event(name)
            .json_data(value)
            .unwrap_or_else(|e| Event::default().event("error").data(format!("cannot encode: {e}"))))
    });
    Ok(Sse::new(events).keep_alive(KeepAlive::default()))
}
