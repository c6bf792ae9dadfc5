//! A small static HTTP server on loopback for the test pages that read
//! reliefd as a third party would (CesiumJS, MapLibre GL JS): folders and
//! files mounted under URL prefixes, GET only, one connection per request.
//! It serves a page from another origin than reliefd's, as a real site
//! would, so reliefd's CORS answers are part of what the pages test.

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;

/// A running server; dropping it stops it.
pub struct Pages {
    pub addr: SocketAddr,
    stop: Arc<AtomicBool>,
}

impl Pages {
    /// Serves each `(prefix, path)`: a prefix ending in `/` maps to a
    /// folder (`/cesium/` to `.../Build/Cesium`), any other to one file.
    pub fn start(mounts: Vec<(String, PathBuf)>) -> anyhow::Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0").context("cannot listen on loopback")?;
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let (mounts, stopped) = (Arc::new(mounts), Arc::clone(&stop));
        std::thread::Builder::new().name("pages-accept".into()).spawn(move || {
            for stream in listener.incoming() {
                if stopped.load(Ordering::Relaxed) {
                    break;
                }
                let Ok(stream) = stream else { continue };
                let mounts = Arc::clone(&mounts);
                let _ = std::thread::Builder::new().name("pages-request".into()).spawn(move || {
                    let _ = answer(stream, &mounts);
                });
            }
        })?;
        Ok(Self { addr, stop })
    }

    /// `http://127.0.0.1:PORT` followed by `path`.
    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }
}

impl Drop for Pages {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Wake the accept loop so it sees the flag.
        let _ = TcpStream::connect(self.addr);
    }
}

fn answer(stream: TcpStream, mounts: &[(String, PathBuf)]) -> anyhow::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request = String::new();
    reader.read_line(&mut request)?;
    loop {
        let mut header = String::new();
        if reader.read_line(&mut header)? == 0 || header.trim().is_empty() {
            break;
        }
    }
    let mut words = request.split_whitespace();
    let (method, target) = (words.next().unwrap_or(""), words.next().unwrap_or("/"));
    let path = percent_decoded(target.split(['?', '#']).next().unwrap_or("/"));
    let found = if method == "GET" { resolve(mounts, &path) } else { None };
    let mut out = stream;
    match found.and_then(|file| std::fs::read(&file).ok().map(|body| (file, body))) {
        Some((file, body)) => {
            let head = format!(
                "HTTP/1.1 200 OK\r\ncontent-type: {}\r\ncontent-length: {}\r\ncache-control: no-store\r\nconnection: close\r\n\r\n",
                content_type(&file),
                body.len()
            );
            out.write_all(head.as_bytes())?;
            out.write_all(&body)?;
        }
        None => {
            let body = format!("not found: {path}");
            let head = format!(
                "HTTP/1.1 404 Not Found\r\ncontent-type: text/plain\r\ncontent-length: {}\r\nconnection: close\r\n\r\n",
                body.len()
            );
            out.write_all(head.as_bytes())?;
            out.write_all(body.as_bytes())?;
        }
    }
    out.flush()?;
    Ok(())
}

/// The file `path` names under the mounts; None outside them (`..` never
/// leaves a folder).
fn resolve(mounts: &[(String, PathBuf)], path: &str) -> Option<PathBuf> {
    for (prefix, target) in mounts {
        if prefix.ends_with('/') {
            let Some(rest) = path.strip_prefix(prefix.as_str()) else { continue };
            let rest = Path::new(rest);
            if rest.components().any(|c| !matches!(c, Component::Normal(_))) {
                return None;
            }
            let file = target.join(rest);
            if file.is_file() {
                return Some(file);
            }
        } else if path == prefix {
            return Some(target.clone());
        }
    }
    None
}

fn percent_decoded(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok());
        match (bytes[i], hex.and_then(|h| u8::from_str_radix(h, 16).ok())) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (b, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn content_type(file: &Path) -> &'static str {
    match file.extension().and_then(|e| e.to_str()).unwrap_or("") {
        "html" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "json" | "map" => "application/json",
        "wasm" => "application/wasm",
        "png" => "image/png",
        "jpg" | "jpeg" => "image/jpeg",
        "svg" => "image/svg+xml",
        "glb" => "model/gltf-binary",
        "ktx2" => "image/ktx2",
        "xml" => "application/xml",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_mount_never_leaves_its_folder() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.js"), "x").unwrap();
        let mounts = vec![("/m/".to_owned(), dir.path().to_path_buf())];
        assert_eq!(resolve(&mounts, "/m/a.js"), Some(dir.path().join("a.js")));
        assert_eq!(resolve(&mounts, "/m/../m/a.js"), None);
        assert_eq!(resolve(&mounts, "/m/b.js"), None);
        assert_eq!(percent_decoded("/a%20b%zz"), "/a b%zz");
    }
}
