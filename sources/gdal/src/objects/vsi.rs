//! The few calls into GDAL's virtual file systems that the `gdal` crate
//! does not wrap: an object's headers, a range read, and forgetting what
//! GDAL holds of an object. The only unsafe code of relief's sources.
#![allow(unsafe_code, reason = "GDAL's VSI functions have no safe binding in the gdal crate")]

use std::ffi::{CStr, CString, c_char};
use std::path::Path;

use gdal_sys::{
    CPLErrorReset, CPLGetLastErrorMsg, CSLDestroy, VSICurlPartialClearCache, VSIFCloseL, VSIFOpenExL, VSIFReadL,
    VSIFSeekL, VSIGetFileMetadata, VSIStatBufL, VSIStatExL,
};

fn c_path(path: &Path) -> Result<CString, String> {
    CString::new(path.to_string_lossy().as_bytes()).map_err(|_| "a path with a NUL byte".to_owned())
}

/// GDAL's last error message on this thread (cleared), or `otherwise`.
fn last_error(otherwise: &str) -> String {
    // SAFETY: CPLGetLastErrorMsg returns a pointer to a thread-local,
    // NUL-terminated string that stays valid until the next CPL call on
    // this thread; it is copied before CPLErrorReset.
    let message = unsafe {
        let raw = CPLGetLastErrorMsg();
        let text = if raw.is_null() { String::new() } else { CStr::from_ptr(raw).to_string_lossy().into_owned() };
        CPLErrorReset();
        text
    };
    let message = message.trim();
    if message.is_empty() { otherwise.to_owned() } else { message.to_owned() }
}

/// The response headers of a request for the object, asked now (GDAL keeps
/// no copy of them): name and value, as the server sent them. The error is
/// GDAL's (the server's words where it gave some).
pub(super) fn headers(path: &Path) -> Result<Vec<(String, String)>, String> {
    let name = c_path(path)?;
    let domain = c"HEADERS";
    // SAFETY: both strings are NUL-terminated and outlive the call; the
    // returned list is a NULL-terminated array of NUL-terminated strings
    // owned by the caller, read here and freed with CSLDestroy.
    let list = unsafe {
        CPLErrorReset();
        VSIGetFileMetadata(name.as_ptr(), domain.as_ptr(), std::ptr::null_mut())
    };
    if list.is_null() {
        // GDAL's own words for the failed request (a 403, a refused
        // connection) come first; a stat tells a missing object otherwise.
        let said = last_error("");
        return Err(if said.is_empty() { why_missing(path) } else { said });
    }
    let mut out = Vec::new();
    // SAFETY: see above; the walk stops at the terminating NULL.
    unsafe {
        let mut at = list;
        while !(*at).is_null() {
            let entry = CStr::from_ptr(*at).to_string_lossy();
            if let Some((k, v)) = entry.split_once('=') {
                out.push((k.trim().to_owned(), v.trim().to_owned()));
            }
            at = at.add(1);
        }
        CSLDestroy(list);
    }
    if out.is_empty() {
        return Err(why_missing(path));
    }
    Ok(out)
}

/// Why GDAL cannot reach the object: a stat that sets GDAL's error (the
/// server's message: not found, access denied, connection refused).
fn why_missing(path: &Path) -> String {
    let Ok(name) = c_path(path) else { return "a path with a NUL byte".to_owned() };
    // The binding declares the stat buffer opaque (size 0): GDAL fills a
    // `struct stat64`, 144 bytes on Linux x86-64, so room for 256 is given.
    let mut buf = [0u64; 32];
    // SAFETY: `buf` is larger than a `struct stat64` and aligned for it;
    // the name is NUL-terminated and outlives the call.
    let found = unsafe {
        CPLErrorReset();
        VSIStatExL(name.as_ptr(), buf.as_mut_ptr().cast::<VSIStatBufL>(), STAT_EXISTS | STAT_SET_ERROR) == 0
    };
    if found { last_error("the server sent no headers") } else { last_error("not found") }
}

const STAT_EXISTS: i32 = 0x1;
const STAT_SET_ERROR: i32 = 0x8;

/// Makes GDAL forget what it holds of the objects under `prefix`: their
/// sizes, existence and cached ranges. The next read asks the server.
pub(super) fn forget(prefix: &Path) {
    if let Ok(name) = c_path(prefix) {
        // SAFETY: a NUL-terminated string that outlives the call.
        unsafe { VSICurlPartialClearCache(name.as_ptr()) };
    }
}

/// One open handle on a file of GDAL's virtual file systems.
pub(super) struct VsiFile(*mut gdal_sys::VSILFILE);

impl VsiFile {
    pub(super) fn open(path: &Path) -> Result<Self, String> {
        let name = c_path(path)?;
        let mode: &CStr = c"rb";
        // SAFETY: NUL-terminated strings that outlive the call; a NULL
        // result is handled.
        let handle = unsafe {
            CPLErrorReset();
            VSIFOpenExL(name.as_ptr(), mode.as_ptr().cast::<c_char>(), 1)
        };
        if handle.is_null() { Err(last_error("cannot open")) } else { Ok(Self(handle)) }
    }

    /// Fills `buf` from `offset`; an error when the object is shorter.
    pub(super) fn read_exact_at(&mut self, buf: &mut [u8], offset: u64) -> Result<(), String> {
        // SAFETY: the handle is open (closed only on drop); `buf` is a
        // valid writable region of `buf.len()` bytes.
        let read = unsafe {
            CPLErrorReset();
            if VSIFSeekL(self.0, offset, 0) != 0 {
                return Err(last_error("cannot seek"));
            }
            VSIFReadL(buf.as_mut_ptr().cast(), 1, buf.len(), self.0)
        };
        if read == buf.len() { Ok(()) } else { Err(last_error("the object is shorter than its tables say")) }
    }
}

impl Drop for VsiFile {
    fn drop(&mut self) {
        // SAFETY: the handle is open and closed exactly once, here.
        unsafe {
            VSIFCloseL(self.0);
        }
    }
}
