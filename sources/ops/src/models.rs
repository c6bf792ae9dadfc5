//! The models an op places (`scatter`, `instances`): relief's stock models,
//! and the users' glTF files from `paths`, each named by its file stem and
//! read through relief-models when the source opens and when it changes,
//! so a missing or corrupt model is the source's error, named with its file.

use std::path::{Path, PathBuf};

use relief_source::SourceError;
use relief_source::files::{Fingerprint, dataset_files};

/// Models relief draws without a file.
pub const STOCK_MODELS: &[&str] = relief_models::STOCK;

/// One user model: its name (the file stem), its file, and what the file
/// looked like when it was checked.
#[derive(Debug, Clone)]
pub struct ModelFile {
    pub name: String,
    pub path: PathBuf,
    pub fingerprint: Fingerprint,
}

/// Checks one model file: a glTF 2.0 model relief can draw (triangles,
/// within the size limits). The renderer reads it again to draw it.
fn check_model(path: &Path) -> Result<(), SourceError> {
    let meta =
        std::fs::metadata(path).map_err(|source| SourceError::Io { what: "model", path: path.into(), source })?;
    if !meta.is_file() {
        return Err(SourceError::format("not a file", path));
    }
    match relief_models::load(path) {
        Ok(_) => Ok(()),
        Err(relief_models::ModelError::Read { source, .. }) => {
            Err(SourceError::Io { what: "model", path: path.into(), source })
        }
        // The message names the file already; said once, at the end.
        Err(e) => {
            let text = e.to_string().replace(&path.display().to_string(), "the file");
            Err(SourceError::format(text, path))
        }
    }
}

/// An error about a model file, saying whose model it is; the path is
/// named once, at the end.
fn of_source(error: SourceError, id: &str, path: &Path) -> SourceError {
    match error {
        SourceError::Io { source, path, .. } => {
            SourceError::format(format!("cannot read model of source '{id}': {source}"), path)
        }
        SourceError::Format { message, path } => {
            SourceError::format(format!("model of source '{id}' is unusable: {message}"), path)
        }
        other => SourceError::format(format!("model of source '{id}' is unusable: {other}"), path),
    }
}

impl ModelFile {
    /// Checks `path` and takes its fingerprint (sidecars such as a glTF's
    /// `.bin` included).
    pub fn open(path: &Path, id: &str) -> Result<Self, SourceError> {
        let fingerprint = Fingerprint::of(path, "model").map_err(|e| of_source(e, id, path))?;
        check_model(path).map_err(|e| of_source(e, id, path))?;
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| !s.is_empty())
            .ok_or_else(|| SourceError::format(format!("model of source '{id}' has no file name"), path))?;
        Ok(Self { name: name.to_owned(), path: path.to_path_buf(), fingerprint })
    }

    /// Opens every model of a source; two files with one stem are refused
    /// (a model is named by its stem).
    pub fn open_all(paths: &[PathBuf], id: &str) -> Result<Vec<Self>, SourceError> {
        let mut models: Vec<Self> = Vec::with_capacity(paths.len());
        for path in paths {
            let model = Self::open(path, id)?;
            if let Some(other) = models.iter().find(|m| m.name == model.name) {
                return Err(SourceError::option(
                    "paths",
                    format!(
                        "'{}' and '{}' are both model '{}' (a model is named by its file stem)",
                        other.path.display(),
                        path.display(),
                        model.name
                    ),
                ));
            }
            models.push(model);
        }
        Ok(models)
    }

    /// The files to watch: the model and its sidecars.
    pub fn files(&self) -> Vec<PathBuf> {
        dataset_files(&self.path)
    }

    /// The model again when its files changed, None when they did not.
    pub fn reopen_if_changed(&self, id: &str) -> Result<Option<Self>, SourceError> {
        let now = Fingerprint::of(&self.path, "model").map_err(|e| of_source(e, id, &self.path))?;
        if now == self.fingerprint {
            return Ok(None);
        }
        Self::open(&self.path, id).map(Some)
    }
}

/// The models again when any of their files changed (each read and checked
/// again), None when none did; an error names a file gone or unusable.
pub fn reopen_changed(models: &[ModelFile], id: &str) -> Result<Option<Vec<ModelFile>>, SourceError> {
    let mut changed = false;
    let mut out = Vec::with_capacity(models.len());
    for model in models {
        match model.reopen_if_changed(id)? {
            Some(new) => {
                changed = true;
                out.push(new);
            }
            None => out.push(model.clone()),
        }
    }
    Ok(changed.then_some(out))
}

/// Every model name a rule may use: the stock ones and the files' stems
/// (a stem may shadow a stock name), sorted.
pub fn known_models(files: &[ModelFile]) -> Vec<String> {
    let mut names: Vec<String> = STOCK_MODELS.iter().map(|s| (*s).to_owned()).collect();
    names.extend(files.iter().map(|m| m.name.clone()));
    names.sort();
    names.dedup();
    names
}
