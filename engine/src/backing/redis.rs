//! Tiles in Redis, shared by replicas of one scene: `relief:tile:<address>`
//! holds a tile's record (`codec.rs`). Reads take a pooled connection on
//! the tile worker that asks; writes go through one background thread.
//! Redis down or slow: reads miss after the timeout, writes are dropped,
//! and the replica generates its own tiles.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::Duration;

use redis::Commands as _;

use super::Backing;

const TIMEOUT: Duration = Duration::from_millis(500);
const QUEUE: usize = 512;

pub struct RedisTiles {
    url: String,
    client: redis::Client,
    idle: Mutex<Vec<redis::Connection>>,
    writes: SyncSender<(u128, Vec<u8>)>,
    pub dropped: AtomicU64,
}

impl std::fmt::Debug for RedisTiles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RedisTiles({})", self.url)
    }
}

/// A Redis that cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("cannot use the shared tile cache at {url}: {message}")]
pub struct RedisError {
    url: String,
    message: String,
}

fn key(address: u128) -> String {
    format!("relief:tile:{address:032x}")
}

fn connect(client: &redis::Client) -> redis::RedisResult<redis::Connection> {
    let connection = client.get_connection_with_timeout(TIMEOUT)?;
    connection.set_read_timeout(Some(TIMEOUT))?;
    connection.set_write_timeout(Some(TIMEOUT))?;
    Ok(connection)
}

impl RedisTiles {
    /// Connects to `url` (`redis://host:port/db` or `unix:///path`) and
    /// checks it answers.
    pub fn open(url: &str) -> Result<Self, RedisError> {
        let fail = |e: redis::RedisError| RedisError { url: url.to_owned(), message: e.to_string() };
        let client = redis::Client::open(url).map_err(fail)?;
        let mut first = connect(&client).map_err(fail)?;
        let _: String = redis::cmd("PING").query(&mut first).map_err(fail)?;
        let (writes, rx) = sync_channel(QUEUE);
        let writer = client.clone();
        let url_for_thread = url.to_owned();
        std::thread::Builder::new()
            .name("relief-redis".into())
            .spawn(move || write_all(&writer, &url_for_thread, &rx))
            .map_err(|e| RedisError { url: url.to_owned(), message: e.to_string() })?;
        Ok(Self { url: url.to_owned(), client, idle: Mutex::new(vec![first]), writes, dropped: AtomicU64::new(0) })
    }
}

impl Backing for RedisTiles {
    fn name(&self) -> &'static str {
        "redis"
    }

    fn get(&self, address: u128) -> Option<Vec<u8>> {
        let pooled = self.idle.lock().ok().and_then(|mut idle| idle.pop());
        let mut connection = match pooled {
            Some(c) => c,
            None => connect(&self.client).ok()?,
        };
        let found: redis::RedisResult<Option<Vec<u8>>> = connection.get(key(address));
        match found {
            Ok(bytes) => {
                if let Ok(mut idle) = self.idle.lock() {
                    idle.push(connection);
                }
                bytes
            }
            Err(e) => {
                // A broken connection is dropped, not pooled.
                tracing::debug!(url = %self.url, "shared tile cache read failed: {e}");
                None
            }
        }
    }

    fn put(&self, address: u128, bytes: Vec<u8>) {
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = self.writes.try_send((address, bytes)) {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

fn write_all(client: &redis::Client, url: &str, rx: &Receiver<(u128, Vec<u8>)>) {
    let mut connection: Option<redis::Connection> = None;
    while let Ok((address, bytes)) = rx.recv() {
        if connection.is_none() {
            connection = connect(client).ok();
        }
        let Some(c) = connection.as_mut() else { continue };
        let written: redis::RedisResult<()> = c.set(key(address), bytes);
        if let Err(e) = written {
            tracing::debug!(%url, "shared tile cache write failed: {e}");
            connection = None;
        }
    }
}
