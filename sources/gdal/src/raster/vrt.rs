//! A VRT mosaic's member files. GDAL opens a VRT whatever its sources, and
//! fails only when a read touches a missing one; relief names every missing
//! member when the mosaic opens and serves the rest, through a copy of the
//! VRT without them (in GDAL's memory file system, every path absolute).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use quick_xml::events::{BytesStart, BytesText, Event};
use quick_xml::{Reader, Writer};
use relief_source::SourceError;

use super::{FileStamp, PixelRect, format_err};

/// A raster's member files, and what GDAL should open.
#[derive(Debug, Clone, Default)]
pub(crate) struct Members {
    /// Members that are there.
    pub files: Vec<PathBuf>,
    /// Members the VRT names that are not there.
    pub missing: Vec<PathBuf>,
    /// Where the missing members would have been, in the VRT's pixels
    /// (their `DstRect`s, rounded outwards): nodata.
    pub holes: Vec<PixelRect>,
    pub open_path: PathBuf,
    /// The sources GDAL reads (all but those of missing members), in the
    /// VRT's order.
    pub sources: Vec<MemberSource>,
    /// The VRT's bands name overview files of their own (`Overview`).
    pub own_overviews: bool,
    /// A band hides its nodata value (`HideNoDataValue`).
    pub hides_nodata: bool,
}

/// One source of a VRT band as the VRT places it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct MemberSource {
    /// The VRT band it fills (1-based).
    pub band: usize,
    pub file: PathBuf,
    /// The member's band it reads (1-based).
    pub file_band: usize,
    /// `SourceProperties`: the member's size and data type name, when given.
    pub file_size: Option<(usize, usize)>,
    pub data_type: Option<String>,
    /// `SrcRect` and `DstRect`: x offset, y offset, width, height.
    pub src: Option<[f64; 4]>,
    pub dst: Option<[f64; 4]>,
    /// A `ComplexSource`'s `NODATA`: its pixels of that value leave what
    /// is under them.
    pub nodata: Option<f64>,
    /// Only a `SimpleSource` or a `ComplexSource` with nothing but the
    /// above (no scaling, lookup table, colour component or mask), in a
    /// band that is a plain `VRTRasterBand`.
    pub plain: bool,
}

/// What `describe` reads of a source, beside its file.
const PLAIN_PARTS: &[&[u8]] =
    &[b"SourceFilename", b"SourceBand", b"SourceProperties", b"SrcRect", b"DstRect", b"NODATA"];

/// The placement of a source from its events (`kind`: its element's name).
fn describe(events: &[Event<'static>], kind: &[u8], band: Option<usize>, file: PathBuf) -> MemberSource {
    let number = |e: &BytesStart<'_>, key: &str| -> Option<f64> {
        let a = e.try_get_attribute(key).ok().flatten()?;
        std::str::from_utf8(&a.value).ok()?.trim().parse().ok()
    };
    let rect = |e: &BytesStart<'_>| -> Option<[f64; 4]> {
        Some([number(e, "xOff")?, number(e, "yOff")?, number(e, "xSize")?, number(e, "ySize")?])
    };
    let mut out = MemberSource {
        band: band.unwrap_or(0),
        file,
        file_band: 1,
        file_size: None,
        data_type: None,
        src: None,
        dst: None,
        nodata: None,
        plain: band.is_some() && (kind == b"SimpleSource" || kind == b"ComplexSource"),
    };
    // The element whose text comes next, and the depth inside the source.
    let (mut open, mut depth) = (None::<Vec<u8>>, 0usize);
    for event in events {
        match event {
            Event::Start(e) | Event::Empty(e) => {
                if depth == 1 {
                    let name = e.name().as_ref().to_vec();
                    out.plain &=
                        PLAIN_PARTS.contains(&name.as_slice()) && (kind == b"ComplexSource" || name != b"NODATA");
                    match name.as_slice() {
                        b"SrcRect" => out.src = rect(e),
                        b"DstRect" => out.dst = rect(e),
                        b"SourceProperties" => {
                            out.file_size = number(e, "RasterXSize")
                                .zip(number(e, "RasterYSize"))
                                .map(|(w, h)| (w as usize, h as usize));
                            out.data_type = e
                                .try_get_attribute("DataType")
                                .ok()
                                .flatten()
                                .and_then(|a| std::str::from_utf8(&a.value).ok().map(str::to_owned));
                        }
                        _ => {}
                    }
                    if matches!(event, Event::Start(_)) {
                        open = Some(name);
                    }
                } else if depth == 0 {
                    // The source element itself: any attribute (resampling) is not plain.
                    out.plain &= e.attributes().next().is_none();
                }
                if matches!(event, Event::Start(_)) {
                    depth += 1;
                }
            }
            Event::Text(t) if depth == 2 => {
                let text = t.decode().map(|t| t.trim().to_owned()).unwrap_or_default();
                match open.as_deref() {
                    Some(b"SourceBand") => match text.parse() {
                        Ok(b) => out.file_band = b,
                        Err(_) => out.plain = false,
                    },
                    Some(b"NODATA") => match text.parse() {
                        Ok(v) => out.nodata = Some(v),
                        Err(_) => out.plain = false,
                    },
                    _ => {}
                }
            }
            Event::End(_) => {
                depth = depth.saturating_sub(1);
                if depth == 1 {
                    open = None;
                }
            }
            _ => {}
        }
    }
    out
}

/// Elements of a VRT band that read one source file.
const SOURCES: &[&[u8]] =
    &[b"SimpleSource", b"ComplexSource", b"AveragedSource", b"KernelFilteredSource", b"NoDataFromMaskSource"];

/// VRTs read lately, by path: the file as it was, and what it held.
type Remembered = Vec<(PathBuf, FileStamp, Members)>;

/// How many VRTs `members` remembers.
const REMEMBERED: usize = 8;

/// The members of `path` (none unless it is a VRT). A VRT unchanged since
/// it was last read, whose members are still there and whose missing
/// members still are not, is not parsed again (a reload after a member's
/// edit reads the VRT again).
pub(crate) fn members(path: &Path) -> Result<Members, SourceError> {
    static LAST: Mutex<Remembered> = Mutex::new(Vec::new());
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("vrt")) {
        return Ok(Members { open_path: path.to_path_buf(), ..Members::default() });
    }
    let stamp = FileStamp::of(path);
    let last = || LAST.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let known = last().iter().find(|(p, s, _)| p == path && Some(*s) == stamp).map(|(_, _, m)| m.clone());
    if let Some(known) = known
        && known.files.iter().all(|f| exists(f))
        && !known.missing.iter().any(|f| exists(f))
    {
        return Ok(known);
    }
    let members = parse(path)?;
    if let Some(stamp) = stamp
        && FileStamp::of(path) == Some(stamp)
    {
        let mut last = last();
        last.retain(|(p, _, _)| p != path);
        if last.len() >= REMEMBERED {
            last.remove(0);
        }
        last.push((path.to_path_buf(), stamp, members.clone()));
    }
    Ok(members)
}

/// The VRT's text: a local file's (a regular one) or an object's; None
/// when it cannot be read (GDAL then says why).
fn vrt_text(path: &Path) -> Option<String> {
    let file = crate::objects::RangeFile::open(path).ok()?;
    String::from_utf8(file.whole(crate::guard::MOST_XML_BYTES).ok()??).ok()
}

/// A member named relative to the VRT at `vrt`: beside it, a file or an
/// object (joined as text: a path join folds an HTTP URL's `//`).
fn beside(vrt: &Path, name: &str) -> PathBuf {
    match vrt.to_str().filter(|_| relief_source::objects::is_object(vrt)).and_then(|v| v.rsplit_once('/')) {
        Some((folder, _)) => PathBuf::from(format!("{folder}/{name}")),
        None => vrt.parent().unwrap_or(Path::new(".")).join(name),
    }
}

/// True when a member is there: a file, or an object the store has.
fn exists(member: &Path) -> bool {
    if relief_source::objects::is_object(member) { FileStamp::of(member).is_some() } else { member.exists() }
}

/// Reads the VRT at `path`: its members, those missing, and what GDAL
/// should open.
fn parse(path: &Path) -> Result<Members, SourceError> {
    let plain = Members { open_path: path.to_path_buf(), ..Members::default() };
    let Some(text) = vrt_text(path) else {
        return Ok(plain);
    };
    // A member named as an object URL (`s3://`, `https://`) is written back
    // as GDAL names it (`/vsis3/`, `/vsicurl/`): the copy is then opened.
    let mut urls = false;
    let bad = |e: &dyn std::fmt::Display| format_err(format!("VRT is not valid XML: {e}"), path);
    let mut reader = Reader::from_str(&text);
    let mut writer = Writer::new(Vec::new());
    let (mut files, mut missing) = (Vec::<PathBuf>::new(), Vec::<PathBuf>::new());
    let mut holes = Vec::new();
    // The events of the source element being read, its depth, its file,
    // where it goes.
    let mut held: Option<(Vec<Event<'static>>, usize, Option<PathBuf>)> = None;
    let mut destination: Option<PixelRect> = None;
    let mut relative = false;
    let mut in_name = false;
    let mut sources = Vec::new();
    // The band being read: its number, or None when it is not a plain
    // `VRTRasterBand` (a derived band, a pixel function).
    let mut band: Option<usize> = None;
    let mut own_overviews = false;
    let mut hides_nodata = false;
    loop {
        let event = reader.read_event().map_err(|e| bad(&e))?;
        if matches!(event, Event::Eof) {
            break;
        }
        let mut event = event.into_owned();
        match &event {
            Event::Start(e) if held.is_none() && e.name().as_ref() == b"VRTRasterBand" => {
                let attribute = |key: &str| e.try_get_attribute(key).ok().flatten();
                band = attribute("band")
                    .and_then(|a| std::str::from_utf8(&a.value).ok()?.trim().parse().ok())
                    .filter(|_| attribute("subClass").is_none());
            }
            Event::Start(e) if held.is_none() && SOURCES.contains(&e.name().as_ref()) => {
                held = Some((Vec::new(), 0, None));
            }
            // Overview files of its own. (An `OverviewList`, which
            // gdalbuildvrt writes when every member has overviews, makes
            // the VRT's overviews from the members': relief reads those.)
            Event::Start(e) | Event::Empty(e) if held.is_none() && e.name().as_ref() == b"Overview" => {
                own_overviews = true;
            }
            // Its nodata value fills the band but is not reported.
            Event::Start(e) if held.is_none() && e.name().as_ref() == b"HideNoDataValue" => {
                hides_nodata = true;
            }
            Event::Start(e) if e.name().as_ref() == b"SourceFilename" => {
                relative =
                    e.try_get_attribute("relativeToVRT").ok().flatten().is_some_and(|a| a.value.as_ref() == b"1");
                in_name = true;
                // Written back absolute: the copy lives elsewhere.
                let mut start = BytesStart::new("SourceFilename");
                start.push_attribute(("relativeToVRT", "0"));
                for a in e.attributes().flatten() {
                    if a.key.as_ref() != b"relativeToVRT" {
                        start.push_attribute(a);
                    }
                }
                event = Event::Start(start.into_owned());
            }
            Event::Text(t) if in_name => {
                let name = t.decode().map_err(|e| bad(&e))?.into_owned();
                let url = relief_source::objects::from_url(name.trim());
                urls |= url.is_some();
                let file = match url {
                    Some(object) => object,
                    None if relative => beside(path, &name),
                    None => PathBuf::from(&name),
                };
                event = Event::Text(BytesText::new(&file.display().to_string()).into_owned());
                if let Some((_, _, f)) = &mut held {
                    *f = Some(file);
                }
            }
            Event::End(e) if e.name().as_ref() == b"SourceFilename" => in_name = false,
            Event::Empty(e) | Event::Start(e) if held.is_some() && e.name().as_ref() == b"DstRect" => {
                let number = |key: &str| -> Option<f64> {
                    let a = e.try_get_attribute(key).ok().flatten()?;
                    std::str::from_utf8(&a.value).ok()?.trim().parse().ok()
                };
                if let (Some(x), Some(y), Some(w), Some(h)) =
                    (number("xOff"), number("yOff"), number("xSize"), number("ySize"))
                {
                    let at = |v: f64| v.max(0.0) as usize;
                    destination = Some(PixelRect {
                        x0: at(x.floor()),
                        y0: at(y.floor()),
                        x1: at((x + w).ceil()),
                        y1: at((y + h).ceil()),
                    });
                }
            }
            _ => {}
        }
        match &mut held {
            Some((events, depth, _)) => {
                match &event {
                    Event::Start(_) => *depth += 1,
                    Event::End(_) => *depth -= 1,
                    _ => {}
                }
                events.push(event);
                if *depth == 0 {
                    let (events, _, file) = held.take().expect("held");
                    let present = match &file {
                        // Not a plain file (a /vsi path, a URL): GDAL's to judge.
                        Some(f) if f.is_absolute() && !exists(f) => false,
                        _ => true,
                    };
                    match file {
                        Some(f) if !present => {
                            holes.extend(destination.take());
                            if !missing.contains(&f) {
                                missing.push(f);
                            }
                        }
                        _ => {
                            destination = None;
                            if let Some(Event::Start(start)) = events.first() {
                                let mut source =
                                    describe(&events, start.name().as_ref(), band, file.clone().unwrap_or_default());
                                // A /vsi path or a URL: GDAL reads it, relief does not.
                                source.plain &= file.as_ref().is_some_and(|f| f.exists());
                                sources.push(source);
                            }
                            if let Some(f) = file.filter(|f| exists(f) && !files.contains(f)) {
                                files.push(f);
                            }
                            for e in events {
                                writer.write_event(e).map_err(|e| bad(&e))?;
                            }
                        }
                    }
                }
            }
            None => writer.write_event(event).map_err(|e| bad(&e))?,
        }
    }
    if missing.is_empty() && !urls {
        return Ok(Members {
            files,
            missing,
            holes,
            open_path: path.to_path_buf(),
            sources,
            own_overviews,
            hides_nodata,
        });
    }
    if files.is_empty() {
        let names: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
        return Err(format_err(format!("none of the VRT's files is there (missing: {})", names.join(", ")), path));
    }
    let copy = PathBuf::from(format!(
        "{}/{}-{}.vrt",
        crate::guard::OWN_MEMORY_FILES,
        std::process::id(),
        super::blocks::new_uid()
    ));
    gdal::vsi::create_mem_file(&copy, writer.into_inner())
        .map_err(|e| format_err(format!("cannot write the VRT without its missing files: {e}"), path))?;
    tracing::debug!(vrt = %path.display(), copy = %copy.display(), "VRT opened through a copy");
    Ok(Members { files, missing, holes, open_path: copy, sources, own_overviews, hides_nodata })
}
