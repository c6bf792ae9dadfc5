//! The URIs a glTF buffer may use: `data:` URIs and relative file paths.

use std::path::{Path, PathBuf};

/// The bytes of a `data:[<media type>][;base64],<data>` URI; `None` when
/// `uri` is not a data URI.
pub(crate) fn data_uri(uri: &str) -> Option<Result<Vec<u8>, String>> {
    let head = uri.get(..5)?;
    if !head.eq_ignore_ascii_case("data:") {
        return None;
    }
    let rest = &uri[5..];
    let Some((media, data)) = rest.split_once(',') else {
        return Some(Err("the data URI has no ',' before its data".to_owned()));
    };
    let is_base64 = media.rsplit(';').next().is_some_and(|p| p.eq_ignore_ascii_case("base64"));
    Some(if is_base64 { base64(data) } else { Ok(percent_decode(data)) })
}

/// The path a relative URI names, taken from `dir` (the folder of the file
/// that holds the URI). URIs with a scheme (`http:`, `file:`) are refused:
/// a model reads only files beside it.
pub(crate) fn relative_path(dir: &Path, uri: &str) -> Result<PathBuf, String> {
    let end = uri.find(['?', '#']).unwrap_or(uri.len());
    let uri = &uri[..end];
    if let Some((scheme, _)) = uri.split_once(':')
        && !scheme.is_empty()
        && !scheme.contains('/')
    {
        return Err(format!("'{scheme}:' URIs are not read, only data: URIs and relative file paths"));
    }
    if uri.starts_with('/') {
        return Err("absolute paths are not read, only data: URIs and relative file paths".to_owned());
    }
    let decoded = String::from_utf8(percent_decode(uri)).map_err(|_| "the decoded URI is not UTF-8 text".to_owned())?;
    Ok(dir.join(decoded))
}

/// Decodes base64 (standard or URL-safe alphabet, padding optional,
/// whitespace skipped).
pub(crate) fn base64(text: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0u32;
    let mut padded = false;
    for (i, c) in text.char_indices() {
        let value = match c {
            'A'..='Z' => c as u32 - 'A' as u32,
            'a'..='z' => c as u32 - 'a' as u32 + 26,
            '0'..='9' => c as u32 - '0' as u32 + 52,
            '+' | '-' => 62,
            '/' | '_' => 63,
            '=' => {
                padded = true;
                continue;
            }
            ' ' | '\t' | '\r' | '\n' => continue,
            _ => return Err(format!("'{c}' at character {i} of the base64 data is not base64")),
        };
        if padded {
            return Err(format!("base64 data continues after its '=' padding at character {i}"));
        }
        acc = (acc << 6) | value;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// Replaces `%XX` escapes by their bytes; anything else is kept as it is.
fn percent_decode(text: &str) -> Vec<u8> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let escaped = (bytes[i] == b'%')
            .then(|| bytes.get(i + 1..i + 3))
            .flatten()
            .and_then(|hex| std::str::from_utf8(hex).ok())
            .and_then(|hex| u8::from_str_radix(hex, 16).ok());
        match escaped {
            Some(byte) => {
                out.push(byte);
                i += 3;
            }
            None => {
                out.push(bytes[i]);
                i += 1;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes_with_and_without_padding() {
        assert_eq!(base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(base64("aGVsbG8").unwrap(), b"hello");
        assert_eq!(base64("aGVs\nbG8h").unwrap(), b"hello!");
        assert_eq!(base64("").unwrap(), b"");
        assert_eq!(base64("/+8=").unwrap(), [0xff, 0xef]);
        assert!(base64("aGV*bG8=").unwrap_err().contains("'*'"));
        assert!(base64("aG=Vs").is_err());
    }

    #[test]
    fn data_uris_decode_and_other_uris_are_not_data() {
        assert_eq!(data_uri("data:application/octet-stream;base64,AAEC").unwrap().unwrap(), [0, 1, 2]);
        assert_eq!(data_uri("data:,a%20b").unwrap().unwrap(), b"a b");
        assert!(data_uri("data:application/octet-stream;base64").unwrap().is_err());
        assert!(data_uri("tree.bin").is_none());
        assert!(data_uri("").is_none());
    }

    #[test]
    fn relative_paths_are_decoded_and_schemes_refused() {
        let dir = Path::new("/models");
        assert_eq!(relative_path(dir, "oak%20tree.bin").unwrap(), Path::new("/models/oak tree.bin"));
        assert_eq!(relative_path(dir, "bin/oak.bin?v=2").unwrap(), Path::new("/models/bin/oak.bin"));
        assert!(relative_path(dir, "https://example.com/oak.bin").unwrap_err().contains("'https:'"));
        assert!(relative_path(dir, "/etc/oak.bin").is_err());
    }
}
