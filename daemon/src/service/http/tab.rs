//! One browser tab's connection: the frames WebSocket (`/api/frames/ws`)
//! asked with `events=1` carries the scene's events and the tab's calls
//! too, so a tab holds one connection to reliefd whatever it does (a
//! browser allows six to one host; two long-lived streams a tab starved
//! the third tab of any).
//!
//! On the socket, beside the binary frames (`ws_frame`):
//! - reliefd sends `{"scene": SceneEvent}` for each scene event (from
//!   generation `from`, a snapshot first), and `{"reply": N, ...}` for
//!   each call, with `camera`, `view`, `pick` or `state`, or `error`;
//! - the tab sends `{"id": N, "navigate": NavigateRequest}`,
//!   `{"id": N, "update": UpdateViewRequest}`, `{"id": N, "pick": {"x":
//!   .., "y": ..}}`, `{"id": N, "home": {}}` or `{"id": N, "state": {}}`;
//!   the view is the socket's where a call names none. Calls are served
//!   in the order sent.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket};
use relief_proto::v1 as pb;
use serde_json::{Value, json};
use tokio_stream::{Stream, StreamExt};
use tonic::Status;

use super::super::auth::{Holder, Scope};
use super::super::calls::Calls;
use super::super::status::error_body;

/// How long a message may take to leave before the socket is closed (a
/// viewer that stopped reading).
const SEND_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);

/// Who the tab is, for the calls it makes on its socket.
pub struct Tab {
    pub calls: Arc<Calls>,
    pub scope: Scope,
    pub holder: Holder,
    pub view_id: String,
}

pub type Events = std::pin::Pin<Box<dyn Stream<Item = Result<pb::SceneEvent, Status>> + Send>>;

/// Serves the socket until either side ends it: frames, events when
/// `events` is set, and the tab's calls.
pub async fn serve(
    mut socket: WebSocket,
    mut frames: impl Stream<Item = Result<pb::RenderResponse, Status>> + Unpin,
    events: Option<Events>,
    tab: Option<Tab>,
) {
    let mut events = events;
    loop {
        let out = tokio::select! {
            item = frames.next() => match item {
                Some(Ok(frame)) => Message::Binary(ws_frame(frame)),
                Some(Err(status)) => {
                    let body = json!({ "error": error_body(&status) }).to_string();
                    let _ = socket.send(Message::Text(body.into())).await;
                    let _ = socket.send(Message::Close(None)).await;
                    return;
                }
                None => return,
            },
            Some(event) = next_event(&mut events) => match event {
                Ok(event) => Message::Text(json!({ "scene": event }).to_string().into()),
                Err(status) => {
                    // The events end; the frames go on.
                    events = None;
                    Message::Text(json!({ "sceneError": error_body(&status) }).to_string().into())
                }
            },
            incoming = socket.recv() => match incoming {
                None | Some(Err(_) | Ok(Message::Close(_))) => return,
                Some(Ok(Message::Text(text))) => match &tab {
                    Some(tab) => Message::Text(answer(tab, text.as_str()).await.to_string().into()),
                    None => continue,
                },
                Some(Ok(_)) => continue,
            },
        };
        if !matches!(tokio::time::timeout(SEND_TIMEOUT, socket.send(out)).await, Ok(Ok(()))) {
            return;
        }
    }
}

async fn next_event(events: &mut Option<Events>) -> Option<Result<pb::SceneEvent, Status>> {
    match events {
        Some(e) => e.next().await,
        None => std::future::pending().await,
    }
}

/// The answer to one call the tab sent: `{"reply": id, NAME: answer}` or
/// `{"reply": id, "error": {code, message}}`.
async fn answer(tab: &Tab, text: &str) -> Value {
    let (id, result) = match serde_json::from_str::<Value>(text) {
        Ok(message) => (message.get("id").cloned().unwrap_or(Value::Null), call(tab, &message).await),
        Err(e) => (Value::Null, Err(Status::invalid_argument(format!("invalid JSON message on the socket: {e}")))),
    };
    match result {
        Ok((name, value)) => json!({ "reply": id, name: value }),
        Err(status) => json!({ "reply": id, "error": error_body(&status) }),
    }
}

fn parsed<T: serde::de::DeserializeOwned>(v: &Value, message: &str) -> Result<T, Status> {
    serde_json::from_value(v.clone()).map_err(|e| Status::invalid_argument(format!("invalid {message}: {e}")))
}

fn encoded<T: serde::Serialize>(name: &'static str, v: &T) -> Result<(&'static str, Value), Status> {
    serde_json::to_value(v).map(|v| (name, v)).map_err(|e| Status::internal(format!("cannot encode a {name}: {e}")))
}

async fn call(tab: &Tab, message: &Value) -> Result<(&'static str, Value), Status> {
    let view = &tab.calls.view;
    if let Some(v) = message.get("navigate") {
        let mut request: pb::NavigateRequest = parsed(v, "NavigateRequest")?;
        if request.view_id.is_empty() {
            request.view_id.clone_from(&tab.view_id);
        }
        return encoded("camera", &view.navigate(tab.scope, tab.holder, request).await?);
    }
    if let Some(v) = message.get("update") {
        let mut request: pb::UpdateViewRequest = parsed(v, "UpdateViewRequest")?;
        if request.view_id.is_empty() {
            request.view_id.clone_from(&tab.view_id);
        }
        return encoded("view", &view.update_view(tab.scope, tab.holder, &request)?);
    }
    if let Some(v) = message.get("pick") {
        let at = |k: &str| v.get(k).and_then(Value::as_f64).unwrap_or(0.5);
        let request = pb::PickRequest { view_id: tab.view_id.clone(), x: at("x"), y: at("y") };
        return encoded("pick", &view.pick(&request).await?);
    }
    if message.get("home").is_some() {
        return encoded("camera", &view.home(tab.scope, tab.holder, &tab.view_id).await?);
    }
    if message.get("state").is_some() {
        return encoded("state", &tab.calls.scene.state());
    }
    Err(Status::invalid_argument("unknown message on the socket: navigate, update, pick, home or state"))
}

/// One frame as a binary WebSocket message: the length of a JSON header
/// (4 bytes, little-endian), the header `{"frame": RenderResponse}` in
/// the proto3 JSON mapping without its image, then the image's bytes
/// (PNG, JPEG or RGBA8 as `frame.format` says). A header that names
/// another member than "frame" may follow on the same connection.
pub fn ws_frame(mut frame: pb::RenderResponse) -> Bytes {
    let image = std::mem::take(&mut frame.image);
    let header = serde_json::json!({ "frame": frame }).to_string();
    let mut out = Vec::with_capacity(4 + header.len() + image.len());
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(&image);
    Bytes::from(out)
}
