//! A tile as bytes for a store outside the process: a header (magic,
//! the tile's address, its content hash) and the payload in postcard. A
//! record is taken back only when its magic and address match and its
//! payload hashes to the recorded content hash, so a torn write, a
//! truncated file or a record of another format reads as a miss.

use std::sync::Arc;

use relief_source::Payload;

use crate::tile::Tile;

const MAGIC: &[u8; 8] = b"RLFTILE1";
const HEADER: usize = 8 + 16 + 8;

pub fn encode(address: u128, tile: &Tile) -> Option<Vec<u8>> {
    let body = postcard::to_stdvec(&*tile.payload).ok()?;
    let mut bytes = Vec::with_capacity(HEADER + body.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&address.to_le_bytes());
    bytes.extend_from_slice(&tile.content_hash.to_le_bytes());
    bytes.extend_from_slice(&body);
    Some(bytes)
}

/// The tile in `bytes`, if they are a whole record of `address`.
pub fn decode(address: u128, bytes: &[u8]) -> Option<Tile> {
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return None;
    }
    let recorded = u128::from_le_bytes(bytes[8..24].try_into().ok()?);
    let content_hash = u64::from_le_bytes(bytes[24..32].try_into().ok()?);
    if recorded != address {
        return None;
    }
    let payload: Payload = postcard::from_bytes(&bytes[HEADER..]).ok()?;
    (payload.content_hash() == content_hash).then(|| Tile { payload: Arc::new(payload), content_hash })
}

#[cfg(test)]
mod tests {
    use relief_source::HeightTile;

    use super::*;

    #[test]
    fn a_record_reads_back_and_a_damaged_one_is_a_miss() {
        let payload = Payload::Height(HeightTile { size: 2, heights: vec![1.0, f32::NAN, 3.5, -2.0] });
        let tile = Tile { content_hash: payload.content_hash(), payload: Arc::new(payload) };
        let bytes = encode(42, &tile).expect("encodes");
        let back = decode(42, &bytes).expect("decodes");
        assert_eq!(back.content_hash, tile.content_hash);
        assert!(decode(43, &bytes).is_none(), "another address");
        assert!(decode(42, &bytes[..bytes.len() - 1]).is_none(), "truncated");
        let mut flipped = bytes.clone();
        let last = flipped.len() - 1;
        flipped[last] ^= 0x40;
        assert!(decode(42, &flipped).is_none(), "a flipped byte");
        assert!(decode(42, b"RLFTILE0").is_none());
    }
}
