//! Rasters and vector data on object storage: an S3-compatible store
//! (`s3://bucket/key`, read as GDAL's `/vsis3/`) or a plain HTTP(S)
//! server with range requests (`https://host/path`, GDAL's `/vsicurl/`).
//!
//! GDAL does the reading, configured as COG servers configure it
//! (`config`): no listing of an object's "folder" on open, consecutive
//! ranges merged into one request, a bounded cache of ranges. This module
//! adds what relief needs on top:
//! - an object's version (ETag, size, Last-Modified) as its file stamp,
//!   asked of the server only when the watcher polls or a notice names it
//!   (`version`), so the stamps compared around every read cost nothing;
//! - range reads of an object's bytes for relief's own TIFF reader
//!   (`RangeFile`), so a reload reads the block tables and the changed
//!   blocks only, and the bytes read are counted (`bytes_read`);
//! - error messages with no secret in them (`redact`).

mod config;
mod ranged;
mod vsi;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{LazyLock, Mutex, PoisonError};

use relief_source::objects::{ObjectVersion, is_object};

pub use config::{Storage, configure_storage, redact};
pub use ranged::{RangeFile, bytes_read};

/// GDAL told, on this thread while it lives, that an object's folder is
/// empty (`GDAL_DISABLE_READDIR_ON_OPEN=EMPTY_DIR`): it then neither lists
/// it nor asks for side objects. Local files keep GDAL's side files.
pub struct EmptyFolder;

impl EmptyFolder {
    pub fn set() -> Self {
        let _unknown_option_is_harmless =
            gdal::config::set_thread_local_config_option("GDAL_DISABLE_READDIR_ON_OPEN", "EMPTY_DIR");
        Self
    }
}

impl Drop for EmptyFolder {
    fn drop(&mut self) {
        let _unknown_option_is_harmless =
            gdal::config::clear_thread_local_config_option("GDAL_DISABLE_READDIR_ON_OPEN");
    }
}

static VERSION_CHECKS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Versions asked of the stores since start (a request each).
pub fn version_checks() -> u64 {
    VERSION_CHECKS.load(std::sync::atomic::Ordering::Relaxed)
}

/// Versions as last asked of the servers.
fn known() -> std::sync::MutexGuard<'static, HashMap<PathBuf, ObjectVersion>> {
    static KNOWN: LazyLock<Mutex<HashMap<PathBuf, ObjectVersion>>> = LazyLock::new(Mutex::default);
    KNOWN.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The object's version: the one last asked unless `fresh` (or never
/// asked), else asked of the server now, after GDAL forgets what it held
/// of the object (a changed object is then read anew). Installed as
/// `relief_source::objects::version`.
pub fn version(path: &Path, fresh: bool) -> Result<ObjectVersion, String> {
    if !is_object(path) {
        return Err("not an object".to_owned());
    }
    if !fresh && let Some(v) = known().get(path) {
        return Ok(v.clone());
    }
    vsi::forget(path);
    VERSION_CHECKS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let asked = vsi::headers(path).map_err(|e| describe(&e)).and_then(|headers| {
        let find = |name: &str| headers.iter().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v.clone());
        let len = find("Content-Range")
            .and_then(|r| r.rsplit_once('/').and_then(|(_, total)| total.parse().ok()))
            .or_else(|| find("Content-Length").and_then(|l| l.parse().ok()))
            .ok_or_else(|| describe("the server gave no size"))?;
        let modified = find("Last-Modified")
            .and_then(|m| httpdate::parse_http_date(&m).ok())
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map(|d| d.as_secs());
        Ok(ObjectVersion { etag: find("ETag").unwrap_or_default(), len, modified })
    });
    let mut known = known();
    match &asked {
        Ok(v) => {
            known.insert(path.to_path_buf(), v.clone());
        }
        Err(_) => {
            known.remove(path);
        }
    }
    asked
}

/// What went wrong with an object, in words a user can act on: GDAL's or
/// the server's message, secrets removed, with what an HTTP status means.
/// (The error it goes into names the object's URL.)
pub fn describe(why: &str) -> String {
    let why = redact(why);
    let status = why.rsplit_once(": ").map(|(_, code)| code.trim());
    let meaning = match status {
        Some("0") => " (no answer: the store is down or cannot be reached)",
        Some("401" | "403") => " (access denied: the credentials were refused or may not read it)",
        Some("404") => " (not found)",
        Some(code) if code.starts_with('5') && code.len() == 3 => {
            " (the store failed; it is asked again at the next poll)"
        }
        _ => "",
    };
    format!("{why}{meaning}")
}
