//! Background threads yield to serving: on a 2-core machine a first frame
//! or a reload must not wait behind hashing files or writing tiles to disk.

/// Puts the calling thread at the lowest priority (nice 19); `what` names
/// the thread's work in the log when that cannot be done.
pub(crate) fn lowest(what: &str) {
    if let Err(e) = rustix::process::setpriority_process(Some(rustix::thread::gettid()), 19) {
        tracing::debug!("the {what} thread keeps its priority: {e}");
    }
}
