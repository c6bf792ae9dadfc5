//! What the security tests share: a token file with two read tokens and a
//! control token, a gRPC request carrying a bearer token, and how long the
//! daemon takes to close a connection that sends a byte a second.

use std::io::{Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

pub const READ: &str = "read-0123456789abcdef";
/// A second read token: views opened with `READ` are not its to steer.
pub const OTHER_READ: &str = "read-fedcba9876543210";
pub const CONTROL: &str = "control-0123456789abcdef";

/// Writes `tokens` in `dir` with the three tokens above; its path.
pub fn token_file(dir: &Path) -> anyhow::Result<String> {
    let path = dir.join("tokens");
    std::fs::write(&path, format!("# who may call\nread {READ}\nread {OTHER_READ}\ncontrol {CONTROL}\n"))?;
    Ok(path.display().to_string())
}

/// `message` with `authorization: Bearer token`, when there is one.
pub fn with_token<T>(message: T, token: Option<&str>) -> anyhow::Result<tonic::Request<T>> {
    let mut r = tonic::Request::new(message);
    if let Some(t) = token {
        r.metadata_mut().insert("authorization", format!("Bearer {t}").parse()?);
    }
    Ok(r)
}

/// How long until the server ends a connection that sends `bytes` one a
/// second (the stream's reads time out after a second: the drip's pace):
/// None when it was still open at `limit`.
pub fn seconds_until_closed(stream: &mut (impl Read + Write), bytes: &[u8], limit: Duration) -> Option<f64> {
    let start = Instant::now();
    let mut sent = 0;
    let mut buffer = [0u8; 4096];
    while start.elapsed() < limit {
        if sent < bytes.len() && stream.write_all(&bytes[sent..=sent]).and_then(|()| stream.flush()).is_err() {
            return Some(start.elapsed().as_secs_f64());
        }
        sent += 1;
        // The read times out after a second: the drip's pace.
        match stream.read(&mut buffer) {
            Ok(0) => return Some(start.elapsed().as_secs_f64()),
            // An answer (408, say) before the close.
            Ok(_) => {}
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => return Some(start.elapsed().as_secs_f64()),
        }
    }
    None
}
