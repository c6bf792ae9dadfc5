use std::path::PathBuf;

/// What went wrong inside a source. Messages read "what, then why, then the
/// path"; the daemon adds the source id in front.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SourceError {
    #[error("cannot read {what}: {source}: {}", crate::objects::display(path))]
    Io {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{message}: {}", crate::objects::display(path))]
    Format { message: String, path: PathBuf },
    #[error("unknown or unusable CRS '{crs}': {message}{}", path_suffix(path.as_ref()))]
    Crs { crs: String, message: String, path: Option<PathBuf> },
    #[error("invalid option '{field}': {message}")]
    InvalidOption { field: String, message: String },
    #[error("input '{input}' failed: {message}")]
    Input { input: String, message: String },
    #[error("{0} is not supported by this source")]
    Unsupported(&'static str),
    /// The file changed while it was read: a writer is at work. Not an
    /// error of the data; read again once the writer is done.
    #[error("file changed while it was being read: {}", crate::objects::display(path))]
    Changing { path: PathBuf },
    /// Another program holds the file locked (a database in the middle of
    /// a write). Shown on the source, and read again later.
    #[error("{message}: {}", crate::objects::display(path))]
    Locked { message: String, path: PathBuf },
}

fn path_suffix(path: Option<&PathBuf>) -> String {
    path.map(|p| format!(": {}", crate::objects::display(p))).unwrap_or_default()
}

impl SourceError {
    /// True when the failure says nothing about the data (a writer was busy).
    pub fn is_transient(&self) -> bool {
        matches!(self, Self::Changing { .. })
    }

    /// True when the same read may succeed later without any change to the
    /// files (a writer busy, a lock held): worth trying again.
    pub fn retry_later(&self) -> bool {
        matches!(self, Self::Changing { .. } | Self::Locked { .. })
    }

    pub fn format(message: impl Into<String>, path: impl Into<PathBuf>) -> Self {
        Self::Format { message: message.into(), path: path.into() }
    }

    pub fn option(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self::InvalidOption { field: field.into(), message: message.into() }
    }
}
