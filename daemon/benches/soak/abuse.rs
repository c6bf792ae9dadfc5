//! Abusive connections for the soak: slowloris clients that send a
//! request's headers a byte a second, and idle ones that send nothing, each
//! opened again as soon as reliefd closes it (as an attacker's would be).
//! They count what reliefd did with them.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// Headers that never end.
const DRIP: &[u8] = b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ";

/// What the abusive connections saw.
#[derive(Default)]
pub struct Abuse {
    /// Connections opened, and those reliefd closed.
    pub opened: AtomicU64,
    pub closed: AtomicU64,
    /// Open now.
    pub open: AtomicI64,
    /// The longest any was held open, in milliseconds.
    pub longest_ms: AtomicU64,
}

impl Abuse {
    /// `slow` slowloris and `idle` silent connections to `addr`, opened a
    /// few a millisecond, until `stop`.
    pub fn start(
        addr: &str,
        slow: usize,
        idle: usize,
        stop: &Arc<AtomicBool>,
    ) -> (Arc<Self>, Vec<tokio::task::JoinHandle<()>>) {
        let abuse = Arc::new(Self::default());
        let tasks = (0..slow + idle)
            .map(|n| {
                let (addr, abuse, stop) = (addr.to_owned(), Arc::clone(&abuse), Arc::clone(stop));
                tokio::spawn(async move {
                    tokio::time::sleep(Duration::from_millis(n as u64 / 2)).await;
                    abuse.connection(&addr, n < slow, &stop).await;
                })
            })
            .collect();
        (abuse, tasks)
    }

    async fn connection(&self, addr: &str, slow: bool, stop: &AtomicBool) {
        let mut buffer = [0u8; 512];
        while !stop.load(Ordering::Relaxed) {
            let Ok(mut socket) = TcpStream::connect(addr).await else {
                tokio::time::sleep(Duration::from_millis(200)).await;
                continue;
            };
            self.opened.fetch_add(1, Ordering::Relaxed);
            self.open.fetch_add(1, Ordering::Relaxed);
            let opened = Instant::now();
            let mut sent = 0;
            let closed = loop {
                if stop.load(Ordering::Relaxed) {
                    break false;
                }
                if slow {
                    let byte = DRIP.get(sent).copied().unwrap_or(b'a');
                    if socket.write_all(&[byte]).await.is_err() {
                        break true;
                    }
                    sent += 1;
                }
                // An answer (a 408) is read on; an end or an error is the close.
                let read = tokio::time::timeout(Duration::from_secs(1), socket.read(&mut buffer)).await;
                if let Ok(Ok(0) | Err(_)) = read {
                    break true;
                }
            };
            self.open.fetch_sub(1, Ordering::Relaxed);
            let held = u64::try_from(opened.elapsed().as_millis()).unwrap_or(u64::MAX);
            self.longest_ms.fetch_max(held, Ordering::Relaxed);
            if closed {
                self.closed.fetch_add(1, Ordering::Relaxed);
                // Again at once, but not in a busy loop when refused at a cap.
                tokio::time::sleep(Duration::from_millis(if held < 1000 { 1000 } else { 10 })).await;
            }
        }
    }
}
