//! Range reads of a file or an object, for relief's own TIFF reader: the
//! block tables, and the blocks a reload finds changed. An object's bytes
//! are read through GDAL (`/vsis3/`, `/vsicurl/`, with GDAL's range
//! cache), one handle per read so any thread may read; what is read is
//! counted for the scene state.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use relief_source::objects::is_object;

use super::vsi::VsiFile;

static BYTES_READ: AtomicU64 = AtomicU64::new(0);

/// Bytes relief has read from objects through range requests since it
/// started (block tables and blocks; GDAL's own reads of an object it
/// opens, its header and the blocks it decodes itself, are not counted).
pub fn bytes_read() -> u64 {
    BYTES_READ.load(Ordering::Relaxed)
}

/// A local file or an object, read by ranges.
#[derive(Debug)]
pub enum RangeFile {
    Local(File),
    Object(PathBuf),
}

impl RangeFile {
    /// Opens a local file (a regular one: see `relief_source::regular`), or
    /// names an object (opened at each read).
    pub fn open(path: &Path) -> std::io::Result<Self> {
        if is_object(path) {
            return Ok(Self::Object(path.to_path_buf()));
        }
        relief_source::regular::open_regular(path).map(Self::Local)
    }

    /// Fills `buf` with the bytes from `offset`.
    pub fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
        match self {
            Self::Local(file) => file.read_exact_at(buf, offset),
            Self::Object(path) => {
                VsiFile::open(path)
                    .and_then(|mut f| f.read_exact_at(buf, offset))
                    .map_err(|why| std::io::Error::other(super::describe(&why)))?;
                BYTES_READ.fetch_add(buf.len() as u64, Ordering::Relaxed);
                tracing::trace!(object = %path.display(), offset, len = buf.len(), "object range read");
                Ok(())
            }
        }
    }

    /// The first `n` bytes (fewer when the file is shorter).
    pub fn head(&self, n: u64) -> std::io::Result<Vec<u8>> {
        match self {
            Self::Local(file) => up_to(file, n),
            Self::Object(_) => {
                let mut bytes = vec![0u8; usize::try_from(n.min(self.size()?)).unwrap_or(0)];
                self.read_exact_at(&mut bytes, 0)?;
                Ok(bytes)
            }
        }
    }

    /// Every byte, when there are at most `most` (None when there are more).
    /// A local file is read to its end as it is now (a writer may have
    /// cut it since it was measured).
    pub fn whole(&self, most: u64) -> std::io::Result<Option<Vec<u8>>> {
        let bytes = match self {
            Self::Local(file) => up_to(file, most.saturating_add(1))?,
            Self::Object(_) if self.size()? > most => return Ok(None),
            Self::Object(_) => self.head(most)?,
        };
        Ok((bytes.len() as u64 <= most).then_some(bytes))
    }

    /// The length of the file, or of the object as last asked.
    pub fn size(&self) -> std::io::Result<u64> {
        match self {
            Self::Local(file) => file.metadata().map(|m| m.len()),
            Self::Object(path) => super::version(path, false).map(|v| v.len).map_err(std::io::Error::other),
        }
    }
}

/// At most `n` bytes of `file` from its start, to its end as it is now
/// (positioned reads: the handle's cursor is not moved).
fn up_to(file: &File, n: u64) -> std::io::Result<Vec<u8>> {
    let mut bytes = vec![0u8; usize::try_from(n.min(1 << 20)).unwrap_or(1 << 20)];
    let mut filled = 0;
    loop {
        if filled == bytes.len() {
            if filled as u64 >= n {
                break;
            }
            let grown = (bytes.len() * 2).min(usize::try_from(n).unwrap_or(usize::MAX));
            bytes.resize(grown, 0);
        }
        match file.read_at(&mut bytes[filled..], filled as u64) {
            Ok(0) => break,
            Ok(read) => filled += read,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    bytes.truncate(filled);
    Ok(bytes)
}
