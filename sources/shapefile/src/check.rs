//! Consistency checks across a shapefile's files, from their headers and
//! sizes alone: the torn states EDITORS.md records (an index that does not
//! match its shapes, a table whose record count disagrees, a record
//! appended before the header that counts it). What no writer leaves in
//! the middle of a save but users' files have, and GDAL reads (a stray
//! byte after the last record, a .shx header length off by less than an
//! entry), is read, with a warning.

use relief_source::SourceError;

use crate::dataset::Part;

/// The size of the .shp header, and of the .shx header (the same header).
pub(crate) const HEADER_BYTES: usize = 100;

/// The size of one .shx entry: a record's offset and content length.
pub(crate) const ENTRY_BYTES: usize = 8;

/// The file code every .shp and .shx header starts with.
const FILE_CODE: i64 = 9994;

/// The shape types of the specification: null, point, polyline, polygon,
/// multipoint; each with z and with m; multipatch.
const SHAPE_TYPES: [i32; 14] = [0, 1, 3, 5, 8, 11, 13, 15, 18, 21, 23, 25, 28, 31];

/// The big-endian i32 at `at`, widened; None past the end.
pub(crate) fn be_i32(bytes: &[u8], at: usize) -> Option<i64> {
    let word: [u8; 4] = bytes.get(at..at.checked_add(4)?)?.try_into().ok()?;
    Some(i64::from(i32::from_be_bytes(word)))
}

/// The header's file code is a shapefile's and its shape type is one of
/// the specification's; `ext` names the file in the message.
fn header_codes(part: &Part, ext: &str) -> Result<(), SourceError> {
    if be_i32(&part.bytes, 0) != Some(FILE_CODE) {
        return Err(SourceError::format(format!("not a shapefile: bad file code in the {ext} header"), &part.path));
    }
    let shape_type = part.bytes.get(32..36).and_then(|b| b.try_into().ok()).map(i32::from_le_bytes);
    match shape_type {
        Some(t) if SHAPE_TYPES.contains(&t) => Ok(()),
        Some(t) => Err(SourceError::format(format!("unknown shape type {t} in the {ext} header"), &part.path)),
        None => Err(SourceError::format(format!("truncated {ext}: shorter than its 100-byte header"), &part.path)),
    }
}

fn le_u32(bytes: &[u8], at: usize) -> Option<usize> {
    let word: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
    Some(u32::from_le_bytes(word) as usize)
}

fn le_u16(bytes: &[u8], at: usize) -> Option<usize> {
    let word: [u8; 2] = bytes.get(at..at + 2)?.try_into().ok()?;
    Some(usize::from(u16::from_le_bytes(word)))
}

/// The .shp is a shapefile whose header gives its length: the file as
/// long as that, or longer by bytes that are not whole records.
///
/// Bytes past the header's length that walk as one or more whole records
/// are a record being appended (QGIS writes each added record, then the
/// header): torn, read again later. Any other tail (a stray byte a writer
/// left, as users' files have) is ignored, as GDAL ignores it, with a
/// warning; the records are those within the header's length.
pub(crate) fn shp(shp: &Part) -> Result<Shp, SourceError> {
    let len = shp.bytes.len();
    let header = (len >= HEADER_BYTES).then(|| be_i32(&shp.bytes, 24));
    let Some(Some(words)) = header else {
        return Err(SourceError::format("truncated .shp: shorter than its 100-byte header", &shp.path));
    };
    header_codes(shp, ".shp")?;
    let declared = words * 2;
    if declared == len as i64 {
        return Ok(Shp { len, warning: None });
    }
    let torn = || {
        SourceError::format(
            format!("truncated or torn .shp: its header says {declared} bytes, the file has {len}"),
            &shp.path,
        )
    };
    let Ok(declared) = usize::try_from(declared) else { return Err(torn()) };
    if declared < HEADER_BYTES || declared > len {
        return Err(torn());
    }
    if whole_records(&shp.bytes, declared) {
        return Err(SourceError::format(
            format!(
                "torn .shp: whole records lie past the {declared} bytes its header says (the file has {len}): \
                 a writer appending them"
            ),
            &shp.path,
        ));
    }
    let extra = len - declared;
    let warning = format!(
        "the .shp has {extra} byte{} past the {declared} its header says, not a record: ignored, as GDAL does \
         ({})",
        if extra == 1 { "" } else { "s" },
        shp.path.display()
    );
    Ok(Shp { len: declared, warning: Some(warning) })
}

/// What the .shp check found: the length its records span, and a warning
/// when the file is longer.
pub(crate) struct Shp {
    /// The bytes to read: the header's length.
    pub len: usize,
    pub warning: Option<String>,
}

/// True when the bytes of `bytes` from `from` on are one or more whole
/// records (each an 8-byte record header whose content length takes the
/// walk exactly to the end).
fn whole_records(bytes: &[u8], from: usize) -> bool {
    let mut at = from;
    while at + 8 <= bytes.len() {
        let Some(content) = be_i32(bytes, at + 4).filter(|c| *c >= 2) else { return false };
        let Ok(content) = usize::try_from(content) else { return false };
        at += 8 + 2 * content;
        if at == bytes.len() {
            return true;
        }
    }
    false
}

/// Records are counted from 0 in messages, as their features' ids are.
///
/// The number of records the .shx indexes, once its header agrees with
/// its size, every entry lies inside the .shp, and the record header
/// there gives the same content length (as GDAL checks: "sizes do not match
/// in .shx and .shp").
///
/// A header length over the file's by less than one entry (no entry can
/// be missing: GDAL reads all the entries of such a file) is read, with a
/// warning; a header that promises a whole entry more, or fewer entries
/// than the file holds, is a .shx being rewritten: torn.
pub(crate) fn shx(shx: &Part, shp: &Part) -> Result<Shx, SourceError> {
    let shp_len = shp.bytes.len();
    let bytes = &shx.bytes;
    let len = bytes.len();
    let torn =
        || SourceError::format(format!("torn .shx: its header length does not match its {len} bytes"), &shx.path);
    let Some(words) = be_i32(bytes, 24) else { return Err(torn()) };
    if len < HEADER_BYTES || !(len - HEADER_BYTES).is_multiple_of(ENTRY_BYTES) {
        return Err(torn());
    }
    let declared = words * 2;
    let over = declared - len as i64;
    if !(0..ENTRY_BYTES as i64).contains(&over) {
        return Err(SourceError::format(
            format!("torn .shx: its header says {declared} bytes, the file has {len}"),
            &shx.path,
        ));
    }
    header_codes(shx, ".shx")?;
    let records = (len - HEADER_BYTES) / ENTRY_BYTES;
    for record in 0..records {
        let at = HEADER_BYTES + record * ENTRY_BYTES;
        let (Some(offset_words), Some(content_words)) = (be_i32(bytes, at), be_i32(bytes, at + 4)) else {
            return Err(torn());
        };
        let entry = if record + 1 == records {
            "the last .shx entry".to_owned()
        } else {
            format!("the .shx entry for record {record}")
        };
        let (start, end) = (offset_words * 2, offset_words * 2 + 8 + content_words * 2);
        if start < HEADER_BYTES as i64 {
            return Err(SourceError::format(format!("{entry} points into the .shp header (byte {start})"), &shx.path));
        }
        // The content starts with the shape type: two 16-bit words at least.
        if content_words < 2 {
            return Err(SourceError::format(
                format!("{entry} gives its record {content_words} words of content, too few for a shape"),
                &shx.path,
            ));
        }
        if end > shp_len as i64 {
            return Err(SourceError::format(
                format!("{entry} points past the end of the .shp ({end} > {shp_len})"),
                &shx.path,
            ));
        }
        let in_shp = be_i32(&shp.bytes, start as usize + 4);
        if in_shp != Some(content_words) {
            return Err(SourceError::format(
                format!(
                    "the .shp and its .shx disagree on the size of record {record}: {} words at byte {start} of the .shp, {content_words} in the .shx",
                    in_shp.unwrap_or_default()
                ),
                &shp.path,
            ));
        }
    }
    let warning = (over > 0).then(|| {
        format!(
            "the .shx header says {declared} bytes, the file has {len}: its {records} entries read, as GDAL does ({})",
            shx.path.display()
        )
    });
    Ok(Shx { records, warning })
}

/// What the .shx check found: the records it indexes, and a warning when
/// its header's length is off.
pub(crate) struct Shx {
    pub records: usize,
    pub warning: Option<String>,
}

/// The .dbf holds `records` records, as `counted_by` ("the .shx indexes")
/// says, and is as long as its header promises.
pub(crate) fn dbf(dbf: &Part, records: usize, counted_by: &str) -> Result<(), SourceError> {
    let bytes = &dbf.bytes;
    // The fixed part of a dBase header is 32 bytes; the counts are in it.
    let header = (bytes.len() >= 32).then(|| (le_u32(bytes, 4), le_u16(bytes, 8), le_u16(bytes, 10)));
    let Some((Some(dbf_records), Some(header_len), Some(record_len))) = header else {
        return Err(SourceError::format("truncated .dbf: shorter than its header", &dbf.path));
    };
    if dbf_records != records {
        return Err(SourceError::format(
            format!("invalid record count {dbf_records} in the .dbf ({counted_by} {records})"),
            &dbf.path,
        ));
    }
    let expected = header_len + records * record_len;
    if bytes.len() != expected && bytes.len() != expected + 1 {
        return Err(SourceError::format(
            format!("torn .dbf: {} bytes where its header promises {expected}", bytes.len()),
            &dbf.path,
        ));
    }
    Ok(())
}
