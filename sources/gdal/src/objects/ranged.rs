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
                    .map_err(|why| std::io::Error::other(super::describe(path, &why)))?;
                BYTES_READ.fetch_add(buf.len() as u64, Ordering::Relaxed);
                tracing::trace!(object = %path.display(), offset, len = buf.len(), "object range read");
                Ok(())
            }
        }
    }

    /// The length of the file, or of the object as last asked.
    pub fn size(&self) -> std::io::Result<u64> {
        match self {
            Self::Local(file) => file.metadata().map(|m| m.len()),
            Self::Object(path) => super::version(path, false).map(|v| v.len).map_err(std::io::Error::other),
        }
    }
}
