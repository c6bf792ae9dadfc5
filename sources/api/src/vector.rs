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
use crate::patches::{self, PatchCounts, PatchStyle};
use crate::payload::{Feature, MeshTile, Payload, PayloadKind};
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
    /// The features are MultiPatch surfaces (3D buildings), each patch a
    /// polygon (`patches`): the source's output is their meshes.
    pub surfaces: bool,
}

/// A vector file format.
pub trait VectorFormat: Send + Sync + std::fmt::Debug + 'static {
    /// The manifest kind.
    const KIND: &'static str;

    /// Reads the dataset whose primary file is `path`; `stamped` is what
    /// `Self::stamped` named for this read. Options are checked here.
    fn read(spec: &SourceSpec, path: &Path, stamped: &[PathBuf]) -> Result<VectorRead, SourceError>;

    /// The files whose datasets (`files::dataset_files`) a read of `path`
    /// depends on: stamped before and after each read, and compared by a
    /// refresh. The path itself, unless the format keeps its data elsewhere
    /// (a file geodatabase: the layer's table files in the folder).
    fn stamped(_spec: &SourceSpec, path: &Path) -> Result<Vec<PathBuf>, SourceError> {
        Ok(vec![path.to_path_buf()])
    }
}

#[derive(Debug)]
pub struct VectorSource<F: VectorFormat> {
    spec: SourceSpec,
    path: PathBuf,
    crs: Arc<dyn CrsTransform>,
    /// What `F::stamped` named, and their fingerprint when read.
    stamped: Vec<PathBuf>,
    fingerprint: Fingerprint,
    index: FeatureIndex,
    /// For MultiPatch surfaces: how they are drawn, and each feature's
    /// anchor (the one tile a level that draws it).
    surfaces: Option<Surfaces>,
    info: SourceInfo,
    format: PhantomData<F>,
}

#[derive(Debug)]
struct Surfaces {
    style: PatchStyle,
    anchors: Vec<Option<(f64, f64)>>,
}

impl<F: VectorFormat> VectorSource<F> {
    pub fn open(spec: &SourceSpec, grid: &TileGrid, crs: Arc<dyn CrsTransform>) -> Result<Self, SourceError> {
        let [path] = spec.paths.as_slice() else {
            return Err(SourceError::option(
                "path",
                format!("a {} source reads one file (its sidecars come with it)", F::KIND),
            ));
        };
        let stamped = F::stamped(spec, path)?;
        let fingerprint = Fingerprint::of_each(&stamped, F::KIND)?;
        let mut read = F::read(spec, path, &stamped)?;
        if Fingerprint::of_each(&stamped, F::KIND)? != fingerprint {
            return Err(SourceError::Changing { path: path.clone() });
        }
        let crs_file = read.crs_file.clone();
        let index = FeatureIndex::new(read.features, &read.crs, grid, crs.as_ref()).map_err(|e| match e {
            SourceError::Crs { crs, message, path: None } => SourceError::Crs { crs, message, path: crs_file },
            other => other,
        })?;
        let surfaces = if read.surfaces {
            let style = PatchStyle::from_spec(spec)?;
            let geodetic = grid.is_geodetic();
            style.details(&mut read.details);
            PatchCounts::of(index.features().iter(), geodetic).report(&mut read.details, &mut read.warnings);
            let anchors = index.features().iter().map(|f| patches::anchor(f, geodetic)).collect();
            Some(Surfaces { style, anchors })
        } else {
            PatchStyle::refuse_on_features(spec, "points, lines or polygons")?;
            None
        };
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
        Ok(Self {
            spec: spec.clone(),
            path: path.clone(),
            crs,
            stamped,
            fingerprint,
            index,
            surfaces,
            info,
            format: PhantomData,
        })
    }

    /// The meshes of the surfaces whose anchor tile `key` is.
    fn meshes(&self, surfaces: &Surfaces, grid: &TileGrid, key: TileKey) -> MeshTile {
        if key.level < surfaces.style.min_level {
            return MeshTile::default();
        }
        let owned = self
            .index
            .features()
            .iter()
            .zip(&surfaces.anchors)
            .filter(|(_, a)| a.is_some_and(|(x, y)| grid.key_at(key.level, x, y) == Some(key)))
            .map(|(f, _)| f);
        patches::mesh(owned, grid.is_geodetic(), &surfaces.style)
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
        if self.surfaces.is_some() { PayloadKind::Mesh } else { PayloadKind::Features }
    }

    fn info(&self) -> SourceInfo {
        self.info.clone()
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        Ok(match &self.surfaces {
            Some(surfaces) => Payload::Mesh(self.meshes(surfaces, ctx.grid, key)),
            None => Payload::Features(self.index.tile(ctx.grid, key)),
        })
    }

    /// Reads the dataset again when any of its files changed; the dirt is
    /// the old and new parts of every feature that changed, came or went.
    fn refresh(&self, grid: &TileGrid) -> Result<Refresh, SourceError> {
        if F::stamped(&self.spec, &self.path)? == self.stamped
            && Fingerprint::of_each(&self.stamped, F::KIND)? == self.fingerprint
        {
            return Ok(Refresh::Unchanged);
        }
        let new = Self::open(&self.spec, grid, Arc::clone(&self.crs))?;
        if new.output() != self.output() {
            return Err(SourceError::format(
                format!(
                    "its layer now holds {} where it held {}: a source keeps its kind of output while the scene \
                     runs; restart reliefd (or point the manifest at a new source) to draw the new kind",
                    new.output(),
                    self.output()
                ),
                &self.path,
            ));
        }
        let dirty = new.index.dirt_since(&self.index);
        Ok(Refresh::Changed { source: Arc::new(new), dirty })
    }
}
