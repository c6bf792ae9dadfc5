//! Scene files are untrusted input to GDAL. The paths a manifest names are
//! the user's own; every file those files make GDAL open (a VRT's members
//! and raw bands, nested VRTs, an OGR VRT's data source, the side files
//! GDAL looks for beside each) must lie under the referencing file's
//! folder, the manifest's folder or a root the manifest declares, after
//! symbolic links are followed. Nothing reaches the network: the drivers
//! that fetch URLs are not registered, `/vsi` paths other than archives
//! are refused, and GDAL's HTTP goes to a proxy that is not there.
//!
//! A dataset is checked before every open (`check_dataset`); the verdict
//! is remembered against the stamps of every file it visited, so a
//! mosaic's hundreds of opens cost a few `stat`s, and an edit to any file
//! of the chain checks it again.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once, PoisonError, RwLock};

use quick_xml::Reader;
use quick_xml::events::Event;
use relief_source::files::FileStamp;
use relief_source::objects::is_object;

/// GDAL and OGR drivers relief never registers: they fetch URLs (web
/// services, cloud APIs, databases over the network), or their files name
/// other files anywhere in a syntax relief does not check.
pub const REFUSED_DRIVERS: &[&str] = &[
    // Web services and cloud APIs.
    "WMS",
    "WMTS",
    "WCS",
    "WFS",
    "OAPIF",
    "OGCAPI",
    "CSW",
    "HTTP",
    "PLMOSAIC",
    "PLSCENES",
    "EEDA",
    "EEDAI",
    "DAAS",
    "NGW",
    "STACTA",
    "STACIT",
    "Carto",
    "AmigoCloud",
    "Elasticsearch",
    "GMLAS",
    // Databases reached over the network.
    "PostgreSQL",
    "PostGISRaster",
    "MySQL",
    "ODBC",
    "PGeo",
    "MSSQLSpatial",
    "MongoDBv3",
    "OCI",
    // Headers that name their data files anywhere.
    "MRF",
    "ERS",
    "ISIS2",
    "ISIS3",
    "PDS",
    "PDS4",
    "DERIVED",
];

/// `/vsi` file systems that read inside an archive relief can check.
const ARCHIVES: &[&str] = &["vsizip", "vsigzip", "vsitar", "vsi7z", "vsirar"];

/// Where relief writes VRTs of its own (a mosaic without its missing
/// members, a warp) in GDAL's memory, from files it has checked.
pub const OWN_MEMORY_FILES: &str = "/vsimem/relief";

/// How deep VRTs may nest.
const MOST_NESTED: usize = 8;

/// The largest XML file read to check it (a VRT of thousands of members
/// is a few MB).
pub(crate) const MOST_XML_BYTES: u64 = 64 << 20;

/// Sets GDAL up to read local files only, once per process: the drivers
/// above deregistered (and skipped by any later registration), VRT Python
/// pixel functions off, GML schemas never downloaded, and HTTP, should
/// anything still ask for it, sent to a proxy on a port nothing serves.
pub fn configure() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let set = crate::set_option;
        set("GDAL_VRT_ENABLE_PYTHON", "NO");
        set("GML_DOWNLOAD_SCHEMA", "NO");
        set("GML_SKIP_RESOLVE_ELEMS", "ALL");
        set("OGR_SQLITE_ALLOW_EXTERNAL_ACCESS", "NO");
        block_http();
        gdal::DriverManager::register_all();
        // Only the drivers this GDAL has: GDAL warns on stderr of every
        // name in GDAL_SKIP it does not know.
        let present: Vec<&str> = REFUSED_DRIVERS
            .iter()
            .copied()
            .filter(|name| gdal::DriverManager::get_driver_by_name(name).is_ok())
            .collect();
        set("GDAL_SKIP", &present.join(" "));
        for name in &present {
            if let Ok(driver) = gdal::DriverManager::get_driver_by_name(name) {
                gdal::DriverManager::deregister_driver(&driver);
            }
        }
    });
}

/// Sends GDAL's HTTP to a proxy on a port nothing serves: a scene of
/// local files reaches no network, whatever slips past the checks. A scene
/// that names objects lifts it (`objects::configure_storage`), and then
/// the checks below keep every object read within the scene's buckets and
/// hosts.
pub(crate) fn block_http() {
    let set = crate::set_option;
    set("GDAL_HTTP_PROXY", "127.0.0.1:1");
    set("GDAL_HTTPS_PROXY", "127.0.0.1:1");
    set("GDAL_HTTP_TIMEOUT", "1");
    set("GDAL_HTTP_CONNECTTIMEOUT", "1");
    set("GDAL_HTTP_MAX_RETRY", "0");
}

static ROOTS: RwLock<Vec<PathBuf>> = RwLock::new(Vec::new());

/// The object prefixes scene files may name objects under: the bucket or
/// origin of every object the manifest names, and `[scene] roots` given as
/// object URLs.
static OBJECT_ROOTS: RwLock<Vec<String>> = RwLock::new(Vec::new());

/// The folders (besides each referencing file's own) that files named by
/// scene files may lie under: the manifest's folder and its `[scene]
/// roots`. Set when a manifest loads; checks made under other roots are
/// forgotten.
pub fn set_roots(roots: &[PathBuf]) {
    let (objects, local): (Vec<&PathBuf>, Vec<&PathBuf>) = roots.iter().partition(|r| is_object(r));
    let canonical: Vec<PathBuf> = local.iter().filter_map(|r| std::fs::canonicalize(r).ok()).collect();
    *ROOTS.write().unwrap_or_else(PoisonError::into_inner) = canonical;
    // Whole path parts only: `dems/` is not a prefix of `dems2/...`.
    *OBJECT_ROOTS.write().unwrap_or_else(PoisonError::into_inner) = objects
        .iter()
        .filter_map(|r| r.to_str())
        .map(|r| if r.ends_with('/') { r.to_owned() } else { format!("{r}/") })
        .collect();
    verdicts().clear();
}

/// True when `object` lies under one of the scene's object roots.
fn object_within(object: &str) -> bool {
    OBJECT_ROOTS.read().unwrap_or_else(PoisonError::into_inner).iter().any(|root| object.starts_with(root.as_str()))
}

fn roots() -> Vec<PathBuf> {
    ROOTS.read().unwrap_or_else(PoisonError::into_inner).clone()
}

/// A dataset checked and found safe, and the files it visited as they
/// were (None: absent).
struct Verdict {
    path: PathBuf,
    visited: Vec<(PathBuf, Option<FileStamp>)>,
}

/// Datasets remembered at most.
const REMEMBERED: usize = 256;

fn verdicts() -> std::sync::MutexGuard<'static, Vec<Verdict>> {
    static VERDICTS: Mutex<Vec<Verdict>> = Mutex::new(Vec::new());
    VERDICTS.lock().unwrap_or_else(PoisonError::into_inner)
}

/// `Ok` when GDAL may open `path` (a file the manifest names, or one a
/// checked file names): every file it would make GDAL open lies within
/// reach, no URL and no driver connection string is named, no Python runs.
/// The error says which file names what, and why it is refused.
pub fn check_dataset(path: &Path) -> Result<(), String> {
    configure();
    let known =
        verdicts().iter().any(|v| v.path == path && v.visited.iter().all(|(file, then)| FileStamp::of(file) == *then));
    if known {
        return Ok(());
    }
    let mut walk = Walk { roots: roots(), visited: Vec::new(), seen: HashSet::new() };
    walk.dataset(path, 0)?;
    let mut verdicts = verdicts();
    verdicts.retain(|v| v.path != path);
    if verdicts.len() >= REMEMBERED {
        verdicts.remove(0);
    }
    verdicts.push(Verdict { path: path.to_path_buf(), visited: walk.visited });
    Ok(())
}

/// One check's walk through the files a dataset names.
struct Walk {
    roots: Vec<PathBuf>,
    visited: Vec<(PathBuf, Option<FileStamp>)>,
    seen: HashSet<PathBuf>,
}

impl Walk {
    /// Checks `path`, its side files and, when it is a GDAL XML file,
    /// every file it names.
    fn dataset(&mut self, path: &Path, depth: usize) -> Result<(), String> {
        if depth > MOST_NESTED {
            return Err(format!("{}: files nest more than {MOST_NESTED} deep", path.display()));
        }
        if !self.seen.insert(path.to_path_buf()) {
            return Ok(());
        }
        self.visited.push((path.to_path_buf(), FileStamp::of(path)));
        let folders = self.own_folders(path);
        // GDAL is told an object has no side objects (objects::config).
        let sides = if is_object(path) { Vec::new() } else { relief_source::regular::side_files(path) };
        for side in sides {
            let stamp = FileStamp::of(&side);
            self.visited.push((side.clone(), stamp));
            if stamp.is_some() {
                Self::within(&side, &folders, path, "a side file")?;
            }
        }
        let Some(text) = xml_text(path)? else { return Ok(()) };
        self.xml(path, &text, &folders, depth)
    }

    /// The folders a file may name files under: its own (as named, and
    /// with links followed) and the roots.
    fn own_folders(&self, path: &Path) -> Vec<PathBuf> {
        let mut folders = self.roots.clone();
        let parent = path.parent().unwrap_or(Path::new("."));
        folders.extend(std::fs::canonicalize(parent).ok());
        if let Some(parent) = std::fs::canonicalize(path).ok().and_then(|p| p.parent().map(Path::to_path_buf)) {
            folders.push(parent);
        }
        folders
    }

    /// `Ok` when `file`, links followed, lies under one of `folders`.
    fn within(file: &Path, folders: &[PathBuf], from: &Path, what: &str) -> Result<(), String> {
        let canonical =
            std::fs::canonicalize(file).map_err(|e| format!("{}: {what} {}: {e}", from.display(), file.display()))?;
        if folders.iter().any(|f| canonical.starts_with(f)) {
            return Ok(());
        }
        Err(format!(
            "{}: {what} {} lies outside the scene's folders (the file's own folder, the manifest's and [scene] roots)",
            from.display(),
            if canonical == file {
                file.display().to_string()
            } else {
                format!("{} ({})", file.display(), canonical.display())
            },
        ))
    }

    /// Checks a GDAL XML file: its kind, and every file it names.
    fn xml(&mut self, path: &Path, text: &str, folders: &[PathBuf], depth: usize) -> Result<(), String> {
        let bad = |e: &dyn std::fmt::Display| format!("{}: not valid XML: {e}", path.display());
        let mut reader = Reader::from_str(text);
        let mut stack: Vec<Vec<u8>> = Vec::new();
        // The reference being read: relative to the file's folder or not.
        let mut naming: Option<bool> = None;
        loop {
            let event = reader.read_event().map_err(|e| bad(&e))?;
            match event {
                Event::Eof => return Ok(()),
                Event::Start(e) if stack.is_empty() => {
                    let root = e.name().as_ref().to_vec();
                    refuse_root(path, &root)?;
                    stack.push(root);
                }
                Event::Empty(e) if stack.is_empty() => refuse_root(path, e.name().as_ref())?,
                Event::Start(e) => {
                    let name = e.name().as_ref().to_vec();
                    if REFERENCES.contains(&name.as_slice()) {
                        let relative = e
                            .attributes()
                            .flatten()
                            .any(|a| a.key.as_ref().eq_ignore_ascii_case(b"relativeToVRT") && a.value.as_ref() == b"1");
                        naming = Some(relative);
                    }
                    stack.push(name);
                }
                Event::Empty(e) if REFERENCES.contains(&e.name().as_ref()) => {
                    return Err(format!(
                        "{}: an empty <{}>",
                        path.display(),
                        String::from_utf8_lossy(e.name().as_ref())
                    ));
                }
                Event::Text(t) => {
                    let text = t.decode().map_err(|e| bad(&e))?;
                    let text = quick_xml::escape::unescape(&text).map_err(|e| bad(&e))?;
                    match stack.last().map(Vec::as_slice) {
                        Some(b"PixelFunctionLanguage") if !text.trim().eq_ignore_ascii_case("C") => {
                            return Err(format!(
                                "{}: a pixel function in {}: relief runs no code from scene files",
                                path.display(),
                                text.trim()
                            ));
                        }
                        Some(b"PixelFunctionCode") => {
                            return Err(format!(
                                "{}: pixel function code: relief runs no code from scene files",
                                path.display()
                            ));
                        }
                        _ => {}
                    }
                    if let Some(relative) = naming.take() {
                        self.reference(path, text.trim(), relative, folders, depth)?;
                    }
                }
                Event::CData(_) if naming.is_some() || stack.last().is_some_and(|n| n == b"PixelFunctionCode") => {
                    return Err(format!("{}: a file name or code in CDATA", path.display()));
                }
                Event::End(_) => {
                    naming = None;
                    stack.pop();
                }
                _ => {}
            }
        }
    }

    /// Checks one file named in `from`: refused unless a local path (or
    /// an archive path) within reach; a file that is there is checked in
    /// turn.
    fn reference(
        &mut self,
        from: &Path,
        name: &str,
        relative: bool,
        folders: &[PathBuf],
        depth: usize,
    ) -> Result<(), String> {
        let refused = |why: &str| {
            Err(format!("{}: refuses to open '{}': {why}", from.display(), relief_source::echo::echoed(name)))
        };
        if name.is_empty() {
            return refused("an empty file name");
        }
        // An object, as GDAL names it or as a URL (`s3://`, `https://`,
        // which the mosaic's reader writes back in GDAL's form).
        let object = if let Some(url) = relief_source::objects::from_url(name.trim()) {
            Some(url.to_string_lossy().into_owned())
        } else if is_object(Path::new(name)) {
            Some(name.to_owned())
        } else if relative && is_object(from) {
            // Path joins fold an HTTP URL's `//`: objects join as text.
            from.to_str().and_then(|f| f.rsplit_once('/')).map(|(folder, _)| format!("{folder}/{name}"))
        } else {
            None
        };
        if let Some(object) = object {
            if !object_within(&object) {
                return refused(
                    "an object outside the scene's buckets and hosts (those of the objects the manifest names, and \
                     [scene] roots)",
                );
            }
            let file = PathBuf::from(object);
            self.visited.push((file.clone(), FileStamp::of(&file)));
            return self.dataset(&file, depth + 1);
        }
        if let Some(why) = refusal(name) {
            return refused(&why);
        }
        if driver_prefix(name) {
            return refused("a driver's connection string, not a file");
        }
        let file = if let Some(rest) = name.strip_prefix("/vsi") {
            let (system, inner) = rest.split_once('/').unwrap_or((rest, ""));
            if system == "subfile" {
                // /vsisubfile/OFFSET_SIZE,FILE
                match inner.split_once(',') {
                    Some((_, file)) if !file.is_empty() => PathBuf::from(file),
                    _ => return refused("a /vsisubfile/ path without its file"),
                }
            } else {
                match archive(inner) {
                    Some(file) => file,
                    None => return refused("an archive path whose archive is not there"),
                }
            }
        } else if relative {
            from.parent().unwrap_or(Path::new(".")).join(name)
        } else {
            PathBuf::from(name)
        };
        let stamp = FileStamp::of(&file);
        self.visited.push((file.clone(), stamp));
        if stamp.is_none() && std::fs::symlink_metadata(&file).is_err() {
            // Not there: nothing to read (the mosaic reports it missing).
            return Ok(());
        }
        Self::within(&file, folders, from, "names the file")?;
        self.dataset(&file, depth + 1)
    }
}

/// Why GDAL must not be handed `name` (a URL, a `/vsi` path to memory or
/// the network), or None for a local path or an archive path (whose
/// archive is checked like any file).
pub fn refusal(name: &str) -> Option<String> {
    if name.contains("://") {
        return Some(
            "a URL: a scene file names an object as /vsis3/bucket/key or /vsicurl/https://host/path, in the \
             scene's buckets and hosts"
                .to_owned(),
        );
    }
    if is_object(Path::new(name)) {
        // Checked against the scene's buckets and hosts where named.
        return None;
    }
    if let Some(rest) = name.strip_prefix("/vsi") {
        let system = format!("vsi{}", rest.split_once('/').map_or(rest, |(s, _)| s));
        if system != "vsisubfile" && !ARCHIVES.contains(&system.as_str()) {
            return Some(format!("/{system}/ reads memory or the network, not scene files"));
        }
    }
    None
}

/// Elements whose text names a file GDAL or OGR opens.
const REFERENCES: &[&[u8]] = &[b"SourceFilename", b"SourceDataset", b"SrcDataSource"];

/// Refuses XML files that describe network services or name files in a
/// way relief does not check; VRTs, OGR VRTs and everything else pass on.
fn refuse_root(path: &Path, root: &[u8]) -> Result<(), String> {
    let root = String::from_utf8_lossy(root);
    let service =
        ["GDAL_WMS", "GDAL_WMTS", "WCS_GDAL", "GDAL_WCS", "Capabilities", "WMT_MS_Capabilities", "OGRWFSDataSource"];
    if service.iter().any(|s| root.eq_ignore_ascii_case(s)) {
        return Err(format!(
            "{}: a <{root}> web service description: scene files read no network data",
            path.display()
        ));
    }
    if root.eq_ignore_ascii_case("MRF_META") {
        return Err(format!(
            "{}: a Meta Raster Format header names its data files anywhere; relief does not read it",
            path.display()
        ));
    }
    Ok(())
}

/// The text of `path` (a file or an object) when it is an XML file (it
/// starts with `<`, after a byte-order mark and white space); None for any
/// other file. Its first bytes tell before the rest is read (an object is
/// most often a large COG).
fn xml_text(path: &Path) -> Result<Option<String>, String> {
    let Ok(file) = crate::objects::RangeFile::open(path) else { return Ok(None) };
    let cannot = |e: std::io::Error| format!("{}: cannot read: {e}", path.display());
    let without_mark = |bytes: Vec<u8>| bytes.strip_prefix(b"\xEF\xBB\xBF").map(<[u8]>::to_vec).unwrap_or(bytes);
    let head = without_mark(file.head(64).map_err(cannot)?);
    if head.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'<') {
        return Ok(None);
    }
    let Some(bytes) = file.whole(MOST_XML_BYTES).map_err(cannot)? else {
        return Err(format!("{}: an XML file over {} MB", path.display(), MOST_XML_BYTES >> 20));
    };
    String::from_utf8(without_mark(bytes)).map(Some).map_err(|_| format!("{}: XML that is not UTF-8", path.display()))
}

/// The archive file of an archive path's inside (`a/b.zip/x/y.tif` or
/// `{a/b.zip}/x/y.tif`): the longest leading part that is a file.
fn archive(inner: &str) -> Option<PathBuf> {
    if let Some(braced) = inner.strip_prefix('{') {
        return braced.split_once('}').map(|(file, _)| PathBuf::from(file));
    }
    let parts: Vec<&str> = inner.split('/').collect();
    (1..=parts.len()).rev().map(|n| PathBuf::from(parts[..n].join("/"))).find(|p| p.is_file())
}

/// A driver's connection string (`NETCDF:"f.nc":var`, `PG:dbname=x`,
/// `DERIVED:...`): a name of two or more letters, digits or underscores
/// before a colon.
fn driver_prefix(name: &str) -> bool {
    name.split_once(':').is_some_and(|(head, _)| {
        head.len() >= 2 && head.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') && !head.contains('/')
    })
}

#[cfg(test)]
mod tests;
