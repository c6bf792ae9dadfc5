//! What a connection may hold of the daemon, before and after it shows a
//! token: at most [`Limits::global`] connections at once, and
//! [`Limits::per_address`] from one address (loopback excepted: its
//! callers are this machine's users); a first request within
//! [`Limits::first_request`] of the connection (after TLS's handshake);
//! an HTTP/1 request's headers within [`Limits::header_read`] (a client
//! sending them a byte at a time is closed); HTTP/2 pings every
//! [`Limits::ping`], the connection closed when one goes unanswered; and
//! a connection with no request or stream under way for [`Limits::idle`]
//! closed. A connection past a limit is closed at once.

use std::collections::HashMap;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::body::{Body, Bytes};
use hyper::body::{Frame, SizeHint};

/// The limits and deadlines of every connection.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub global: usize,
    pub per_address: usize,
    pub first_request: Duration,
    pub header_read: Duration,
    pub ping: Duration,
    pub idle: Duration,
}

impl Limits {
    pub const DEFAULT: Self = Self {
        global: 2048,
        per_address: 256,
        first_request: Duration::from_secs(10),
        header_read: Duration::from_secs(10),
        ping: Duration::from_secs(20),
        idle: Duration::from_secs(300),
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The connections open now, in all and by address.
pub struct Connections {
    limits: Limits,
    open: AtomicUsize,
    by_address: Mutex<HashMap<IpAddr, usize>>,
    refused: AtomicU64,
}

/// A connection let in: it counts until dropped.
///
/// Each request carries a [`Hold`] on it, so that a connection upgraded to
/// a WebSocket (whose serving outlives the HTTP connection's) keeps
/// counting while its socket lives.
pub struct Admitted {
    connections: Arc<Connections>,
    address: IpAddr,
}

impl Connections {
    pub fn new(limits: Limits) -> Arc<Self> {
        Arc::new(Self { limits, open: AtomicUsize::new(0), by_address: Mutex::default(), refused: AtomicU64::new(0) })
    }

    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// Lets a connection from `address` in, or says which limit it meets.
    pub fn admit(self: &Arc<Self>, address: IpAddr) -> Result<Admitted, String> {
        let mut by_address = self.by_address.lock().unwrap_or_else(PoisonError::into_inner);
        let from = by_address.get(&address).copied().unwrap_or(0);
        let refusal = if self.open.load(Ordering::Relaxed) >= self.limits.global {
            Some(format!("{} connections are open", self.limits.global))
        } else if !address.is_loopback() && from >= self.limits.per_address {
            Some(format!("{} connections are open from {address}", self.limits.per_address))
        } else {
            None
        };
        if let Some(why) = refusal {
            self.refused.fetch_add(1, Ordering::Relaxed);
            metrics::counter!("relief_connections_refused_total").increment(1);
            return Err(why);
        }
        by_address.insert(address, from + 1);
        self.open.fetch_add(1, Ordering::Relaxed);
        Ok(Admitted { connections: Arc::clone(self), address })
    }

    /// Connections open now, and refused since start.
    pub fn counts(&self) -> (usize, u64) {
        (self.open.load(Ordering::Relaxed), self.refused.load(Ordering::Relaxed))
    }
}

/// A request's hold on its connection's place among the connections.
#[derive(Clone)]
pub struct Hold(#[expect(dead_code, reason = "held, never read: it counts while it lives")] Arc<Admitted>);

impl Hold {
    pub fn new(admitted: Arc<Admitted>) -> Self {
        Self(admitted)
    }
}

impl Drop for Admitted {
    fn drop(&mut self) {
        let mut by_address = self.connections.by_address.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(n) = by_address.get_mut(&self.address) {
            *n -= 1;
            if *n == 0 {
                by_address.remove(&self.address);
            }
        }
        self.connections.open.fetch_sub(1, Ordering::Relaxed);
    }
}

/// What a connection is doing: requests made, and requests or response
/// bodies (streams) under way.
pub struct Activity {
    opened: Instant,
    requests: AtomicU64,
    under_way: AtomicUsize,
    /// When the last request or body began or ended.
    last: Mutex<Instant>,
}

/// A request or body under way: it counts until dropped.
pub struct UnderWay(Arc<Activity>);

impl Activity {
    pub fn new() -> Arc<Self> {
        let now = Instant::now();
        Arc::new(Self {
            opened: now,
            requests: AtomicU64::new(0),
            under_way: AtomicUsize::new(0),
            last: Mutex::new(now),
        })
    }

    fn touch(&self) {
        *self.last.lock().unwrap_or_else(PoisonError::into_inner) = Instant::now();
    }

    /// A request begins; it is under way until the guard is dropped (with
    /// the response's body, for a stream).
    pub fn begin(self: &Arc<Self>) -> UnderWay {
        self.requests.fetch_add(1, Ordering::Relaxed);
        self.under_way.fetch_add(1, Ordering::Relaxed);
        self.touch();
        UnderWay(Arc::clone(self))
    }

    /// Why the connection should be closed now, if it should: no first
    /// request in time, or idle for too long.
    pub fn overdue(&self, limits: &Limits) -> Option<&'static str> {
        if self.requests.load(Ordering::Relaxed) == 0 {
            return (self.opened.elapsed() > limits.first_request).then_some("no request in time");
        }
        let idle = self.under_way.load(Ordering::Relaxed) == 0
            && self.last.lock().unwrap_or_else(PoisonError::into_inner).elapsed() > limits.idle;
        idle.then_some("idle")
    }
}

impl Drop for UnderWay {
    fn drop(&mut self) {
        self.0.under_way.fetch_sub(1, Ordering::Relaxed);
        self.0.touch();
    }
}

/// A response body that holds `guard` while it is sent (a stream's whole
/// life).
pub struct Held<G> {
    body: Body,
    _guard: G,
}

impl<G: Send + Unpin + 'static> Held<G> {
    pub fn body(body: Body, guard: G) -> Body {
        Body::new(Self { body, _guard: guard })
    }
}

impl<G: Unpin> hyper::body::Body for Held<G> {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        Pin::new(&mut self.body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.body.size_hint()
    }
}

/// Whether a request came over TLS (its connection's), for the URLs an
/// answer names (a TileJSON's tiles).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Secure(pub bool);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connections_count_until_dropped_within_their_limits() {
        let limits = Limits { global: 3, per_address: 2, ..Limits::DEFAULT };
        let c = Connections::new(limits);
        let far: IpAddr = "10.0.0.9".parse().expect("an address");
        let (a, b) = (c.admit(far).ok(), c.admit(far).ok());
        assert!(a.is_some() && b.is_some());
        assert!(c.admit(far).is_err_and(|e| e.contains("from 10.0.0.9")));
        let local: IpAddr = "127.0.0.1".parse().expect("an address");
        let l = c.admit(local).ok();
        assert!(l.is_some(), "loopback is not held to the per-address limit");
        assert!(c.admit(local).is_err_and(|e| e.contains("3 connections are open")));
        drop(a);
        assert!(c.admit(far).is_ok());
        assert_eq!(c.counts().1, 2);
    }

    #[test]
    fn a_connection_is_overdue_without_a_first_request_or_idle() {
        let limits = Limits { first_request: Duration::ZERO, idle: Duration::ZERO, ..Limits::DEFAULT };
        let a = Activity::new();
        std::thread::sleep(Duration::from_millis(2));
        assert_eq!(a.overdue(&limits), Some("no request in time"));
        let call = a.begin();
        std::thread::sleep(Duration::from_millis(2));
        assert_eq!(a.overdue(&limits), None, "a request under way is not idle");
        drop(call);
        std::thread::sleep(Duration::from_millis(2));
        assert_eq!(a.overdue(&limits), Some("idle"));
    }
}
