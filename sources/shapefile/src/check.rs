//! Consistency checks across a shapefile's files, from their headers and
//! sizes alone.

use std::path::{Path, PathBuf};

use relief_source::SourceError;

fn bytes(path: &Path, what: &'static str) -> Result<Vec<u8>, SourceError> {
    std::fs::read(path).map_err(|source| SourceError::Io { what, path: path.to_path_buf(), source })
}

fn be_i32(b: &[u8], at: usize) -> i64 {
    i64::from(i32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]))
}

/// The sibling file with `ext`, matching the case of the .shp's extension.
pub(crate) fn sibling(shp: &Path, ext: &str) -> PathBuf {
    let upper = shp.extension().and_then(|e| e.to_str()).is_some_and(|e| e.chars().all(|c| c.is_ascii_uppercase()));
    shp.with_extension(if upper { ext.to_ascii_uppercase() } else { ext.to_owned() })
}

/// The number of records, once .shp, .shx and .dbf agree on it.
pub(crate) fn check(shp: &Path) -> Result<usize, SourceError> {
    let (shx_path, dbf_path) = (sibling(shp, "shx"), sibling(shp, "dbf"));
    let shp_len = std::fs::metadata(shp)
        .map_err(|source| SourceError::Io { what: "shapefile", path: shp.to_path_buf(), source })?
        .len();
    if !shx_path.exists() {
        return Err(SourceError::format("missing .shx index: the shapefile cannot be read without it", &shx_path));
    }
    let shx = bytes(&shx_path, "shapefile index")?;
    let dbf = bytes(&dbf_path, "shapefile attributes")?;
    let shp_head = {
        let mut head = vec![0u8; 100];
        let mut f = std::fs::File::open(shp).map_err(|source| SourceError::Io {
            what: "shapefile",
            path: shp.to_path_buf(),
            source,
        })?;
        std::io::Read::read_exact(&mut f, &mut head)
            .map_err(|_| SourceError::format("truncated .shp: shorter than its 100-byte header", shp))?;
        head
    };
    if be_i32(&shp_head, 0) != 9994 {
        return Err(SourceError::format("not a shapefile: bad file code in the .shp header", shp));
    }
    let declared = be_i32(&shp_head, 24) * 2;
    if declared != shp_len as i64 {
        return Err(SourceError::format(
            format!("truncated or torn .shp: its header says {declared} bytes, the file has {shp_len}"),
            shp,
        ));
    }
    if shx.len() < 100 || be_i32(&shx, 24) * 2 != shx.len() as i64 || (shx.len() - 100) % 8 != 0 {
        return Err(SourceError::format(
            format!("torn .shx: its header length does not match its {} bytes", shx.len()),
            &shx_path,
        ));
    }
    let records = (shx.len() - 100) / 8;
    if records > 0 {
        let last = 100 + (records - 1) * 8;
        let end = be_i32(&shx, last) * 2 + 8 + be_i32(&shx, last + 4) * 2;
        if end > shp_len as i64 {
            return Err(SourceError::format(
                format!("the last .shx entry points past the end of the .shp ({end} > {shp_len})"),
                &shx_path,
            ));
        }
    }
    if dbf.len() < 32 {
        return Err(SourceError::format("truncated .dbf: shorter than its header", &dbf_path));
    }
    let dbf_records = u32::from_le_bytes([dbf[4], dbf[5], dbf[6], dbf[7]]) as usize;
    let (header_len, record_len) =
        (usize::from(u16::from_le_bytes([dbf[8], dbf[9]])), usize::from(u16::from_le_bytes([dbf[10], dbf[11]])));
    if dbf_records != records {
        return Err(SourceError::format(
            format!("invalid record count {dbf_records} in the .dbf (the .shx indexes {records})"),
            &dbf_path,
        ));
    }
    let expected = header_len + records * record_len;
    if dbf.len() != expected && dbf.len() != expected + 1 {
        return Err(SourceError::format(
            format!("torn .dbf: {} bytes where its header promises {expected}", dbf.len()),
            &dbf_path,
        ));
    }
    Ok(records)
}
