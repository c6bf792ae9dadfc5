//! Who may reach the HTTP calls from a browser: a page from another site
//! must not steer or read a reliefd its user runs on their own machine.
//! One layer in front of the HTTP routes (gRPC goes through untouched:
//! browsers cannot speak it):
//! - the `Host` a request names must be this daemon's (its address, or a
//!   loopback name while it listens on loopback) or one `--allow-host`
//!   names, where no token is asked for: a DNS-rebinding page reaches the
//!   daemon under a name of its own;
//! - a request that comes with an `Origin` (every cross-site fetch,
//!   WebSocket and EventSource sends one) must come from this daemon's own
//!   origin, or one `--allow-origin` names;
//! - a body (POST, PUT, PATCH) must be `application/json`, which a page of
//!   another site cannot send without a preflight this daemon never grants.

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use tonic::Status;

use super::auth::is_grpc;
use super::status::HttpError;

/// The hosts and origins a daemon answers browsers from.
#[derive(Debug, Clone, Default)]
pub struct Site {
    /// Where it listens.
    pub listen: Option<SocketAddr>,
    /// Check the `Host` header (where no token is asked for).
    pub check_host: bool,
    /// Names (`relief.example.org`, with or without a port) also served.
    pub hosts: Vec<String>,
    /// Origins (`https://maps.example.org`) whose pages may call.
    pub origins: Vec<String>,
}

impl Site {
    /// Whether `host` (a `Host` header: `name[:port]`) names this daemon.
    fn host_allowed(&self, host: &str) -> bool {
        let (name, _) = split_port(host);
        let name = name.trim_start_matches('[').trim_end_matches(']');
        if self.hosts.iter().any(|h| h.eq_ignore_ascii_case(host) || h.eq_ignore_ascii_case(name)) {
            return true;
        }
        let Some(listen) = self.listen else { return true };
        match name.parse::<IpAddr>() {
            // An address cannot be rebound: it is this machine's if the
            // daemon listens there, or anywhere.
            Ok(ip) => {
                listen.ip().is_unspecified() || ip == listen.ip() || (listen.ip().is_loopback() && ip.is_loopback())
            }
            Err(_) => listen.ip().is_loopback() && name.eq_ignore_ascii_case("localhost"),
        }
    }

    /// Whether a page from `origin` may call, for a request to `host`.
    fn origin_allowed(&self, origin: &str, host: Option<&str>) -> bool {
        if self.origins.iter().any(|o| o.trim_end_matches('/').eq_ignore_ascii_case(origin)) {
            return true;
        }
        // The daemon's own page: the origin's host and port are the request's.
        let own = origin.split_once("://").map(|(_, rest)| rest);
        own.zip(host).is_some_and(|(own, host)| own.eq_ignore_ascii_case(host))
    }
}

/// `host[:port]` split (an IPv6 literal keeps its brackets).
fn split_port(host: &str) -> (&str, Option<&str>) {
    if host.starts_with('[') {
        return match host.find(']') {
            Some(end) => (&host[..=end], host[end + 1..].strip_prefix(':')),
            None => (host, None),
        };
    }
    match host.rsplit_once(':') {
        Some((name, port)) if !name.contains(':') => (name, Some(port)),
        _ => (host, None),
    }
}

fn refused(status: Status) -> Response {
    HttpError::from(status).into_response()
}

/// The layer: a request from another site is refused (403), one with a
/// body that is not JSON too (415); an allowed page's answer says it may
/// read it (`Access-Control-Allow-Origin`).
pub async fn check(State(site): State<Arc<Site>>, request: Request, next: Next) -> Response {
    if is_grpc(&request) {
        return next.run(request).await;
    }
    // HTTP/1 names its host in `Host`, HTTP/2 in the URI's authority.
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned)
        .or_else(|| request.uri().authority().map(|a| a.as_str().to_owned()));
    if site.check_host
        && let Some(host) = &host
        && !site.host_allowed(host)
    {
        return refused(Status::permission_denied(format!(
            "host '{}' is not this reliefd's (listening on {}): a page reached it under another name; \
             give reliefd --allow-host NAME to serve that name",
            relief_source::echo::echoed(host),
            site.listen.map_or_else(String::new, |l| l.to_string())
        )));
    }
    let origin = request.headers().get(header::ORIGIN).filter(|v| v.as_bytes() != b"null").cloned();
    if let Some(origin) = origin.as_ref().and_then(|v| v.to_str().ok())
        && !site.origin_allowed(origin, host.as_deref())
    {
        return refused(Status::permission_denied(format!(
            "a page from {} may not call this reliefd; give reliefd --allow-origin {} to let it",
            relief_source::echo::echoed(origin),
            relief_source::echo::echoed(origin)
        )));
    }
    // A page that sends a token in a header asks first (a preflight): the
    // standard tiles, which only read, grant it to an allowed page; no
    // other route does.
    if *request.method() == Method::OPTIONS
        && request.uri().path().starts_with("/tiles/")
        && let Some(origin) = origin.clone()
        && request.headers().get(header::ACCESS_CONTROL_REQUEST_METHOD).is_some_and(|m| m.as_bytes() == b"GET")
    {
        let headers = [
            (header::ACCESS_CONTROL_ALLOW_ORIGIN, origin),
            (header::ACCESS_CONTROL_ALLOW_METHODS, header::HeaderValue::from_static("GET")),
            (header::ACCESS_CONTROL_ALLOW_HEADERS, header::HeaderValue::from_static("authorization, accept")),
            (header::ACCESS_CONTROL_MAX_AGE, header::HeaderValue::from_static("600")),
            (header::VARY, header::HeaderValue::from_static("Origin")),
        ];
        return (axum::http::StatusCode::NO_CONTENT, axum::http::HeaderMap::from_iter(headers)).into_response();
    }
    if matches!(*request.method(), Method::POST | Method::PUT | Method::PATCH) {
        let json = request
            .headers()
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.split(';').next())
            .is_some_and(|v| v.trim().eq_ignore_ascii_case("application/json"));
        if !json {
            let status = Status::invalid_argument(
                "the body must be JSON sent as 'content-type: application/json' (an empty body is '{}')",
            );
            let mut response = refused(status);
            *response.status_mut() = axum::http::StatusCode::UNSUPPORTED_MEDIA_TYPE;
            return response;
        }
    }
    let mut response = next.run(request).await;
    // A page the daemon lets call may read the answer (CORS), and the
    // standard tiles' cache headers.
    if let Some(origin) = origin {
        let headers = response.headers_mut();
        headers.insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, origin);
        headers.append(header::VARY, header::HeaderValue::from_static("Origin"));
        headers.insert(
            header::ACCESS_CONTROL_EXPOSE_HEADERS,
            header::HeaderValue::from_static("etag, x-relief-version, x-relief-generation"),
        );
    }
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    fn site(listen: &str, hosts: &[&str], origins: &[&str]) -> Site {
        Site {
            listen: listen.parse().ok(),
            check_host: true,
            hosts: hosts.iter().map(|s| (*s).to_owned()).collect(),
            origins: origins.iter().map(|s| (*s).to_owned()).collect(),
        }
    }

    #[test]
    fn hosts_are_this_daemons_or_named() {
        let local = site("127.0.0.1:50051", &[], &[]);
        for host in ["127.0.0.1:50051", "localhost:50051", "LOCALHOST", "[::1]:50051", "127.0.0.1"] {
            assert!(local.host_allowed(host), "{host}");
        }
        for host in ["evil.example:50051", "10.0.0.2:50051", "rebind.example"] {
            assert!(!local.host_allowed(host), "{host}");
        }
        let named = site("127.0.0.1:50051", &["relief.example.org"], &[]);
        assert!(named.host_allowed("relief.example.org:50051"));
        let lan = site("10.0.0.2:443", &[], &[]);
        assert!(lan.host_allowed("10.0.0.2:443") && !lan.host_allowed("localhost:443"));
        assert!(site("0.0.0.0:443", &[], &[]).host_allowed("192.168.1.9:443"));
    }

    #[test]
    fn origins_are_this_daemons_own_or_named() {
        let local = site("127.0.0.1:50051", &[], &["https://maps.example.org"]);
        assert!(local.origin_allowed("http://127.0.0.1:50051", Some("127.0.0.1:50051")));
        assert!(local.origin_allowed("https://maps.example.org", Some("127.0.0.1:50051")));
        assert!(!local.origin_allowed("https://evil.example", Some("127.0.0.1:50051")));
        assert!(!local.origin_allowed("http://127.0.0.1:9999", Some("127.0.0.1:50051")));
    }

    #[test]
    fn ports_split_from_names_and_addresses() {
        assert_eq!(split_port("a.example:80"), ("a.example", Some("80")));
        assert_eq!(split_port("[::1]:80"), ("[::1]", Some("80")));
        assert_eq!(split_port("[::1]"), ("[::1]", None));
        assert_eq!(split_port("a.example"), ("a.example", None));
    }
}
