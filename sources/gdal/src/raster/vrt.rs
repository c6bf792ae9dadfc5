//! A VRT mosaic's member files. GDAL opens a VRT whatever its sources, and
//! fails only when a read touches a missing one; relief names every missing
//! member when the mosaic opens and serves the rest, through a copy of the
//! VRT without them (in GDAL's memory file system, every path absolute).

use std::path::{Path, PathBuf};

use quick_xml::events::{BytesStart, BytesText, Event};
use quick_xml::{Reader, Writer};
use relief_source::SourceError;

use super::{PixelRect, format_err};

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
}

/// Elements of a VRT band that read one source file.
const SOURCES: &[&[u8]] =
    &[b"SimpleSource", b"ComplexSource", b"AveragedSource", b"KernelFilteredSource", b"NoDataFromMaskSource"];

/// The members of `path` (none unless it is a VRT).
pub(crate) fn members(path: &Path) -> Result<Members, SourceError> {
    let plain = Members { open_path: path.to_path_buf(), ..Members::default() };
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("vrt")) {
        return Ok(plain);
    }
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(plain);
    };
    let folder = path.parent().unwrap_or(Path::new("."));
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
    loop {
        let event = reader.read_event().map_err(|e| bad(&e))?;
        if matches!(event, Event::Eof) {
            break;
        }
        let mut event = event.into_owned();
        match &event {
            Event::Start(e) if held.is_none() && SOURCES.contains(&e.name().as_ref()) => {
                held = Some((Vec::new(), 0, None));
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
                let file = if relative { folder.join(&name) } else { PathBuf::from(&name) };
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
                        Some(f) if f.is_absolute() && !f.exists() => false,
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
                            if let Some(f) = file.filter(|f| f.exists() && !files.contains(f)) {
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
    if missing.is_empty() {
        return Ok(Members { files, missing, holes, open_path: path.to_path_buf() });
    }
    if files.is_empty() {
        let names: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
        return Err(format_err(format!("none of the VRT's files is there (missing: {})", names.join(", ")), path));
    }
    let copy = PathBuf::from(format!("/vsimem/relief/{}-{}.vrt", std::process::id(), super::blocks::new_uid()));
    gdal::vsi::create_mem_file(&copy, writer.into_inner())
        .map_err(|e| format_err(format!("cannot write the VRT without its missing files: {e}"), path))?;
    Ok(Members { files, missing, holes, open_path: copy })
}
