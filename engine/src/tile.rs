//! A generated tile, as the memory cache and the outer stores (disk,
//! Redis) hold it: below both, so that neither imports the other.

use std::sync::Arc;

use relief_source::Payload;

/// A generated tile and the hash of its content.
#[derive(Debug)]
pub struct Tile {
    pub payload: Arc<Payload>,
    pub content_hash: u64,
}
