//! Who may call what. A token file gives each bearer token a scope: `read`
//! (state, events, tiles, elevation, renders, frames, the caller's own
//! views) or `control` (also the scene's camera, reloads and source
//! parameters). One layer in front of both transports checks the token
//! of every call and hands its scope to the call; the calls that change
//! the scene ask for `control` themselves, so gRPC and HTTP cannot differ.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{HeaderValue, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use tonic::Status;

use super::status::HttpError;
pub use crate::frames::Holder;

/// What a caller may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Scope {
    /// Look: state, events, tiles, elevation, renders, frames, own views.
    Read,
    /// Also steer: the scene's camera, reloads, source parameters.
    Control,
}

impl Scope {
    /// `Ok` when this scope may `what` (a phrase: "move the scene camera").
    pub fn require_control(self, what: &str) -> Result<(), Status> {
        match self {
            Self::Control => Ok(()),
            Self::Read => Err(Status::permission_denied(format!(
                "this token may only read; to {what} the call needs a control token"
            ))),
        }
    }

    fn parse(word: &str) -> Option<Self> {
        match word {
            "read" => Some(Self::Read),
            "control" => Some(Self::Control),
            _ => None,
        }
    }
}

/// A token file that cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("cannot use the token file: {message}: {}", path.display())]
pub struct TokenFileError {
    message: String,
    path: PathBuf,
}

/// The callers a daemon lets in.
#[derive(Debug, Clone)]
pub enum Access {
    /// No tokens: every caller may do everything (loopback, or `--insecure`).
    Open,
    /// Only callers with one of these tokens, each with its scope.
    Tokens(Arc<HashMap<String, Scope>>),
}

/// Tokens shorter than this are refused: a guessable token is no token.
const MIN_TOKEN_CHARS: usize = 16;

impl Access {
    /// Reads a token file: one `SCOPE TOKEN` per line (`read` or
    /// `control`), `#` comments and blank lines skipped.
    pub fn from_file(path: &Path) -> Result<Self, TokenFileError> {
        let fail = |message: String| TokenFileError { message, path: path.to_path_buf() };
        let text = relief_source::regular::read_regular_to_string(path).map_err(|e| fail(e.to_string()))?;
        let mut tokens = HashMap::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let mut words = line.split_whitespace();
            let (Some(scope), Some(token), None) = (words.next(), words.next(), words.next()) else {
                return Err(fail(format!("line {} is not 'SCOPE TOKEN' (SCOPE is read or control)", n + 1)));
            };
            let scope = Scope::parse(scope)
                .ok_or_else(|| fail(format!("line {}: unknown scope '{scope}' (known: read, control)", n + 1)))?;
            if token.chars().count() < MIN_TOKEN_CHARS {
                return Err(fail(format!("line {}: the token is shorter than {MIN_TOKEN_CHARS} characters", n + 1)));
            }
            if tokens.insert(token.to_owned(), scope).is_some() {
                return Err(fail(format!("line {}: the token is listed twice", n + 1)));
            }
        }
        if tokens.is_empty() {
            return Err(fail("it lists no tokens".into()));
        }
        Ok(Self::Tokens(Arc::new(tokens)))
    }

    /// The scope `token` grants, comparing in time that does not depend on
    /// where a wrong token first differs.
    fn scope_of(&self, token: Option<&str>) -> Result<Scope, &'static str> {
        let Self::Tokens(tokens) = self else {
            return Ok(Scope::Control);
        };
        let token = token.ok_or("missing token: send 'authorization: Bearer TOKEN'")?;
        let mut found = None;
        for (known, scope) in tokens.iter() {
            if same_bytes(known.as_bytes(), token.as_bytes()) {
                found = Some(*scope);
            }
        }
        found.ok_or("the token is not one this reliefd accepts")
    }
}

fn same_bytes(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The GET calls that take their token as an `access_token` query
/// parameter (a browser's EventSource, WebSocket and image requests cannot
/// set headers): streams and images, which only read; and every standard
/// tile under `/tiles/` (tile clients build their URLs from templates).
const QUERY_TOKEN_PATHS: [&str; 4] = ["/api/events", "/api/frames", "/api/frames/ws", "/api/render"];

/// The bearer token of a request, and whether it came in the query: the
/// `authorization` header, or an `access_token` query parameter of a GET
/// stream or image (`QUERY_TOKEN_PATHS`; a token there reads only).
fn bearer(request: &Request) -> Option<(String, bool)> {
    if let Some(value) = request.headers().get(header::AUTHORIZATION) {
        let text = value.to_str().ok()?;
        let (kind, token) = text.split_once(' ')?;
        return kind.eq_ignore_ascii_case("bearer").then(|| (token.trim().to_owned(), false));
    }
    let path = request.uri().path();
    let streams = request.method() == axum::http::Method::GET
        && (QUERY_TOKEN_PATHS.contains(&path) || path.starts_with("/tiles/"));
    if !streams {
        return None;
    }
    let token = request.uri().query()?.split('&').find_map(|pair| {
        let (name, value) = pair.split_once('=')?;
        // Percent-decoded, `+` kept: a token may hold any character.
        (name == "access_token").then(|| percent_encoding::percent_decode_str(value).decode_utf8_lossy().into_owned())
    })?;
    Some((token, true))
}

/// What needs no token: the viewer's page (it holds no scene data) and
/// gRPC health checks (load balancers probe them).
fn is_public(request: &Request) -> bool {
    let path = request.uri().path();
    path.starts_with("/grpc.health.v1.Health/")
        || (request.method() == axum::http::Method::GET && relief_web::asset(path).is_some())
}

/// A gRPC call (its content type), which browsers cannot make.
pub fn is_grpc(request: &Request) -> bool {
    request
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/grpc"))
}

/// The layer: a call without a good token is answered UNAUTHENTICATED
/// (gRPC) or 401 (HTTP); one with a good token goes on with its scope.
pub async fn check(State(access): State<Access>, mut request: Request, next: Next) -> Response {
    if is_public(&request) {
        request.extensions_mut().insert(Scope::Read);
        request.extensions_mut().insert(Holder::ANYONE);
        return next.run(request).await;
    }
    let (token, in_query) = bearer(&request).unzip();
    match access.scope_of(token.as_deref()) {
        Ok(scope) => {
            // A token in a URL ends up in logs and histories: it reads only.
            let scope = if in_query == Some(true) { scope.min(Scope::Read) } else { scope };
            let holder = match (&access, token) {
                (Access::Tokens(_), Some(token)) => Holder::of(&token),
                _ => Holder::ANYONE,
            };
            request.extensions_mut().insert(scope);
            request.extensions_mut().insert(holder);
            next.run(request).await
        }
        Err(why) => {
            tracing::debug!(path = request.uri().path(), "refused a call: {why}");
            let status = Status::unauthenticated(why);
            if is_grpc(&request) {
                status.into_http::<axum::body::Body>()
            } else {
                let mut response = HttpError::from(status).into_response();
                response.headers_mut().insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
                response
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> Result<Access, TokenFileError> {
        let dir = tempfile::tempdir().map_err(|e| TokenFileError { message: e.to_string(), path: PathBuf::new() })?;
        let path = dir.path().join("tokens");
        std::fs::write(&path, text).map_err(|e| TokenFileError { message: e.to_string(), path: path.clone() })?;
        Access::from_file(&path)
    }

    #[test]
    fn a_token_file_gives_each_token_its_scope() -> Result<(), TokenFileError> {
        let access = file("# team\ncontrol cccccccccccccccccccc\n\nread rrrrrrrrrrrrrrrrrrrr\n")?;
        assert_eq!(access.scope_of(Some("cccccccccccccccccccc")), Ok(Scope::Control));
        assert_eq!(access.scope_of(Some("rrrrrrrrrrrrrrrrrrrr")), Ok(Scope::Read));
        assert!(access.scope_of(Some("rrrrrrrrrrrrrrrrrrrx")).is_err());
        assert!(access.scope_of(None).is_err());
        assert_eq!(Access::Open.scope_of(None), Ok(Scope::Control));
        Ok(())
    }

    #[test]
    fn bad_token_files_are_refused_with_the_line() {
        for (text, says) in [
            ("", "lists no tokens"),
            ("write aaaaaaaaaaaaaaaaaaaa\n", "line 1: unknown scope 'write'"),
            ("read short\n", "line 1: the token is shorter than 16"),
            ("read\n", "line 1 is not 'SCOPE TOKEN'"),
            ("read aaaaaaaaaaaaaaaaaaaa\ncontrol aaaaaaaaaaaaaaaaaaaa\n", "line 2: the token is listed twice"),
        ] {
            let message = file(text).err().map(|e| e.to_string()).unwrap_or_default();
            assert!(message.contains(says), "{text:?}: {message}");
            assert!(message.starts_with("cannot use the token file: "), "{message}");
        }
    }
}
