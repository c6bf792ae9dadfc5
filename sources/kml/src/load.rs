//! Reading a .kml or a .kmz safely into the kml crate's tree.

use std::io::Read;
use std::path::Path;

use kml::Kml;
use relief_source::SourceError;

/// What a KML source will read at most.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Bytes of KML text, after inflation.
    pub max_kml_bytes: u64,
    /// Entries in a KMZ archive.
    pub max_entries: usize,
    /// Inflated size over compressed size for any KMZ entry.
    pub max_ratio: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self { max_kml_bytes: 64 << 20, max_entries: 10_000, max_ratio: 200 }
    }
}

fn format(message: impl Into<String>, path: &Path) -> SourceError {
    SourceError::format(message, path)
}

/// The KML text of a .kml file, or of the document inside a .kmz.
pub(crate) fn text(path: &Path, limits: &Limits) -> Result<String, SourceError> {
    let io = |source| SourceError::Io { what: "kml", path: path.to_path_buf(), source };
    let is_kmz = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("kmz"));
    let bytes = if is_kmz {
        let file = std::fs::File::open(path).map_err(io)?;
        let mut zip = zip::ZipArchive::new(file).map_err(|e| format(format!("not a KMZ (zip) archive: {e}"), path))?;
        if zip.len() > limits.max_entries {
            return Err(format(
                format!("KMZ has {} entries, more than the limit of {}", zip.len(), limits.max_entries),
                path,
            ));
        }
        // The document is doc.kml, or else the first .kml at the root, as Google Earth reads it.
        let names: Vec<String> = zip.file_names().map(str::to_owned).collect();
        let doc = names
            .iter()
            .find(|n| n.eq_ignore_ascii_case("doc.kml"))
            .or_else(|| names.iter().find(|n| !n.contains('/') && n.to_ascii_lowercase().ends_with(".kml")))
            .or_else(|| names.iter().find(|n| n.to_ascii_lowercase().ends_with(".kml")))
            .ok_or_else(|| format("KMZ holds no .kml document", path))?
            .clone();
        let mut entry = zip.by_name(&doc).map_err(|e| format(format!("cannot read '{doc}' in the KMZ: {e}"), path))?;
        let (size, packed) = (entry.size(), entry.compressed_size().max(1));
        if size > limits.max_kml_bytes || size / packed > limits.max_ratio {
            return Err(format(
                format!(
                    "KMZ entry '{doc}' inflates to {size} bytes from {packed} (limits: {} bytes, ratio {}): refused as a zip bomb",
                    limits.max_kml_bytes, limits.max_ratio
                ),
                path,
            ));
        }
        // The header's size may lie: never inflate past the limit.
        let mut bytes = Vec::new();
        entry
            .by_ref()
            .take(limits.max_kml_bytes + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| format(format!("cannot inflate '{doc}': {e}"), path))?;
        if bytes.len() as u64 > limits.max_kml_bytes {
            return Err(format(
                format!("KMZ entry '{doc}' inflates past {} bytes: refused as a zip bomb", limits.max_kml_bytes),
                path,
            ));
        }
        bytes
    } else {
        let len = std::fs::metadata(path).map_err(io)?.len();
        if len > limits.max_kml_bytes {
            return Err(format(format!("KML is {len} bytes, more than the limit of {}", limits.max_kml_bytes), path));
        }
        std::fs::read(path).map_err(io)?
    };
    let text = String::from_utf8(bytes).map_err(|_| format("KML is not UTF-8 text", path))?;
    // Entity declarations are how billion-laughs documents expand; KML has
    // no use for them.
    if text.contains("<!ENTITY") {
        return Err(format(
            "KML declares XML entities (<!ENTITY>): refused, they are how entity-expansion attacks work",
            path,
        ));
    }
    Ok(text)
}

/// The parsed document.
pub(crate) fn parse(text: &str, path: &Path) -> Result<Kml, SourceError> {
    let text = tighten_coordinates(text);
    kml::KmlReader::<_, f64>::from_string(&text).read().map_err(|e| format(format!("malformed KML: {e}"), path))
}

/// Inside `<coordinates>`, tuples are separated by whitespace and their
/// parts by commas; writers that put a space after a comma ("19, 37") are
/// common enough (Google's own samples) to read them as meant.
fn tighten_coordinates(text: &str) -> std::borrow::Cow<'_, str> {
    const OPEN: &str = "<coordinates>";
    const CLOSE: &str = "</coordinates>";
    if !text.contains(", ") && !text.contains(",\t") {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find(OPEN) {
        let body_start = start + OPEN.len();
        let Some(len) = rest[body_start..].find(CLOSE) else { break };
        out.push_str(&rest[..body_start]);
        let body = &rest[body_start..body_start + len];
        let mut after_comma = false;
        for c in body.chars() {
            if after_comma && c.is_whitespace() {
                continue;
            }
            after_comma = c == ',';
            out.push(c);
        }
        rest = &rest[body_start + len..];
    }
    out.push_str(rest);
    std::borrow::Cow::Owned(out)
}
