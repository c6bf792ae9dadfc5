//! A file-backed vector source, generic over its file format: one place
//! for opening (with the re-stat that discards a read a writer disturbed),
//! reprojection, feature tiles and feature-diff refreshes. A format crate
//! supplies only `VectorFormat::read`.

use std::collections::BTreeMap;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::crs::CrsTransform;
use crate::error::SourceError;
use crate::features::FeatureIndex;
use crate::files::Fingerprint;
use crate::grid::{TileGrid, TileKey};
use crate::payload::{Feature, Payload, PayloadKind};
use crate::source::{GenerateContext, Refresh, Source, SourceInfo, SourceSpec};

/// What a format read from its files, features still in their own CRS.
#[derive(Debug, Default)]
pub struct VectorRead {
    pub features: Vec<Feature>,
    /// The features' CRS, any definition PROJ accepts.
    pub crs: String,
    /// The file that states the CRS, named in CRS errors (a .prj).
    pub crs_file: Option<PathBuf>,
    /// Every file read, sidecars included.
    pub files: Vec<PathBuf>,
    /// The CRS as the state shows it.
    pub crs_name: String,
    pub vertical_datum: String,
    /// Counts and facts for the state: features, null shapes, links...
    pub details: BTreeMap<String, String>,
    /// What the reader did that the user should know about: a rebuilt
    /// index, a missing attribute table, a mode read as its nearest.
    pub warnings: Vec<String>,
}

/// A vector file format.
pub trait VectorFormat: Send + Sync + std::fmt::Debug + 'static {
    /// The manifest kind.
    const KIND: &'static str;

    /// Reads the dataset whose primary file is `path`. Options are checked here.
    fn read(spec: &SourceSpec, path: &Path) -> Result<VectorRead, SourceError>;
}

#[derive(Debug)]
pub struct VectorSource<F: VectorFormat> {
    spec: SourceSpec,
    path: PathBuf,
    crs: Arc<dyn CrsTransform>,
    fingerprint: Fingerprint,
    index: FeatureIndex,
    info: SourceInfo,
    format: PhantomData<F>,
}

impl<F: VectorFormat> VectorSource<F> {
    pub fn open(spec: &SourceSpec, grid: &TileGrid, crs: Arc<dyn CrsTransform>) -> Result<Self, SourceError> {
        let [path] = spec.paths.as_slice() else {
            return Err(SourceError::option(
                "path",
                format!("a {} source reads one file (its sidecars come with it)", F::KIND),
            ));
        };
        let fingerprint = Fingerprint::of(path, F::KIND)?;
        let read = F::read(spec, path)?;
        if Fingerprint::of(path, F::KIND)? != fingerprint {
            return Err(SourceError::Changing { path: path.clone() });
        }
        let crs_file = read.crs_file.clone();
        let index = FeatureIndex::new(read.features, &read.crs, grid, crs.as_ref()).map_err(|e| match e {
            SourceError::Crs { crs, message, path: None } => SourceError::Crs { crs, message, path: crs_file },
            other => other,
        })?;
        let info = SourceInfo {
            files: read.files,
            extent: index.extent(),
            crs: read.crs_name,
            vertical_datum: read.vertical_datum,
            vertical_units: String::new(),
            resolution: None,
            details: read.details,
            warnings: read.warnings,
            ..SourceInfo::default()
        };
        Ok(Self { spec: spec.clone(), path: path.clone(), crs, fingerprint, index, info, format: PhantomData })
    }
}

impl<F: VectorFormat> Source for VectorSource<F> {
    fn id(&self) -> &str {
        &self.spec.id
    }

    fn kind(&self) -> &'static str {
        F::KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Features
    }

    fn info(&self) -> SourceInfo {
        self.info.clone()
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        Ok(Payload::Features(self.index.tile(ctx.grid, key)))
    }

    /// Reads the dataset again when any of its files changed; the dirt is
    /// the old and new parts of every feature that changed, came or went.
    fn refresh(&self, grid: &TileGrid) -> Result<Refresh, SourceError> {
        if Fingerprint::of(&self.path, F::KIND)? == self.fingerprint {
            return Ok(Refresh::Unchanged);
        }
        let new = Self::open(&self.spec, grid, Arc::clone(&self.crs))?;
        let dirty = new.index.dirt_since(&self.index);
        Ok(Refresh::Changed { source: Arc::new(new), dirty })
    }
}
