//! The `shapefile` source kind.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use relief_source::files::Fingerprint;
use relief_source::{
    CrsTransform, DirtySet, Extent, Feature, FeatureTile, GenerateContext, Geometry, Payload, PayloadKind, Refresh,
    Source, SourceError, SourceInfo, SourceSpec, TileGrid, TileKey,
};

use crate::check::{check, sibling};
use crate::read::read;

pub const KIND: &str = "shapefile";

/// A shapefile's features, in the grid's CRS.
#[derive(Debug)]
pub struct ShapefileSource {
    spec: SourceSpec,
    path: PathBuf,
    crs: Arc<dyn CrsTransform>,
    grid_crs: String,
    /// The CRS as the .prj states it (or the manifest overrides it).
    file_crs: String,
    crs_note: String,
    fingerprint: Fingerprint,
    features: Arc<Vec<Feature>>,
    /// Per feature, the bounding box of each part.
    extents: Arc<Vec<Vec<Extent>>>,
    null_shapes: usize,
    shape_types: BTreeMap<String, usize>,
}

impl ShapefileSource {
    pub fn open(spec: &SourceSpec, grid: &TileGrid, crs: Arc<dyn CrsTransform>) -> Result<Self, SourceError> {
        spec.only_options(&["crs"])?;
        let [path] = spec.paths.as_slice() else {
            return Err(SourceError::option("path", "a shapefile source reads one .shp (its sidecars come with it)"));
        };
        if !path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("shp")) {
            return Err(SourceError::option("path", format!("'{}' is not a .shp file", path.display())));
        }
        let fingerprint = Fingerprint::of(path, "shapefile")?;
        let records = check(path)?;
        let mut read = read(path)?;
        if Fingerprint::of(path, "shapefile")? != fingerprint {
            return Err(SourceError::Changing { path: path.clone() });
        }
        debug_assert_eq!(records, read.features.len() + read.null_shapes);
        let (file_crs, crs_note) = match (spec.text("crs")?, std::fs::read_to_string(sibling(path, "prj"))) {
            (Some(c), _) => (c.to_owned(), "from the manifest".to_owned()),
            (None, Ok(wkt)) if !wkt.trim().is_empty() => (wkt.trim().to_owned(), "from the .prj".to_owned()),
            _ => ("EPSG:4326".to_owned(), "no .prj: WGS84 longitude/latitude assumed".to_owned()),
        };
        to_grid(&mut read.features, &file_crs, grid.crs(), crs.as_ref(), path)?;
        let extents = read.features.iter().map(|f| f.geometry.part_extents()).collect();
        Ok(Self {
            spec: spec.clone(),
            path: path.clone(),
            crs,
            grid_crs: grid.crs().to_owned(),
            file_crs,
            crs_note,
            fingerprint,
            features: Arc::new(read.features),
            extents: Arc::new(extents),
            null_shapes: read.null_shapes,
            shape_types: read.shape_types,
        })
    }

    pub fn feature_count(&self) -> usize {
        self.features.len()
    }
}

/// Every coordinate of `features` from `from` to `to`, in one PROJ call.
fn to_grid(
    features: &mut [Feature],
    from: &str,
    to: &str,
    crs: &dyn CrsTransform,
    path: &std::path::Path,
) -> Result<(), SourceError> {
    fn each(g: &mut Geometry, f: &mut impl FnMut(&mut [f64; 3])) {
        match g {
            Geometry::Points(ps) => ps.iter_mut().for_each(f),
            Geometry::Lines(ls) => ls.iter_mut().flatten().for_each(f),
            Geometry::Polygons(polys) => polys.iter_mut().flatten().flatten().for_each(f),
        }
    }
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for feature in features.iter_mut() {
        each(&mut feature.geometry, &mut |p| {
            xs.push(p[0]);
            ys.push(p[1]);
        });
    }
    crs.transform(from, to, &mut xs, &mut ys).map_err(|e| match e {
        SourceError::Crs { crs, message, .. } => SourceError::Crs { crs, message, path: Some(sibling(path, "prj")) },
        other => other,
    })?;
    let mut n = 0;
    for feature in features.iter_mut() {
        each(&mut feature.geometry, &mut |p| {
            (p[0], p[1]) = (xs[n], ys[n]);
            n += 1;
        });
    }
    Ok(())
}

impl Source for ShapefileSource {
    fn id(&self) -> &str {
        &self.spec.id
    }

    fn kind(&self) -> &'static str {
        KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Features
    }

    fn info(&self) -> SourceInfo {
        let mut details = BTreeMap::new();
        details.insert("features".into(), self.features.len().to_string());
        details.insert("null_shapes".into(), self.null_shapes.to_string());
        for (kind, count) in &self.shape_types {
            details.insert(format!("shapes.{kind}"), count.to_string());
        }
        details.insert("crs_source".into(), self.crs_note.clone());
        if let Ok(cpg) = std::fs::read_to_string(sibling(&self.path, "cpg")) {
            details.insert("encoding".into(), cpg.trim().to_owned());
        }
        let extent = self.extents.iter().flatten().copied().reduce(|a, b| a.union(&b));
        SourceInfo {
            files: relief_source::files::dataset_files(&self.path),
            extent,
            crs: self.file_crs.lines().next().unwrap_or_default().chars().take(80).collect(),
            details,
            ..SourceInfo::default()
        }
    }

    /// The features that reach into the tile: a part's box touching it,
    /// and a point only in the one tile that owns it.
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let tile = ctx.grid.tile_extent(key);
        let features = self
            .features
            .iter()
            .zip(self.extents.iter())
            .filter(|(f, parts)| match &f.geometry {
                Geometry::Points(ps) => ps.iter().any(|p| ctx.grid.key_at(key.level, p[0], p[1]) == Some(key)),
                _ => parts.iter().any(|e| e.touches(&tile)),
            })
            .map(|(f, _)| f.clone())
            .collect();
        Ok(Payload::Features(FeatureTile { features }))
    }

    /// Reads the dataset again when any of its files changed; the dirt is
    /// the old and new parts of every feature that changed, came or went.
    fn refresh(&self, grid: &TileGrid) -> Result<Refresh, SourceError> {
        if Fingerprint::of(&self.path, "shapefile")? == self.fingerprint {
            return Ok(Refresh::Unchanged);
        }
        let new = Self::open(&self.spec, grid, Arc::clone(&self.crs))?;
        let old_by_id: BTreeMap<u64, usize> = self.features.iter().enumerate().map(|(i, f)| (f.id, i)).collect();
        let new_by_id: BTreeMap<u64, usize> = new.features.iter().enumerate().map(|(i, f)| (f.id, i)).collect();
        let mut dirt = Vec::new();
        for id in old_by_id.keys().chain(new_by_id.keys()) {
            let (old, fresh) = (old_by_id.get(id), new_by_id.get(id));
            let same = match (old, fresh) {
                (Some(&o), Some(&n)) => self.features[o] == new.features[n],
                _ => false,
            };
            if !same {
                dirt.extend(old.map(|&o| self.extents[o].clone()).unwrap_or_default());
                dirt.extend(fresh.map(|&n| new.extents[n].clone()).unwrap_or_default());
            }
        }
        debug_assert_eq!(new.grid_crs, self.grid_crs);
        Ok(Refresh::Changed { source: Arc::new(new), dirty: DirtySet::from_extents(dirt) })
    }
}
