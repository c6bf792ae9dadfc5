//! Messages meant for people: in words, with no Rust `Debug` output (a
//! library's error printed with `{:?}`), and the path they speak of last.

use std::path::Path;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// What gives Rust `Debug` output away in a message: marks (text that only
/// `Debug` output holds, such as `Some(` or a quick-xml `BytesStart`) and,
/// where asked, a struct's ` { field: `.
///
/// Each format keeps its own list: what counts as a mark depends on what
/// its messages may rightly hold (a TOML message may suggest an inline
/// table, ` { crs = ... }`, so the manifest's tests look for struct fields
/// rather than ` { `).
#[derive(Debug, Clone, Copy)]
pub struct DebugMarks {
    marks: &'static [&'static str],
    struct_fields: bool,
}

impl DebugMarks {
    /// These marks only.
    pub const fn new(marks: &'static [&'static str]) -> Self {
        Self { marks, struct_fields: false }
    }

    /// These marks, and a struct's ` { field: ` too.
    #[must_use]
    pub const fn and_struct_fields(self) -> Self {
        Self { struct_fields: true, ..self }
    }

    /// The first sign of `Debug` output in `text`: the first of the marks
    /// (in their order) that it holds, else, where struct fields count, the
    /// first ` { field:` (a name of letters, digits and `_`, then a colon);
    /// None when there is none.
    pub fn find<'t>(&self, text: &'t str) -> Option<&'t str> {
        if let Some(at) = self.marks.iter().find_map(|mark| text.find(mark).map(|at| &text[at..at + mark.len()])) {
            return Some(at);
        }
        if !self.struct_fields {
            return None;
        }
        text.match_indices(" { ").find_map(|(at, _)| {
            let rest = &text[at + 3..];
            let field = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(rest.len());
            (field > 0 && rest[field..].starts_with(':')).then(|| &text[at..=(at + 3 + field)])
        })
    }
}

/// Fails the test case unless `message` is in words with the path last:
/// `debug` (what `DebugMarks::find` found in it, less what the caller
/// excuses) is None, and the message ends with `path`.
pub fn in_words(message: &str, debug: Option<&str>, path: &Path) -> Result<(), TestCaseError> {
    prop_assert!(debug.is_none(), "Debug output ({}) in: {}", debug.unwrap_or_default(), message);
    prop_assert!(message.ends_with(&path.display().to_string()), "the path is not last: {}", message);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MARKS: DebugMarks = DebugMarks::new(&["BytesStart", "Some("]);

    #[test]
    fn the_first_mark_in_the_lists_order_is_found() {
        assert_eq!(MARKS.find("bad: Some(Start(BytesStart { buf: 1 }))"), Some("BytesStart"));
        assert_eq!(MARKS.find("bad: Some(1)"), Some("Some("));
        assert_eq!(MARKS.find("bad: Point { x: 1 }"), None, "struct fields were not asked for");
    }

    #[test]
    fn struct_fields_are_told_from_inline_tables() {
        let marks = MARKS.and_struct_fields();
        assert_eq!(marks.find("bad: Point { x: 1 }"), Some(" { x:"));
        assert_eq!(marks.find("bad: Error { kind_2: 1 }"), Some(" { kind_2:"));
        assert_eq!(marks.find("use \"geodetic\" or { crs = \"EPSG:...\" }"), None);
        assert_eq!(marks.find("a { : b"), None);
    }

    #[test]
    fn a_message_in_words_ends_with_its_path() {
        let path = Path::new("data/roads.kml");
        assert!(in_words("cannot read: data/roads.kml", None, path).is_ok());
        assert!(in_words("cannot read: data/roads.kml", Some("Some("), path).is_err());
        assert!(in_words("data/roads.kml: cannot read", None, path).is_err());
    }
}
