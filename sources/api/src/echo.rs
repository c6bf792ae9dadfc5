//! What an error message says back of what a caller or a file sent: at most
//! [`MOST_CHARS`] characters of it, so a megabyte id is not answered with
//! a megabyte message.

/// Characters of a caller's text an error repeats.
pub const MOST_CHARS: usize = 200;

/// `text` as an error message repeats it: whole when short, else its first
/// [`MOST_CHARS`] characters and how many more there were.
pub fn echoed(text: &str) -> String {
    match text.char_indices().nth(MOST_CHARS) {
        None => text.to_owned(),
        Some((cut, _)) => format!("{}... ({} more bytes)", &text[..cut], text.len() - cut),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_texts_are_cut_and_short_ones_kept() {
        assert_eq!(echoed("dem"), "dem");
        let long = "é".repeat(1000);
        let cut = echoed(&long);
        assert!(cut.starts_with(&"é".repeat(MOST_CHARS)) && cut.ends_with("... (1600 more bytes)"), "{cut}");
    }
}
