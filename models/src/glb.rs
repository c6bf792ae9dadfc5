//! The GLB container: a 12-byte header, a JSON chunk and an optional BIN
//! chunk, each chunk padded to 4 bytes.

const MAGIC: &[u8; 4] = b"glTF";
const HEADER_BYTES: usize = 12;
const CHUNK_HEADER_BYTES: usize = 8;
const CHUNK_JSON: u32 = u32::from_le_bytes(*b"JSON");
const CHUNK_BIN: u32 = u32::from_le_bytes(*b"BIN\0");

/// True when `bytes` start like a GLB file.
pub(crate) fn is_glb(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// The JSON and BIN chunks of a GLB file. Chunks of unknown types are
/// skipped, as the specification asks.
pub(crate) fn split(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    if bytes.len() < HEADER_BYTES {
        return Err(format!("its GLB header is cut short ({} of {HEADER_BYTES} bytes)", bytes.len()));
    }
    let version = u32_at(bytes, 4);
    if version != 2 {
        return Err(format!("it is a version {version} GLB file; only version 2 is read"));
    }
    let length = u32_at(bytes, 8) as usize;
    if length > bytes.len() {
        return Err(format!("its GLB header says {length} bytes but the file has {} (cut short?)", bytes.len()));
    }
    if length < HEADER_BYTES {
        return Err(format!("its GLB header says {length} bytes, less than the header itself"));
    }
    let mut rest = &bytes[HEADER_BYTES..length];
    let (mut json, mut bin) = (None, None);
    // A tail shorter than a chunk header is padding, however it got there.
    while rest.len() >= CHUNK_HEADER_BYTES {
        let chunk_length = u32_at(rest, 0) as usize;
        let kind = u32_at(rest, 4);
        let body = rest
            .get(CHUNK_HEADER_BYTES..CHUNK_HEADER_BYTES.saturating_add(chunk_length))
            .ok_or_else(|| format!("a GLB chunk of {chunk_length} bytes reaches past the end of the file"))?;
        match kind {
            CHUNK_JSON if json.is_none() && bin.is_none() => json = Some(body),
            CHUNK_BIN if json.is_some() && bin.is_none() => bin = Some(body),
            CHUNK_JSON | CHUNK_BIN => return Err("its GLB chunks are out of order or repeated".to_owned()),
            _ => {}
        }
        rest = &rest[CHUNK_HEADER_BYTES + chunk_length..];
    }
    let json = json.ok_or("the GLB file has no JSON chunk")?;
    Ok((json, bin))
}

/// A GLB file of `json` and `bin`, each padded to 4 bytes (the JSON with
/// spaces, the binary with zeros).
pub(crate) fn assemble(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let json_padded = json.len().next_multiple_of(4);
    let bin_padded = bin.len().next_multiple_of(4);
    let mut length = HEADER_BYTES + CHUNK_HEADER_BYTES + json_padded;
    if !bin.is_empty() {
        length += CHUNK_HEADER_BYTES + bin_padded;
    }
    let mut out = Vec::with_capacity(length);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(length as u32).to_le_bytes());
    out.extend_from_slice(&(json_padded as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(out.len() + json_padded - json.len(), b' ');
    if !bin.is_empty() {
        out.extend_from_slice(&(bin_padded as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(bin);
        out.resize(out.len() + bin_padded - bin.len(), 0);
    }
    out
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assembled_files_are_aligned_and_split_back() {
        let glb = assemble(b"{\"a\":1}", &[1, 2, 3, 4, 5]);
        assert_eq!(glb.len() % 4, 0);
        assert_eq!(u32_at(&glb, 8) as usize, glb.len());
        let (json, bin) = split(&glb).unwrap();
        assert_eq!(json, b"{\"a\":1} ");
        assert_eq!(bin.unwrap(), [1, 2, 3, 4, 5, 0, 0, 0]);
        let no_bin = assemble(b"{}", &[]);
        assert!(split(&no_bin).unwrap().1.is_none());
    }

    #[test]
    fn broken_containers_are_reported() {
        let glb = assemble(b"{}", &[1, 2, 3, 4]);
        assert!(split(&glb[..8]).unwrap_err().contains("cut short"));
        assert!(split(&glb[..glb.len() - 4]).unwrap_err().contains("cut short"));
        let mut v1 = glb.clone();
        v1[4] = 1;
        assert!(split(&v1).unwrap_err().contains("version 1"));
        let mut tiny = glb.clone();
        tiny[8..12].copy_from_slice(&4u32.to_le_bytes());
        assert!(split(&tiny).is_err());
        let mut huge_chunk = glb;
        huge_chunk[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(split(&huge_chunk).unwrap_err().contains("past the end"));
    }
}
