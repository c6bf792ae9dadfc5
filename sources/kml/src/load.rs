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
        let file = relief_source::regular::open_regular(path).map_err(io)?;
        let mut zip = zip::ZipArchive::new(file)
            .map_err(|e| format(format!("not a KMZ (zip) archive: {}", unzip_error(&e)), path))?;
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
        let mut entry = zip
            .by_name(&doc)
            .map_err(|e| format(format!("cannot read '{doc}' in the KMZ: {}", unzip_error(&e)), path))?;
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
            .map_err(|e| format(format!("cannot inflate '{doc}': {}", lower_first(&e.to_string())), path))?;
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
        relief_source::regular::read_regular(path).map_err(io)?
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

/// The stack of the thread that runs the kml crate's parser. It reads
/// nesting by recursion, tens of kilobytes of stack for each level of
/// folders (a 2 MiB thread overflows at about 40, aborting the process);
/// this holds `tidy`'s limit of nesting with room to spare.
const PARSE_STACK_BYTES: usize = 64 << 20;

/// The parsed document, from text `tidy` made ready for the kml crate.
pub(crate) fn parse(text: &str, path: &Path) -> Result<Kml, SourceError> {
    let parsed = std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("kml-parse".into())
            .stack_size(PARSE_STACK_BYTES)
            .spawn_scoped(scope, || kml::KmlReader::<_, f64>::from_string(text).read())
            .map(std::thread::ScopedJoinHandle::join)
    });
    match parsed {
        Ok(Ok(Ok(kml))) => Ok(kml),
        Ok(Ok(Err(e))) => {
            let why = match e {
                kml::Error::InvalidXmlEvent(_) => crate::tidy::markup_in_value(text).unwrap_or_else(|| explain(&e)),
                e => explain(&e),
            };
            Err(format(format!("malformed KML: {why}"), path))
        }
        // The tidy pass leaves nothing known to make the kml crate panic;
        // if something unknown does, the file is refused, not the process.
        Ok(Err(_)) => Err(format(format!("malformed KML: {PARSER_FAILED}"), path)),
        Err(e) => Err(SourceError::Io { what: "kml (no thread to parse it on)", path: path.to_path_buf(), source: e }),
    }
}

/// What a parse that panicked is reported as.
const PARSER_FAILED: &str = "the kml parser failed on this file (a bug in relief: please report it)";

/// The kml crate's errors as sentences: some of its messages carry Rust
/// `Debug` output of XML events, never shown to a user.
fn explain(e: &kml::Error) -> String {
    use kml::Error as E;
    let quoted = |s: &str| s.chars().take(40).collect::<String>();
    match e {
        E::InvalidInput(s) if s.contains("\"name\"") => "a <SimpleData> or <SimpleArrayData> has no name".into(),
        E::InvalidInput(_) => "unexpected XML content".into(),
        E::MalformedXml(e) => e.to_string(),
        E::InvalidXmlEvent(_) => "an element that holds a value holds markup".into(),
        E::CoordEmpty => "a coordinate tuple has fewer than two numbers".into(),
        E::NoElements => "no KML elements found".into(),
        E::NumParse(s) => format!("'{}' is not a number, where KML expects one", quoted(s)),
        E::InvalidKmlVersion(s) => format!("unknown KML version '{}'", quoted(s)),
        E::InvalidKmlElement(s) => format!("unknown KML element '{}'", quoted(s)),
        E::InvalidGeometry(_) => "a polygon has no outer boundary ring".into(),
        E::InvalidAltitudeMode(s) => format!("unknown altitude mode '{}'", quoted(s)),
        E::InvalidColorMode(s) => format!("unknown color mode '{}' (expected normal or random)", quoted(s)),
        E::InvalidListItemType(s) => format!("unknown list item type '{}'", quoted(s)),
        E::InvalidRefreshMode(s) => format!("unknown refresh mode '{}'", quoted(s)),
        E::InvalidViewRefreshMode(s) => format!("unknown view refresh mode '{}'", quoted(s)),
        E::InvalidUnits(s) => format!("unknown units '{}'", quoted(s)),
        E::IoError(e) => e.to_string(),
    }
}

/// A zip error as a sentence.
fn unzip_error(e: &zip::result::ZipError) -> String {
    use zip::result::ZipError as Z;
    match e {
        Z::Io(e) => e.to_string(),
        Z::InvalidArchive(m) => format!("invalid archive ({})", lower_first(m)),
        Z::UnsupportedArchive(m) => format!("unsupported archive ({})", lower_first(m)),
        Z::FileNotFound => "entry not found".into(),
        Z::InvalidPassword => "wrong password".into(),
        other => lower_first(&other.to_string()),
    }
}

/// A library's message with its first letter in lower case, unless it
/// starts an acronym ("EOCD").
fn lower_first(s: &str) -> String {
    let mut chars = s.chars();
    match (chars.next(), chars.next()) {
        (Some(first), second) if !second.is_some_and(char::is_uppercase) => {
            first.to_lowercase().chain(s[first.len_utf8()..].chars()).collect()
        }
        _ => s.to_owned(),
    }
}
