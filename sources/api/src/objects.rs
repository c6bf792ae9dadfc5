//! Sources on object storage: how relief names an object, and how the
//! rest of relief learns an object's version without knowing how objects
//! are read.
//!
//! A manifest names an object as `s3://bucket/key` or `https://host/path`;
//! relief holds it as the path GDAL reads it by (`/vsis3/bucket/key`,
//! `/vsicurl/https://host/path`), so every place that passes paths around
//! passes objects too. An object's version (its ETag, size and
//! Last-Modified) stands where a file's stamp does (`files::FileStamp`):
//! the crate that reads objects (relief-source-gdal, through GDAL's HTTP)
//! installs the function that asks for it, once per process.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// GDAL's prefix for an S3 object.
pub const S3: &str = "/vsis3/";
/// GDAL's prefix for a plain HTTP(S) object.
pub const HTTP: &str = "/vsicurl/";

/// One object's version as the store reports it.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ObjectVersion {
    pub etag: String,
    pub len: u64,
    /// Last-Modified, in seconds since 1970, when the store says.
    pub modified: Option<u64>,
}

/// Asks the store for an object's version: `fresh` asks it now, else an
/// answer the reader holds may do. The error says why the object cannot be
/// reached (missing, refused, the store down), without secrets.
pub type VersionOf = fn(&Path, bool) -> Result<ObjectVersion, String>;

static VERSION_OF: OnceLock<VersionOf> = OnceLock::new();

/// Installs the function that asks for objects' versions (once; a second
/// call is ignored).
pub fn set_version_of(f: VersionOf) {
    let _installed_already = VERSION_OF.set(f);
}

/// The version of the object at `path`, as last asked (`fresh`: asked now),
/// or why it cannot be had.
pub fn version(path: &Path, fresh: bool) -> Result<ObjectVersion, String> {
    match VERSION_OF.get() {
        Some(f) => f(path, fresh),
        None => Err("this build of relief reads no objects".to_owned()),
    }
}

/// True when `path` names an object (in GDAL's form), not a local file.
pub fn is_object(path: &Path) -> bool {
    path.to_str().is_some_and(|p| p.starts_with(S3) || p.starts_with(HTTP))
}

/// GDAL's form of a manifest's object URL (`s3://b/k` is `/vsis3/b/k`,
/// `https://h/p` is `/vsicurl/https://h/p`); None for anything else.
pub fn from_url(url: &str) -> Option<PathBuf> {
    if let Some(rest) = url.strip_prefix("s3://") {
        let (bucket, key) = rest.split_once('/')?;
        return (!bucket.is_empty() && !key.is_empty()).then(|| PathBuf::from(format!("{S3}{bucket}/{key}")));
    }
    let lower = url.get(..8).map(str::to_ascii_lowercase).unwrap_or_default();
    (lower.starts_with("https://") || lower.starts_with("http://")).then(|| PathBuf::from(format!("{HTTP}{url}")))
}

/// GDAL's form of a `[scene] roots` URL: a bucket (`s3://bucket`), a
/// prefix in one (`s3://bucket/dems/`) or a host's (`https://host/dems`),
/// always ending in `/` so a root matches whole names only (`dems/` is not
/// a prefix of `dems2/`). None for anything else.
pub fn root_from_url(url: &str) -> Option<PathBuf> {
    let gdal = if let Some(rest) = url.strip_prefix("s3://") {
        let bucket = rest.split('/').next().filter(|b| !b.is_empty())?;
        format!("{S3}{}", if rest.len() > bucket.len() { rest.to_owned() } else { format!("{bucket}/") })
    } else {
        let lower = url.get(..8).map(str::to_ascii_lowercase).unwrap_or_default();
        if !(lower.starts_with("https://") || lower.starts_with("http://")) {
            return None;
        }
        format!("{HTTP}{}", without_query(url))
    };
    Some(PathBuf::from(if gdal.ends_with('/') { gdal } else { format!("{gdal}/") }))
}

/// The object's URL as a user wrote it (`s3://bucket/key`, `https://...`),
/// with any query string (a presigned URL's signature) left out; None for
/// a local path.
pub fn shown(path: &Path) -> Option<String> {
    let p = path.to_str()?;
    let url =
        if let Some(rest) = p.strip_prefix(S3) { format!("s3://{rest}") } else { p.strip_prefix(HTTP)?.to_owned() };
    Some(without_query(&url).to_owned())
}

/// How a path is named to a user: an object by its URL (`shown`), a file
/// by its path.
pub fn display(path: &Path) -> String {
    shown(path).unwrap_or_else(|| path.display().to_string())
}

/// `url` without its query string and fragment.
pub fn without_query(url: &str) -> &str {
    url.split(['?', '#']).next().unwrap_or(url)
}

/// The place objects under `path` share for the guard's purposes: the
/// bucket (`/vsis3/bucket/`) or the origin (`/vsicurl/https://host/`).
pub fn root_of(path: &Path) -> Option<String> {
    let p = path.to_str()?;
    if let Some(rest) = p.strip_prefix(S3) {
        let bucket = rest.split('/').next().filter(|b| !b.is_empty())?;
        return Some(format!("{S3}{bucket}/"));
    }
    let rest = p.strip_prefix(HTTP)?;
    let (scheme, after) = rest.split_once("://")?;
    let host = after.split('/').next().filter(|h| !h.is_empty())?;
    Some(format!("{HTTP}{scheme}://{host}/"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_become_gdal_paths_and_back() {
        assert_eq!(from_url("s3://dem/alps/n43.tif"), Some(PathBuf::from("/vsis3/dem/alps/n43.tif")));
        assert_eq!(
            from_url("https://data.example/cop/dem.tif"),
            Some(PathBuf::from("/vsicurl/https://data.example/cop/dem.tif"))
        );
        assert_eq!(from_url("s3://bucket-only"), None);
        assert_eq!(from_url("s3:///key"), None);
        assert_eq!(from_url("/data/dem.tif"), None);
        assert_eq!(from_url("ftp://x/y"), None);
        let object = from_url("s3://dem/n43.tif").unwrap_or_default();
        assert!(is_object(&object));
        assert!(!is_object(Path::new("/data/dem.tif")));
        assert_eq!(shown(&object).as_deref(), Some("s3://dem/n43.tif"));
        let signed = from_url("https://h.example/d.tif?X-Amz-Signature=secret").unwrap_or_default();
        assert_eq!(shown(&signed).as_deref(), Some("https://h.example/d.tif"));
        assert_eq!(root_of(&object).as_deref(), Some("/vsis3/dem/"));
        assert_eq!(root_of(&signed).as_deref(), Some("/vsicurl/https://h.example/"));
        assert_eq!(root_of(Path::new("/data/dem.tif")), None);
        assert_eq!(root_from_url("s3://dem"), Some(PathBuf::from("/vsis3/dem/")));
        assert_eq!(root_from_url("s3://dem/alps"), Some(PathBuf::from("/vsis3/dem/alps/")));
        assert_eq!(root_from_url("https://h.example/cop/"), Some(PathBuf::from("/vsicurl/https://h.example/cop/")));
        assert_eq!(root_from_url("s3://"), None);
        assert_eq!(root_from_url("tiles"), None);
    }
}
