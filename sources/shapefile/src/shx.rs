//! A missing .shx rebuilt from the .shp, as GDAL does with
//! SHAPE_RESTORE_SHX: the records are walked from the first, each record
//! header giving its number and content length, to the end of the file.

use relief_source::SourceError;

use crate::check::{ENTRY_BYTES, HEADER_BYTES, be_i32};
use crate::dataset::Part;

/// A record's header in the .shp: its number and its content length.
const RECORD_HEADER_BYTES: usize = 8;

/// The .shx bytes for `shp` (its header already checked) and the number of
/// records it indexes. A record numbered out of turn, too short for a shape
/// type or running past the end means the walk has lost its way: with no
/// index to say where records start, that is an error, never a guess.
///
/// Messages count records from 0, as their features' ids do; the numbers
/// the .shp writes in the record headers start at 1.
pub(crate) fn rebuild(shp: &Part) -> Result<(Vec<u8>, usize), SourceError> {
    let bytes = &shp.bytes;
    let fail = |message: String| {
        SourceError::format(
            format!("no .shx beside the .shp, and its records do not walk cleanly: {message}"),
            &shp.path,
        )
    };
    let header = bytes.get(..HEADER_BYTES).ok_or_else(|| fail("the .shp is shorter than its header".into()))?;
    let mut shx = header.to_vec();
    let mut at = HEADER_BYTES;
    let mut records: usize = 0;
    while at < bytes.len() {
        let (record, number) = (records, records + 1);
        let (Some(found), Some(content_words)) = (be_i32(bytes, at), be_i32(bytes, at + 4)) else {
            return Err(fail(format!(
                "the file ends inside the header of record {record}, at byte {at} of {}",
                bytes.len()
            )));
        };
        if found != number as i64 {
            return Err(fail(format!("the record at byte {at} is numbered {found} where {number} was expected")));
        }
        // The content starts with the shape type: two 16-bit words at least.
        if content_words < 2 {
            return Err(fail(format!("record {record} at byte {at} declares {content_words} words of content")));
        }
        let end = at + RECORD_HEADER_BYTES + content_words as usize * 2;
        if end > bytes.len() {
            return Err(fail(format!(
                "record {record} at byte {at} runs to byte {end}, past the end of the file ({} bytes)",
                bytes.len()
            )));
        }
        let offset_words = i32::try_from(at / 2).map_err(|_| fail(format!("record {record} lies past 4 GiB")))?;
        shx.extend_from_slice(&offset_words.to_be_bytes());
        shx.extend_from_slice(&(content_words as i32).to_be_bytes());
        at = end;
        records += 1;
    }
    let shx_words =
        i32::try_from(shx.len() / 2).map_err(|_| fail(format!("{records} records are too many to index")))?;
    shx[24..28].copy_from_slice(&shx_words.to_be_bytes());
    debug_assert_eq!(shx.len(), HEADER_BYTES + records * ENTRY_BYTES);
    Ok((shx, records))
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    /// A .shp of null shapes, one record per entry of `numbers`.
    fn nulls(numbers: &[i32]) -> Part {
        let mut bytes = vec![0u8; HEADER_BYTES];
        bytes[..4].copy_from_slice(&9994i32.to_be_bytes());
        for n in numbers {
            bytes.extend_from_slice(&n.to_be_bytes());
            bytes.extend_from_slice(&2i32.to_be_bytes());
            bytes.extend_from_slice(&0i32.to_le_bytes());
        }
        let words = (bytes.len() / 2) as i32;
        bytes[24..28].copy_from_slice(&words.to_be_bytes());
        Part { path: PathBuf::from("/d/nulls.shp"), bytes }
    }

    #[test]
    fn the_rebuilt_index_points_at_each_record() -> Result<(), SourceError> {
        let (shx, records) = rebuild(&nulls(&[1, 2, 3]))?;
        assert_eq!(records, 3);
        assert_eq!(shx.len(), 100 + 3 * 8);
        assert_eq!(be_i32(&shx, 24), Some((shx.len() / 2) as i64));
        let entries: Vec<(Option<i64>, Option<i64>)> =
            (0..3).map(|k| (be_i32(&shx, 100 + k * 8), be_i32(&shx, 104 + k * 8))).collect();
        // Each null record is 12 bytes: offsets 100, 112, 124 in words.
        assert_eq!(entries, [(Some(50), Some(2)), (Some(56), Some(2)), (Some(62), Some(2))]);
        Ok(())
    }

    #[test]
    fn records_out_of_turn_or_cut_short_are_errors_naming_the_shp() {
        let message = rebuild(&nulls(&[1, 3])).unwrap_err().to_string();
        assert!(message.contains("numbered 3 where 2 was expected"), "{message}");
        assert!(message.ends_with(": /d/nulls.shp"), "{message}");

        let mut cut = nulls(&[1, 2]);
        cut.bytes.truncate(cut.bytes.len() - 2);
        let message = rebuild(&cut).unwrap_err().to_string();
        assert!(message.contains("record 1 at byte 112 runs to byte 124, past the end"), "{message}");

        let mut inside_header = nulls(&[1]);
        inside_header.bytes.extend_from_slice(&[0, 0, 0]);
        let message = rebuild(&inside_header).unwrap_err().to_string();
        assert!(message.contains("ends inside the header of record 1"), "{message}");
    }
}
