//! relief-testkit: what relief's property tests share, as a dev-dependency
//! of the crates whose parsers they spoil.
//!
//! - `Mutation`, `mutation` and `apply`: files spoiled byte by byte (bytes
//!   replaced or flipped, text put in, spans dropped or repeated, the file
//!   cut short), the text put in chosen by each format.
//! - `DebugMarks` and `in_words`: a message shows no Rust `Debug` output and
//!   ends with the path it speaks of.
//!
//! It depends on proptest only: nothing of relief's, so any crate's tests
//! may use it.

mod debug;
mod mutation;

pub use debug::{DebugMarks, in_words};
pub use mutation::{Mutation, apply, mutation};
