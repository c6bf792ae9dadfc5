//! Objects have no change notification: their versions are asked of the
//! store, every `[watch] poll_s` (a HEAD per object), or at once for the
//! objects an S3 event notice names (`POST /api/notify`). A source is read
//! again when one of its objects' versions changed, or the object became
//! unreachable (the read then fails, its error is shown, and the last good
//! version is kept) or reachable again.

use std::collections::{BTreeSet, HashMap};
use std::path::PathBuf;

use relief_source::files::FileStamp;
use relief_source::objects::{S3, is_object};

use crate::scene::Scene;

/// The objects the scene reads, and the sources that read each.
pub fn objects(scene: &Scene) -> HashMap<PathBuf, BTreeSet<String>> {
    let snap = scene.snapshot();
    let mut map: HashMap<PathBuf, BTreeSet<String>> = HashMap::new();
    for slot in &snap.slots {
        let mut files = slot.spec.paths.clone();
        if let Some(source) = &slot.source {
            files.extend(source.info().files);
        }
        for file in files.into_iter().filter(|f| is_object(f)) {
            map.entry(file).or_default().insert(slot.spec.id.clone());
        }
    }
    map
}

/// What a poll last found of each object: its stamp, or None (unreachable).
#[derive(Debug, Default)]
pub struct Polled(HashMap<PathBuf, Option<FileStamp>>);

impl Polled {
    /// Asks the store for the version of every object the scene reads;
    /// the sources of those whose answer changed since the last poll (the
    /// first poll compares with what the sources read).
    pub fn changed(&mut self, scene: &Scene) -> BTreeSet<String> {
        let mut out = BTreeSet::new();
        let objects = objects(scene);
        self.0.retain(|path, _| objects.contains_key(path));
        for (path, sources) in objects {
            let before = match self.0.get(&path) {
                Some(seen) => *seen,
                None => FileStamp::of(&path),
            };
            let now = relief_source::objects::version(&path, true).ok().map(|v| FileStamp::object(&v));
            if now != before {
                tracing::debug!(object = %relief_source::objects::display(&path), "object changed");
                out.extend(sources);
            }
            self.0.insert(path, now);
        }
        out
    }
}

/// The sources reading any of `named` (objects, or their `s3://` URLs),
/// each object's version asked anew; an S3 event names objects by bucket
/// and key, so every object of the scene whose key it names is matched.
pub fn noticed(scene: &Scene, named: &[PathBuf]) -> BTreeSet<String> {
    let objects = objects(scene);
    let mut out = BTreeSet::new();
    for path in named {
        if let Some(sources) = objects.get(path) {
            let _asked = relief_source::objects::version(path, true);
            out.extend(sources.iter().cloned());
        }
    }
    out
}

/// An S3 event notification's objects (the JSON S3, MinIO and others send
/// to a webhook: `Records[].s3.bucket.name` and `.s3.object.key`, the key
/// URL-encoded), as GDAL names them (`/vsis3/bucket/key`).
pub fn event_objects(event: &serde_json::Value) -> Result<Vec<PathBuf>, String> {
    let records = event
        .get("Records")
        .and_then(serde_json::Value::as_array)
        .ok_or("not an S3 event notification: no \"Records\" list")?;
    let mut out = Vec::new();
    for (n, record) in records.iter().enumerate() {
        let s3 = record.get("s3").ok_or_else(|| format!("record {n} has no \"s3\" part"))?;
        let bucket = s3
            .pointer("/bucket/name")
            .and_then(serde_json::Value::as_str)
            .ok_or_else(|| format!("record {n} names no bucket (s3.bucket.name)"))?;
        let key = s3
            .pointer("/object/key")
            .and_then(serde_json::Value::as_str)
            .ok_or_else(|| format!("record {n} names no object (s3.object.key)"))?;
        out.push(PathBuf::from(format!("{S3}{bucket}/{}", url_decoded(key))));
    }
    Ok(out)
}

/// An S3 event's key as stored: `+` is a space, `%XX` a byte.
fn url_decoded(key: &str) -> String {
    let hex = |b: u8| char::from(b).to_digit(16).and_then(|d| u8::try_from(d).ok());
    let bytes = key.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let escaped =
            (bytes[i] == b'%').then(|| Some(hex(*bytes.get(i + 1)?)? * 16 + hex(*bytes.get(i + 2)?)?)).flatten();
        match (bytes[i], escaped) {
            (_, Some(b)) => {
                out.push(b);
                i += 3;
            }
            (b'+', None) => {
                out.push(b' ');
                i += 1;
            }
            (b, None) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_s3_event_names_its_objects() {
        let event = serde_json::json!({"Records": [
            {"eventName": "ObjectCreated:Put", "s3": {"bucket": {"name": "dem"}, "object": {"key": "alps/N43+E007%2B1.tif", "eTag": "x"}}},
            {"s3": {"bucket": {"name": "other"}, "object": {"key": "a.tif"}}}
        ]});
        assert_eq!(
            event_objects(&event).ok(),
            Some(vec![PathBuf::from("/vsis3/dem/alps/N43 E007+1.tif"), PathBuf::from("/vsis3/other/a.tif")])
        );
        assert!(event_objects(&serde_json::json!({"hello": 1})).unwrap_err().contains("Records"));
        let no_key = serde_json::json!({"Records": [{"s3": {"bucket": {"name": "b"}, "object": {}}}]});
        assert!(event_objects(&no_key).unwrap_err().contains("s3.object.key"));
        assert_eq!(url_decoded("100%"), "100%");
    }
}
