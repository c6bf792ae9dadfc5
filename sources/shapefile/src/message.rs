//! The shapefile and dBase crates' errors as plain lower-case sentences.
//! Their own `Display` falls back on `Debug` for some errors (`DbaseError(..)`,
//! `Error { kind: .. }`, `dbase::Numeric`), which no user should see.

use shapefile::dbase;

/// What went wrong reading a shape.
pub(crate) fn shape(error: &shapefile::Error) -> String {
    use shapefile::Error as E;
    match error {
        E::IoError(e) => io(e),
        E::InvalidFileCode(code) => format!("not a shapefile (file code {code})"),
        E::InvalidShapeType(code) => format!("unknown shape type {code}"),
        E::InvalidPatchType(code) => format!("unknown multipatch part type {code}"),
        E::MismatchShapeType { .. } => "a shape of another type than the file's".to_owned(),
        E::InvalidShapeRecordSize => "its declared size does not match its parts and points".to_owned(),
        E::AllocationLimitExceeded { requested_bytes } => {
            format!("it declares {requested_bytes} bytes of parts or points, more than can be held")
        }
        E::DbaseError(e) => table(e, &[]),
        E::MissingDbf => "no .dbf".to_owned(),
        E::MissingIndexFile => "no .shx".to_owned(),
        // Variants behind the crate's optional features.
        #[allow(unreachable_patterns)]
        other => lower_first(&other.to_string()),
    }
}

/// What went wrong reading the attribute table; `fields` names the fields
/// by index, where known.
pub(crate) fn table(error: &dbase::Error, fields: &[String]) -> String {
    let what = kind(error.kind());
    let field = error.field_index().map(|f| match fields.get(f.0) {
        Some(name) => format!("field '{name}'"),
        None => format!("field {}", f.0 + 1),
    });
    match (error.record_index(), field) {
        (Some(record), Some(field)) => format!("record {}, {field}: {what}", record.0),
        (Some(record), None) => format!("record {}: {what}", record.0),
        (None, _) => format!("its header: {what}"),
    }
}

fn kind(kind: &dbase::ErrorKind) -> String {
    use dbase::ErrorKind as K;
    match kind {
        K::IoError(e) => io(e),
        K::ParseFloatError(e) => format!("not a number ({e})"),
        K::ParseIntError(e) => format!("not a whole number ({e})"),
        K::InvalidDate(e) => format!("invalid date ({})", lower_first(&e.to_string())),
        K::InvalidTime(e) => format!("invalid time ({e})"),
        K::InvalidFieldType(c) => format!("unknown field type '{}'", c.escape_default()),
        K::MissingMemoFile | K::ErrorOpeningMemoFile(_) => {
            "a memo field, and relief does not read memo (.dbt, .fpt) files".to_owned()
        }
        K::BadConversion(_) | K::IncompatibleType => "a value of the wrong type for its field".to_owned(),
        K::EndOfRecord => "the record ends before its last field".to_owned(),
        K::UnsupportedCodePage(_) => {
            "its code page is not one relief can decode; a .cpg naming the encoding (such as UTF-8) fixes this"
                .to_owned()
        }
        K::StringDecodeError(e) => format!("text that is not in the table's encoding ({e})"),
        K::InvalidFile(details) => lower_first(details),
        K::Message(message) => lower_first(message),
        other => lower_first(&other.to_string()),
    }
}

fn io(error: &std::io::Error) -> String {
    if error.kind() == std::io::ErrorKind::UnexpectedEof {
        "it runs past the end of the file".to_owned()
    } else {
        lower_first(&error.to_string())
    }
}

fn lower_first(text: &str) -> String {
    let mut chars = text.chars();
    chars.next().map(|c| c.to_lowercase().chain(chars).collect()).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_message_shows_debug_output() {
        let errors = [
            shapefile::Error::MissingDbf,
            shapefile::Error::InvalidShapeRecordSize,
            shapefile::Error::IoError(std::io::ErrorKind::UnexpectedEof.into()),
        ];
        for e in &errors {
            let text = shape(e);
            assert!(!text.contains("Some(") && !text.contains('{') && !text.contains("Error"), "{text}");
            assert_eq!(text, lower_first(&text), "{text}");
        }
        assert_eq!(lower_first("The file"), "the file");
        assert_eq!(lower_first(""), "");
    }
}
