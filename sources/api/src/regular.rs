//! Scene files are read only when they are regular files. A named pipe,
//! a device or a socket put in a file's place would block a reader for
//! good (opening a pipe waits for its writer): files are opened without
//! waiting and refused unless regular, and a path handed to a library that
//! opens it itself (GDAL) is checked first, with the side files GDAL looks
//! for beside it.

use std::fs::{File, Metadata, OpenOptions};
use std::io::{self, Read};
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// What a file that is not regular is, in words; None for a regular one.
fn special(meta: &Metadata) -> Option<&'static str> {
    let kind = meta.file_type();
    if kind.is_file() {
        None
    } else if kind.is_fifo() {
        Some("a named pipe")
    } else if kind.is_char_device() || kind.is_block_device() {
        Some("a device")
    } else if kind.is_socket() {
        Some("a socket")
    } else if kind.is_dir() {
        Some("a folder")
    } else {
        Some("not a regular file")
    }
}

fn refused(path: &Path, what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, format!("{} is {what}, not a regular file", path.display()))
}

/// Opens `path` for reading if it is a regular file: opened without
/// waiting (a pipe's open would wait for a writer), then checked.
pub fn open_regular(path: &Path) -> io::Result<File> {
    let file = OpenOptions::new().read(true).custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32).open(path)?;
    match special(&file.metadata()?) {
        None => Ok(file),
        Some(what) => Err(refused(path, what)),
    }
}

/// The bytes of `path`, if it is a regular file.
pub fn read_regular(path: &Path) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    open_regular(path)?.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// The text of `path`, if it is a regular file of UTF-8.
pub fn read_regular_to_string(path: &Path) -> io::Result<String> {
    String::from_utf8(read_regular(path)?)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, format!("{} is not UTF-8 text", path.display())))
}

/// `Ok` when `path` is a regular file (following links) or, with
/// `folders`, a folder: what a library may open itself.
pub fn check_regular(path: &Path, folders: bool) -> io::Result<()> {
    let meta = std::fs::metadata(path)?;
    match special(&meta) {
        None => Ok(()),
        Some(_) if folders && meta.is_dir() => Ok(()),
        Some(what) => Err(refused(path, what)),
    }
}

/// The side files GDAL and OGR look for beside `path` by name (auxiliary
/// metadata, overviews, masks, world files, projections, shapefile parts):
/// each must be absent or a regular file before GDAL opens `path`.
pub fn side_files(path: &Path) -> Vec<PathBuf> {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name().and_then(|n| n.to_str())) else {
        return Vec::new();
    };
    let stem = name.rsplit_once('.').map_or(name, |(s, _)| s);
    let mut out: Vec<PathBuf> =
        ["aux.xml", "aux", "ovr", "msk", "wld"].iter().map(|e| dir.join(format!("{name}.{e}"))).collect();
    for ext in [
        "aux", "ovr", "rrd", "tfw", "tifw", "tiffw", "wld", "jgw", "pgw", "prj", "imd", "rpb", "xml", "shx", "dbf",
        "cpg", "qix", "sbn", "sbx",
    ] {
        for case in [ext.to_owned(), ext.to_uppercase()] {
            out.push(dir.join(format!("{stem}.{case}")));
        }
    }
    out.push(dir.join(format!("{stem}_rpc.txt")));
    out.push(dir.join(format!("{stem}_RPC.TXT")));
    out
}

/// `Ok` when `path` is a regular file (or, with `folders`, a folder) and
/// every side file GDAL may open beside it is absent or regular.
pub fn check_for_gdal(path: &Path, folders: bool) -> io::Result<()> {
    check_regular(path, folders)?;
    for side in side_files(path) {
        if let Ok(meta) = std::fs::metadata(&side)
            && let Some(what) = special(&meta)
            && !meta.is_dir()
        {
            return Err(refused(&side, what));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a test")]

    use super::*;

    fn fifo(path: &Path) {
        rustix::fs::mknodat(rustix::fs::CWD, path, rustix::fs::FileType::Fifo, rustix::fs::Mode::from(0o600), 0)
            .unwrap();
    }

    #[test]
    fn a_named_pipe_is_refused_at_once_and_a_file_read() {
        let dir = tempfile::tempdir().unwrap();
        let pipe = dir.path().join("dem.tif");
        fifo(&pipe);
        let started = std::time::Instant::now();
        let e = open_regular(&pipe).unwrap_err().to_string();
        assert!(e.contains("is a named pipe, not a regular file") && e.contains("dem.tif"), "{e}");
        assert!(check_regular(&pipe, false).is_err() && check_for_gdal(&pipe, true).is_err());
        assert!(started.elapsed() < std::time::Duration::from_secs(5), "a pipe's open waited");
        let file = dir.path().join("ok.tif");
        std::fs::write(&file, b"bytes").unwrap();
        assert_eq!(read_regular(&file).unwrap(), b"bytes");
        assert!(check_for_gdal(&file, false).is_ok());
        // A pipe in a side file's place is refused too.
        fifo(&dir.path().join("ok.tif.aux.xml"));
        let e = check_for_gdal(&file, false).unwrap_err().to_string();
        assert!(e.contains("ok.tif.aux.xml is a named pipe"), "{e}");
        assert!(check_regular(dir.path(), true).is_ok() && check_regular(dir.path(), false).is_err());
    }
}
