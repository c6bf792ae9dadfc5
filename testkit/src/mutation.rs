//! Files spoiled byte by byte, as a disk, a transfer or a careless writer
//! might spoil them.

use proptest::prelude::*;
use proptest::sample::Index;

/// One change to a file's bytes. Positions are proptest `Index`es, scaled
/// to the file's length when applied, so a mutation fits any file.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// A byte replaced.
    Set(Index, u8),
    /// A byte's bit flipped (the bit's number, 0 to 7).
    Flip(Index, u8),
    /// Text put in, one of the format's inserts (see `mutation`).
    Insert(Index, &'static str),
    /// A span of up to so many bytes dropped.
    Drop(Index, usize),
    /// A span of up to so many bytes written twice.
    Repeat(Index, usize),
    /// The file cut short.
    Cut(Index),
}

/// Any one `Mutation`, insertions three times as likely as each other kind;
/// what `Insert` puts in is one of `inserts`: the markup or punctuation of
/// the format under test, whole and in broken halves, which reaches its
/// parser further than random bytes do.
///
/// # Panics
///
/// When `inserts` is empty.
pub fn mutation(inserts: &'static [&'static str]) -> impl Strategy<Value = Mutation> {
    assert!(!inserts.is_empty(), "a mutation strategy needs text to insert");
    prop_oneof![
        1 => (any::<Index>(), any::<u8>()).prop_map(|(at, b)| Mutation::Set(at, b)),
        1 => (any::<Index>(), 0u8..8).prop_map(|(at, bit)| Mutation::Flip(at, bit)),
        3 => (any::<Index>(), any::<Index>())
            .prop_map(move |(at, what)| Mutation::Insert(at, inserts[what.index(inserts.len())])),
        1 => (any::<Index>(), 1usize..64).prop_map(|(at, len)| Mutation::Drop(at, len)),
        1 => (any::<Index>(), 1usize..64).prop_map(|(at, len)| Mutation::Repeat(at, len)),
        1 => any::<Index>().prop_map(Mutation::Cut),
    ]
}

/// Applies `mutations` to `bytes` in order, stopping once nothing is left.
pub fn apply(bytes: &mut Vec<u8>, mutations: &[Mutation]) {
    for m in mutations {
        if bytes.is_empty() {
            return;
        }
        let len = bytes.len();
        match m {
            Mutation::Set(at, b) => bytes[at.index(len)] = *b,
            Mutation::Flip(at, bit) => bytes[at.index(len)] ^= 1 << bit,
            Mutation::Insert(at, text) => {
                let at = at.index(len + 1);
                bytes.splice(at..at, text.bytes());
            }
            Mutation::Drop(at, n) => {
                let at = at.index(len);
                bytes.drain(at..(at + n).min(len));
            }
            Mutation::Repeat(at, n) => {
                let at = at.index(len);
                let span = bytes[at..(at + n).min(len)].to_vec();
                bytes.splice(at..at, span);
            }
            Mutation::Cut(at) => bytes.truncate(at.index(len)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What each mutation should leave of `bytes`, written as slices put
    /// together.
    fn expected(bytes: &[u8], m: &Mutation) -> Vec<u8> {
        let len = bytes.len();
        match m {
            Mutation::Set(at, b) => {
                let i = at.index(len);
                [&bytes[..i], &[*b], &bytes[i + 1..]].concat()
            }
            Mutation::Flip(at, bit) => {
                let i = at.index(len);
                [&bytes[..i], &[bytes[i] ^ (1 << bit)], &bytes[i + 1..]].concat()
            }
            Mutation::Insert(at, text) => {
                let i = at.index(len + 1);
                [&bytes[..i], text.as_bytes(), &bytes[i..]].concat()
            }
            Mutation::Drop(at, n) => {
                let i = at.index(len);
                [&bytes[..i], &bytes[(i + n).min(len)..]].concat()
            }
            Mutation::Repeat(at, n) => {
                let i = at.index(len);
                [&bytes[..(i + n).min(len)], &bytes[i..]].concat()
            }
            Mutation::Cut(at) => bytes[..at.index(len)].to_vec(),
        }
    }

    proptest! {
        #[test]
        fn each_mutation_changes_what_it_names(
            bytes in prop::collection::vec(any::<u8>(), 1..100),
            m in mutation(&["<a>", "é"]),
        ) {
            let mut after = bytes.clone();
            apply(&mut after, std::slice::from_ref(&m));
            prop_assert_eq!(after, expected(&bytes, &m), "{:?}", m);
        }

        #[test]
        fn an_empty_file_takes_no_mutations(ms in prop::collection::vec(mutation(&["x"]), 1..5)) {
            let mut bytes = Vec::new();
            apply(&mut bytes, &ms);
            prop_assert!(bytes.is_empty());
        }
    }
}
