//! One pass over the KML text before the kml crate reads it: what that
//! parser refuses, trips on or loops on is rewritten as the nearest thing
//! it reads, or refused here with a line number.
//!
//! - `altitudeMode` and `gx:altitudeMode`: the sea-floor modes (which the
//!   kml crate refuses) are read as their ground modes, an unknown mode as
//!   `clampToGround` (KML's default), each with a warning.
//! - Free text for people (`description`, `name`, balloon `text`...) that
//!   holds HTML, unescaped and often not well-formed (`<br>`), becomes
//!   CDATA: the text is the HTML, as a CDATA description's already is.
//! - `coordinates`: spaces after commas dropped ("19, 37", common in
//!   Google's own samples), every tuple of a Point, LineString or
//!   LinearRing checked here, and a Point without one left out (the kml
//!   crate panics on it).
//! - `&` that starts no XML reference becomes `&amp;`; comments, DOCTYPE
//!   and processing instructions, which KML has no use for, are dropped
//!   (the kml crate refuses a comment inside a value).
//! - The elements must nest and close properly (the kml crate can loop
//!   forever on a document cut short), and no deeper than `MAX_DEPTH`
//!   (it reads nesting by recursion, on a stack sized for that). A
//!   placemark whose inner tags do not match (`<Data>` closed by `</Dta>`,
//!   an element never closed before `</Placemark>`) is left out whole, with
//!   a warning naming its lines, and the others are read; a document whose
//!   every placemark is torn, or whose structure outside placemarks is
//!   (a file cut short, being written), is refused.
//!
//! Everything else is copied through byte for byte.

use std::borrow::Cow;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use quick_xml::Reader;
use quick_xml::events::Event;
use relief_source::SourceError;

/// The deepest element nesting read: real KML (folders in folders) stays
/// far below it, and the kml crate's recursion stays well inside the stack
/// of the thread it runs on (`load::PARSE_STACK_BYTES`).
const MAX_DEPTH: usize = 256;

/// Elements of free text for people, where writers put HTML.
const PROSE: &[&str] = &["name", "description", "Snippet", "snippet", "text", "displayName", "address", "value"];

/// The KML text ready for the kml crate, and what the user should know
/// about how it was read.
pub(crate) struct Tidied<'a> {
    pub text: Cow<'a, str>,
    pub warnings: Vec<String>,
}

/// Tidies `text` (the KML document of `path`) for the kml crate.
pub(crate) fn tidy<'a>(text: &'a str, path: &Path) -> Result<Tidied<'a>, SourceError> {
    Pass::new(text).run().map_err(|message| SourceError::format(format!("malformed KML: {message}"), path))
}

/// An open element.
struct Open {
    /// As written, with its prefix.
    name: String,
    /// Where its start tag begins in the text.
    at: usize,
    /// The placemark's number, for a `Placemark`.
    placemark: Option<usize>,
    /// For a `Point`: where it begins in the output, and whether the last
    /// `coordinates` inside it (at any depth) held a tuple.
    point: Option<(usize, bool)>,
    /// For a `Placemark`: where it begins in the output.
    out_at: usize,
}

/// Where altitude modes read as another were found.
#[derive(Default)]
struct Remapped {
    placemarks: BTreeSet<usize>,
    elsewhere: usize,
}

struct Pass<'a> {
    text: &'a str,
    out: String,
    /// Bytes of `text` already copied to `out` (or replaced there).
    copied: usize,
    changed: bool,
    open: Vec<Open>,
    placemarks: usize,
    /// (mode as written, mode read) to where.
    remapped: BTreeMap<(String, &'static str), Remapped>,
    points_left_out: usize,
    /// Placemarks left out for their mismatched tags: why, by line.
    torn: Vec<String>,
}

impl<'a> Pass<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            text,
            out: String::new(),
            copied: 0,
            changed: false,
            open: Vec::new(),
            placemarks: 0,
            remapped: BTreeMap::new(),
            points_left_out: 0,
            torn: Vec::new(),
        }
    }

    fn run(mut self) -> Result<Tidied<'a>, String> {
        // Where the current reader starts: a text element is skipped in
        // the raw text (it may not be XML), and reading starts again after it.
        let mut base = 0;
        'restart: loop {
            let mut reader = Reader::from_str(self.text.get(base..).unwrap_or_default());
            let config = reader.config_mut();
            // Nesting is checked here, across the restarts.
            config.check_end_names = false;
            config.allow_unmatched_ends = true;
            config.allow_dangling_amp = true;
            loop {
                let before = base + reader.buffer_position() as usize;
                let event = reader.read_event().map_err(|e| {
                    let at = base + reader.error_position() as usize;
                    format!("{e} at line {}", self.line(at))
                })?;
                let after = base + reader.buffer_position() as usize;
                match event {
                    Event::Start(start) => {
                        let name = String::from_utf8_lossy(start.name().as_ref()).into_owned();
                        if is_text_element(&name) {
                            let Some((close, end)) = close_of(self.text, &name, after)
                                .filter(|(close, _)| self.closes_inside_placemark(*close))
                            else {
                                let why = format!("<{name}> at line {} is never closed", self.line(before));
                                base = self.leave_out_placemark(None, after, why)?;
                                continue 'restart;
                            };
                            self.text_element(&name, before, after, close)?;
                            base = end;
                            continue 'restart;
                        }
                        self.open_element(name, before)?;
                    }
                    Event::End(end) => {
                        let name = String::from_utf8_lossy(end.name().as_ref()).into_owned();
                        if let Some(resume) = self.close_element(&name, before, after)? {
                            base = resume;
                            continue 'restart;
                        }
                    }
                    // A dangling `&` (allowed above) is text starting with one.
                    Event::Text(text) if text.starts_with(b"&") => self.replace(before, before + 1, "&amp;"),
                    Event::GeneralRef(reference) => {
                        let known = if reference.is_char_ref() {
                            matches!(reference.resolve_char_ref(), Ok(Some(_)))
                        } else {
                            reference.decode().is_ok_and(|name| quick_xml::escape::resolve_xml_entity(&name).is_some())
                        };
                        if !known {
                            self.replace(before, before + 1, "&amp;");
                        }
                    }
                    Event::Comment(_) | Event::DocType(_) | Event::PI(_) => self.replace(before, after, ""),
                    Event::Eof => break 'restart,
                    _ => {}
                }
            }
        }
        if let Some(open) = self.open.last() {
            return Err(format!(
                "<{}> opened at line {} is never closed (the file may be cut short)",
                open.name,
                self.line(open.at)
            ));
        }
        if !self.torn.is_empty() && self.torn.len() == self.placemarks {
            return Err(format!("every placemark is torn: {}", self.torn.join("; ")));
        }
        let warnings = self.warnings();
        let text = if self.changed {
            self.flush(self.text.len());
            Cow::Owned(self.out)
        } else {
            Cow::Borrowed(self.text)
        };
        Ok(Tidied { text, warnings })
    }

    fn open_element(&mut self, name: String, at: usize) -> Result<(), String> {
        if self.open.len() >= MAX_DEPTH {
            return Err(format!("elements nest more than {MAX_DEPTH} deep at line {}", self.line(at)));
        }
        let mut out_at = 0;
        let (placemark, point) = match local(&name) {
            "Placemark" => {
                self.flush(at);
                out_at = self.out.len();
                self.placemarks += 1;
                (Some(self.placemarks - 1), None)
            }
            "Point" => {
                self.flush(at);
                (None, Some((self.out.len(), false)))
            }
            _ => (None, None),
        };
        self.open.push(Open { name, at, placemark, point, out_at });
        Ok(())
    }

    /// Closes the innermost element with the end tag `name` (from `at` to
    /// `end`). Some(offset): a torn placemark was left out, and reading
    /// goes on from `offset`, past its end.
    fn close_element(&mut self, name: &str, at: usize, end: usize) -> Result<Option<usize>, String> {
        let Some(open) = self.open.pop() else {
            return Err(format!("</{name}> at line {} closes no open element", self.line(at)));
        };
        if open.name != name {
            let why = format!(
                "<{}> opened at line {} is closed by </{name}> at line {}",
                open.name,
                self.line(open.at),
                self.line(at)
            );
            self.open.push(open);
            return self.leave_out_placemark(Some(name), end, why).map(Some);
        }
        if let Some((mark, false)) = open.point {
            self.flush(end);
            self.out.truncate(mark);
            self.changed = true;
            self.points_left_out += 1;
        }
        Ok(None)
    }

    /// True when the end tag at `close` comes before the end of the
    /// placemark being read, if any (a text element's end found past it
    /// belongs to another placemark).
    fn closes_inside_placemark(&self, close: usize) -> bool {
        let Some(placemark) = self.open.iter().rev().find(|o| o.placemark.is_some()) else { return true };
        let placemark_end = self.text.get(placemark.at..close).and_then(|t| t.find(&format!("</{}", placemark.name)));
        placemark_end.is_none()
    }

    /// Leaves out the placemark being read, torn at a mismatched end tag
    /// `closing` (ending at `end`) or at an element never closed (`None`,
    /// from `end`), and says where reading goes on: after this tag when it
    /// is the placemark's own end, else after the placemark's next end tag.
    /// Err(`why`) outside any placemark.
    fn leave_out_placemark(&mut self, closing: Option<&str>, end: usize, why: String) -> Result<usize, String> {
        let Some(depth) = self.open.iter().rposition(|o| o.placemark.is_some()) else { return Err(why) };
        let placemark_name = self.open[depth].name.clone();
        let resume = if closing == Some(placemark_name.as_str()) {
            end
        } else {
            close_of(self.text, &placemark_name, end).map(|(_, resume)| resume).ok_or_else(|| why.clone())?
        };
        let placemark = &self.open[depth];
        let (first, last) = (self.line(placemark.at), self.line(resume.saturating_sub(1)));
        let out_at = placemark.out_at;
        self.flush(placemark.at);
        self.out.truncate(out_at);
        self.copied = resume;
        self.changed = true;
        self.open.truncate(depth);
        let lines = if first == last { format!("line {first}") } else { format!("lines {first}-{last}") };
        self.torn.push(format!("the placemark at {lines} ({why})"));
        Ok(resume)
    }

    /// A text element from its start tag at `at`, its content from
    /// `content` to its end tag at `close`.
    fn text_element(&mut self, name: &str, at: usize, content: usize, close: usize) -> Result<(), String> {
        let raw = self.text.get(content..close).unwrap_or_default();
        match local(name) {
            "altitudeMode" => {
                let written = plain(raw).unwrap_or_else(|| raw.to_owned());
                let written = written.trim();
                let read = match written {
                    "clampToGround" | "relativeToGround" | "absolute" => None,
                    "relativeToSeaFloor" => Some("relativeToGround"),
                    // clampToSeaFloor, or unknown, or empty (which means
                    // KML's default): the kml crate refuses them all.
                    _ => Some("clampToGround"),
                };
                if let Some(read) = read {
                    if !written.is_empty() {
                        let shown: String = written.chars().take(40).collect();
                        let place = self.remapped.entry((shown, read)).or_default();
                        match self.open.iter().rev().find_map(|o| o.placemark) {
                            Some(n) => {
                                place.placemarks.insert(n);
                            }
                            None => place.elsewhere += 1,
                        }
                    }
                    self.replace(content, close, read);
                } else if written != raw {
                    let written = written.to_owned();
                    self.replace(content, close, &written);
                }
            }
            "coordinates" => {
                let Some(text) = plain(raw) else {
                    let markup = pieces(raw).into_iter().find_map(|p| match p {
                        Piece::Markup(m) => Some(m.split(|c: char| c.is_whitespace() || c == '>').next().unwrap_or(m)),
                        _ => None,
                    });
                    let what = match markup {
                        Some(m) => format!("{}>", m.chars().take(40).collect::<String>()),
                        None => "an unknown entity reference".into(),
                    };
                    return Err(format!("<{name}> at line {} holds {what} where numbers belong", self.line(at)));
                };
                let tight = tighten(&text);
                // The kml crate reads every `coordinates` inside a geometry,
                // at any depth, the last one winning.
                let in_geometry =
                    self.open.iter().any(|o| matches!(local(&o.name), "Point" | "LineString" | "LinearRing"));
                if in_geometry && let Some(bad) = tight.split_whitespace().find(|t| !is_tuple(t)) {
                    let bad: String = bad.chars().take(40).collect();
                    return Err(format!(
                        "'{bad}' in <{name}> at line {} is not longitude,latitude[,altitude]",
                        self.line(at)
                    ));
                }
                let has_tuple = tight.split_whitespace().next().is_some();
                for (_, point_has_tuple) in self.open.iter_mut().filter_map(|o| o.point.as_mut()) {
                    *point_has_tuple = has_tuple;
                }
                if tight != raw {
                    let escaped = quick_xml::escape::partial_escape(tight.as_str()).into_owned();
                    self.replace(content, close, &escaped);
                }
            }
            _ => {
                if !is_xml_text(raw) {
                    let cdata = cdata(raw);
                    self.replace(content, close, &cdata);
                }
            }
        }
        Ok(())
    }

    fn warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        for ((written, read), seen) in &self.remapped {
            let known = matches!(written.as_str(), "relativeToSeaFloor" | "clampToSeaFloor");
            let why = if known { "relief has no sea floor" } else { "it is not a KML altitude mode" };
            let count = seen.placemarks.len();
            let s = |n: usize| if n == 1 { "" } else { "s" };
            let where_ = match (count, seen.elsewhere) {
                (count, 0) => format!("{count} placemark{}", s(count)),
                (0, n) => format!("{n} element{} outside placemarks", s(n)),
                (count, n) => format!("{count} placemark{} (and {n} element{} outside placemarks)", s(count), s(n)),
            };
            warnings.push(format!("altitude mode '{written}' read as '{read}' in {where_}: {why}"));
        }
        for torn in &self.torn {
            warnings.push(format!("{torn} was left out: its tags do not match; the other placemarks are read"));
        }
        if self.points_left_out > 0 {
            let n = self.points_left_out;
            let s = if n == 1 { "" } else { "s" };
            warnings.push(format!("{n} point{s} without coordinates left out"));
        }
        warnings
    }

    /// Copies the text up to `until` into the output.
    fn flush(&mut self, until: usize) {
        if until > self.copied {
            self.out.push_str(self.text.get(self.copied..until).unwrap_or_default());
            self.copied = until;
        }
    }

    /// Writes `with` in place of the text from `start` to `end`.
    fn replace(&mut self, start: usize, end: usize, with: &str) {
        self.flush(start);
        self.out.push_str(with);
        self.copied = self.copied.max(end);
        self.changed = true;
    }

    fn line(&self, at: usize) -> usize {
        line_of(self.text, at)
    }
}

/// Elements the kml crate reads as one value (with its `read_str`), in
/// some places: markup inside one of those makes it refuse the document.
const VALUES: &[&str] = &[
    "styleUrl",
    "extrude",
    "tessellate",
    "key",
    "href",
    "refreshMode",
    "viewRefreshMode",
    "viewFormat",
    "httpQuery",
    "targetHref",
    "sourceHref",
    "color",
    "colorMode",
    "bgColor",
    "textColor",
    "displayMode",
    "fill",
    "outline",
    "maxSnippetLines",
    "x",
    "y",
    "z",
    "roll",
    "tilt",
    "heading",
    "longitude",
    "latitude",
    "altitude",
    "scale",
    "width",
    "refreshInterval",
    "viewRefreshTime",
    "viewBoundScale",
    "SimpleData",
];

/// Why the kml crate found markup where it reads a value, in words: the
/// first value element (of tidied text) that holds an element.
pub(crate) fn markup_in_value(text: &str) -> Option<String> {
    let mut reader = Reader::from_str(text);
    let mut open: Vec<(String, usize)> = Vec::new();
    loop {
        let before = reader.buffer_position() as usize;
        let (start, empty) = match reader.read_event().ok()? {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(_) => {
                open.pop();
                continue;
            }
            Event::Eof => return None,
            _ => continue,
        };
        let name = String::from_utf8_lossy(start.name().as_ref()).into_owned();
        if let Some((value, at)) = open.last().filter(|(value, _)| VALUES.contains(&local(value))) {
            let line = line_of(text, *at);
            return Some(format!("<{value}> at line {line} holds <{name}> where a value belongs"));
        }
        if !empty {
            open.push((name, before));
        }
    }
}

/// Elements read here as raw text: free text for people, altitude modes
/// and coordinates.
fn is_text_element(name: &str) -> bool {
    let local = local(name);
    PROSE.contains(&local) || local == "altitudeMode" || local == "coordinates"
}

/// The 1-based line of a byte offset.
fn line_of(text: &str, at: usize) -> usize {
    text.as_bytes()[..at.min(text.len())].split(|&b| b == b'\n').count()
}

/// A name without its prefix (`gx:altitudeMode` is `altitudeMode`).
fn local(name: &str) -> &str {
    name.rsplit(':').next().unwrap_or(name)
}

/// Where the end tag of `name` begins and ends, searched from `from` in the
/// raw text, past CDATA sections and comments.
fn close_of(text: &str, name: &str, from: usize) -> Option<(usize, usize)> {
    let mut at = from;
    loop {
        let rest = text.get(at..)?;
        let lt = at + rest.find('<')?;
        let tail = &text[lt..];
        if let Some(inner) = tail.strip_prefix("<![CDATA[") {
            at = lt + "<![CDATA[".len() + inner.find("]]>")? + "]]>".len();
        } else if let Some(inner) = tail.strip_prefix("<!--") {
            at = lt + "<!--".len() + inner.find("-->")? + "-->".len();
        } else if let Some(after) = tail.strip_prefix("</").and_then(|t| t.strip_prefix(name)) {
            let spaces = after.len() - after.trim_start().len();
            if after[spaces..].starts_with('>') {
                return Some((lt, lt + 2 + name.len() + spaces + 1));
            }
            at = lt + 1;
        } else {
            at = lt + 1;
        }
    }
}

/// The pieces of raw element content: text (still escaped), CDATA
/// sections' insides, comments and anything else that starts with `<`.
enum Piece<'a> {
    Text(&'a str),
    CData(&'a str),
    Comment,
    Markup(&'a str),
}

fn pieces(raw: &str) -> Vec<Piece<'_>> {
    let mut out = Vec::new();
    let mut rest = raw;
    while !rest.is_empty() {
        let Some(lt) = rest.find('<') else {
            out.push(Piece::Text(rest));
            break;
        };
        if lt > 0 {
            out.push(Piece::Text(&rest[..lt]));
        }
        let tail = &rest[lt..];
        let (piece, len) = if let Some(end) = tail.strip_prefix("<![CDATA[").and_then(|t| t.find("]]>")) {
            (Piece::CData(&tail[9..9 + end]), 9 + end + 3)
        } else if let Some(end) = tail.strip_prefix("<!--").and_then(|t| t.find("-->")) {
            (Piece::Comment, 4 + end + 3)
        } else {
            let len = tail[1..].find('<').map_or(tail.len(), |n| n + 1);
            (Piece::Markup(&tail[..len]), len)
        };
        out.push(piece);
        rest = &tail[len..];
    }
    out
}

/// The text of raw content that holds only text, CDATA and comments, its
/// references resolved; `None` when it holds markup or an unknown reference.
fn plain(raw: &str) -> Option<String> {
    let mut text = String::new();
    for piece in pieces(raw) {
        match piece {
            Piece::Text(t) => text.push_str(&quick_xml::escape::unescape(t).ok()?),
            Piece::CData(t) => text.push_str(t),
            Piece::Comment => {}
            Piece::Markup(_) => return None,
        }
    }
    Some(text)
}

/// True when the kml crate reads this content as it stands: text with
/// known references, and CDATA.
fn is_xml_text(raw: &str) -> bool {
    pieces(raw).iter().all(|piece| match piece {
        Piece::Text(t) => quick_xml::escape::unescape(t).is_ok(),
        Piece::CData(_) => true,
        Piece::Comment | Piece::Markup(_) => false,
    })
}

/// Raw content as one CDATA section: the text is the markup as written
/// (HTML, for a description), CDATA inside it unwrapped.
fn cdata(raw: &str) -> String {
    let mut inner = String::with_capacity(raw.len());
    for piece in pieces(raw) {
        match piece {
            Piece::Text(t) | Piece::Markup(t) | Piece::CData(t) => inner.push_str(t),
            Piece::Comment => {}
        }
    }
    format!("<![CDATA[{}]]>", inner.replace("]]>", "]]]]><![CDATA[>"))
}

/// Inside coordinates, tuples are separated by whitespace and their parts
/// by commas; writers that put a space after a comma ("19, 37") are common
/// enough to read them as meant.
fn tighten(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut after_comma = false;
    for c in text.chars() {
        if after_comma && c.is_whitespace() {
            continue;
        }
        after_comma = c == ',';
        out.push(c);
    }
    out
}

/// A coordinate tuple as the kml crate reads one: two or three numbers
/// (more are ignored).
fn is_tuple(token: &str) -> bool {
    let mut parts = token.split(',');
    let mut number = |required: bool| match parts.next() {
        Some(p) => p.parse::<f64>().is_ok(),
        None => !required,
    };
    number(true) && number(true) && number(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(text: &str) -> Result<(String, Vec<String>), String> {
        Pass::new(text).run().map(|t| (t.text.into_owned(), t.warnings))
    }

    #[test]
    fn a_placemark_whose_tags_do_not_match_is_left_out_and_the_others_read() -> Result<(), String> {
        let text = "<kml><Document>\n\
             <Placemark><name>a</name><Point><coordinates>1,2</coordinates></Point></Placemark>\n\
             <Placemark><name>b</name><ExtendedData><Data name=\"x\"><value>1</value></Dta>\n\
             </ExtendedData><Point><coordinates>3,4</coordinates></Point></Placemark>\n\
             <Placemark><name>c</name><ExtendedData><Data name=\"y\"><value>2</value></ExtendedData></Placemark>\n\
             <Placemark><name>d</name><Point><coordinates>5,6</coordinates></Point></Placemark>\n\
             </Document></kml>";
        let (out, warnings) = run(text)?;
        assert!(out.contains("<name>a</name>") && out.contains("<name>d</name>"), "{out}");
        assert!(!out.contains("<name>b</name>") && !out.contains("<name>c</name>"), "{out}");
        assert!(out.ends_with("</Document></kml>"), "{out}");
        assert_eq!(
            warnings,
            [
                "the placemark at lines 3-4 (<Data> opened at line 3 is closed by </Dta> at line 3) was left out: \
                 its tags do not match; the other placemarks are read",
                "the placemark at line 5 (<Data> opened at line 5 is closed by </ExtendedData> at line 5) was left \
                 out: its tags do not match; the other placemarks are read",
            ]
        );
        Ok(())
    }

    #[test]
    fn every_placemark_torn_or_a_tear_outside_placemarks_is_refused() {
        let all =
            "<kml><Document>\n<Placemark><name>a</Name></Placemark>\n<Placemark><b></Placemark>\n</Document></kml>";
        let err = run(all).unwrap_err();
        assert!(err.starts_with("every placemark is torn: the placemark at line 2"), "{err}");
        let outside = "<kml><Document><Folder><name>f</name></Document></kml>";
        assert_eq!(run(outside).unwrap_err(), "<Folder> opened at line 1 is closed by </Document> at line 1");
        let cut = "<kml><Document><Placemark><name>a</name><Point><coordinates>1,2</coordinates></Point></Placemark><Placemark><Data>";
        assert!(run(cut).unwrap_err().contains("never closed"), "a file cut short");
    }

    #[test]
    fn clean_kml_is_copied_unchanged() -> Result<(), String> {
        let text = r#"<?xml version="1.0"?><kml><Document><Placemark><name>a &amp; b</name><description><![CDATA[<b>x</b>]]></description><Point><altitudeMode>absolute</altitudeMode><coordinates>1,2,3</coordinates></Point></Placemark></Document></kml>"#;
        let tidied = Pass::new(text).run()?;
        assert!(matches!(tidied.text, Cow::Borrowed(_)));
        assert!(tidied.warnings.is_empty());
        Ok(())
    }

    #[test]
    fn sea_floor_modes_are_read_as_ground_modes_with_a_warning() -> Result<(), String> {
        let (text, warnings) = run(
            "<kml><Placemark><Point><gx:altitudeMode>relativeToSeaFloor</gx:altitudeMode><coordinates>1,2</coordinates></Point></Placemark>\
             <Placemark><LineString><gx:altitudeMode> clampToSeaFloor </gx:altitudeMode><coordinates>1,2 3,4</coordinates></LineString></Placemark>\
             <Placemark><Point><gx:altitudeMode>relativeToSeaFloor</gx:altitudeMode><coordinates>1,2</coordinates></Point></Placemark></kml>",
        )?;
        assert!(text.contains("<gx:altitudeMode>relativeToGround</gx:altitudeMode>"), "{text}");
        assert!(text.contains("<gx:altitudeMode>clampToGround</gx:altitudeMode>"), "{text}");
        assert_eq!(
            warnings,
            [
                "altitude mode 'clampToSeaFloor' read as 'clampToGround' in 1 placemark: relief has no sea floor",
                "altitude mode 'relativeToSeaFloor' read as 'relativeToGround' in 2 placemarks: relief has no sea floor",
            ]
        );
        Ok(())
    }

    #[test]
    fn a_mode_outside_placemarks_is_counted_as_such() -> Result<(), String> {
        let (_, warnings) = run("<GroundOverlay><gx:altitudeMode>clampToSeaFloor</gx:altitudeMode></GroundOverlay>")?;
        assert_eq!(
            warnings,
            [
                "altitude mode 'clampToSeaFloor' read as 'clampToGround' in 1 element outside placemarks: relief has no sea floor"
            ]
        );
        Ok(())
    }

    #[test]
    fn html_in_a_description_becomes_cdata() -> Result<(), String> {
        let (text, _) =
            run(r#"<Placemark><description><b>bold</b> &nbsp;<a href="x">link</a><br></description></Placemark>"#)?;
        assert_eq!(
            text,
            r#"<Placemark><description><![CDATA[<b>bold</b> &nbsp;<a href="x">link</a><br>]]></description></Placemark>"#
        );
        let (text, _) = run("<name>a <i>]]></i><![CDATA[<c>]]></name>")?;
        assert_eq!(text, "<name><![CDATA[a <i>]]]]><![CDATA[></i><c>]]></name>");
        Ok(())
    }

    #[test]
    fn coordinates_are_tightened_checked_and_empty_points_left_out() -> Result<(), String> {
        let (text, _) = run("<LineString><coordinates>1, 2 3,\t4</coordinates></LineString>")?;
        assert_eq!(text, "<LineString><coordinates>1,2 3,4</coordinates></LineString>");
        let (text, warnings) = run(
            "<Placemark><Point><altitudeMode>absolute</altitudeMode><coordinates> </coordinates></Point></Placemark>",
        )?;
        assert_eq!(text, "<Placemark></Placemark>");
        assert_eq!(warnings, ["1 point without coordinates left out"]);
        let e = run("<Point>\n<coordinates>1,x</coordinates></Point>").unwrap_err();
        assert_eq!(e, "'1,x' in <coordinates> at line 2 is not longitude,latitude[,altitude]");
        Ok(())
    }

    #[test]
    fn stray_ampersands_and_doctypes_are_mended() -> Result<(), String> {
        let (text, _) = run("<!DOCTYPE kml><href>a?b=1&c=2&amp;d&bogus;</href>")?;
        assert_eq!(text, "<href>a?b=1&amp;c=2&amp;d&amp;bogus;</href>");
        Ok(())
    }

    #[test]
    fn broken_nesting_is_refused_with_lines() {
        assert_eq!(
            run("<kml>\n<Folder>\n</Document>").unwrap_err(),
            "<Folder> opened at line 2 is closed by </Document> at line 3"
        );
        assert_eq!(
            run("<kml><Placemark><Point>").unwrap_err(),
            "<Point> opened at line 1 is never closed (the file may be cut short)"
        );
        assert_eq!(run("<kml><name>x</kml>").unwrap_err(), "<name> at line 1 is never closed");
        let deep = "<a>".repeat(MAX_DEPTH + 1);
        assert!(run(&deep).unwrap_err().starts_with("elements nest more than 256 deep"));
    }
}
