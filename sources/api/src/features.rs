//! Features held by a vector source: reprojected once, indexed by the
//! boxes of their parts, cut into feature tiles, and compared between
//! versions for dirt. One implementation for every vector source kind.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::crs::CrsTransform;
use crate::dirty::DirtySet;
use crate::error::SourceError;
use crate::grid::{Extent, TileGrid, TileKey};
use crate::payload::{Feature, FeatureTile, Geometry};

#[derive(Debug, Clone, Default)]
pub struct FeatureIndex {
    features: Arc<Vec<Feature>>,
    /// Per feature, the bounding box of each part.
    extents: Arc<Vec<Vec<Extent>>>,
}

fn each_position(g: &mut Geometry, f: &mut impl FnMut(&mut [f64; 3])) {
    match g {
        Geometry::Points(ps) => ps.iter_mut().for_each(f),
        Geometry::Lines(ls) => ls.iter_mut().flatten().for_each(f),
        Geometry::Polygons(polys) => polys.iter_mut().flatten().flatten().for_each(f),
    }
}

/// Equal features, where a missing z (NaN) equals a missing z.
fn same(a: &Feature, b: &Feature) -> bool {
    let positions = |g: &Geometry| -> Vec<u64> {
        let mut out = Vec::new();
        let mut g = g.clone();
        each_position(&mut g, &mut |p| out.extend(p.map(|v| if v.is_nan() { u64::MAX } else { v.to_bits() })));
        out
    };
    let shape = |g: &Geometry| match g {
        Geometry::Points(ps) => (0, ps.len(), 0),
        Geometry::Lines(ls) => (1, ls.len(), ls.iter().map(Vec::len).sum()),
        Geometry::Polygons(ps) => (2, ps.len(), ps.iter().map(Vec::len).sum()),
    };
    a.id == b.id
        && a.properties == b.properties
        && shape(&a.geometry) == shape(&b.geometry)
        && positions(&a.geometry) == positions(&b.geometry)
}

impl FeatureIndex {
    /// Takes `features` from `from` to the grid's CRS (one transform call
    /// for all their positions) and indexes them.
    pub fn new(
        mut features: Vec<Feature>,
        from: &str,
        grid: &TileGrid,
        crs: &dyn CrsTransform,
    ) -> Result<Self, SourceError> {
        let (mut xs, mut ys) = (Vec::new(), Vec::new());
        for feature in &mut features {
            each_position(&mut feature.geometry, &mut |p| {
                xs.push(p[0]);
                ys.push(p[1]);
            });
        }
        crs.transform(from, grid.crs(), &mut xs, &mut ys)?;
        let mut n = 0;
        for feature in &mut features {
            each_position(&mut feature.geometry, &mut |p| {
                (p[0], p[1]) = (xs[n], ys[n]);
                n += 1;
            });
        }
        let extents = features.iter().map(|f| f.geometry.part_extents()).collect();
        Ok(Self { features: Arc::new(features), extents: Arc::new(extents) })
    }

    /// The features, in the grid's CRS.
    pub fn features(&self) -> &[Feature] {
        &self.features
    }

    pub fn len(&self) -> usize {
        self.features.len()
    }

    pub fn is_empty(&self) -> bool {
        self.features.is_empty()
    }

    /// The box round every part of every feature.
    pub fn extent(&self) -> Option<Extent> {
        self.extents.iter().flatten().copied().reduce(|a, b| a.union(&b))
    }

    /// The features that reach into tile `key`: a line or polygon when a
    /// part's box touches the tile, a point only in the one tile that owns
    /// it (the grid's half-open rule).
    pub fn tile(&self, grid: &TileGrid, key: TileKey) -> FeatureTile {
        let tile = grid.tile_extent(key);
        let features = self
            .features
            .iter()
            .zip(self.extents.iter())
            .filter(|(f, parts)| match &f.geometry {
                Geometry::Points(ps) => ps.iter().any(|p| grid.key_at(key.level, p[0], p[1]) == Some(key)),
                _ => parts.iter().any(|e| e.touches(&tile)),
            })
            .map(|(f, _)| f.clone())
            .collect();
        FeatureTile { features }
    }

    /// Where `self` differs from `old`: the old and new parts of every
    /// feature (by id) that changed, came or went.
    pub fn dirt_since(&self, old: &Self) -> DirtySet {
        let by_id = |index: &Self| {
            let mut map: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
            for (i, f) in index.features.iter().enumerate() {
                map.entry(f.id).or_default().push(i);
            }
            map
        };
        let (before, after) = (by_id(old), by_id(self));
        let ids: std::collections::BTreeSet<u64> = before.keys().chain(after.keys()).copied().collect();
        let mut dirt = Vec::new();
        for id in &ids {
            let (b, a) = (before.get(id), after.get(id));
            let same = match (b, a) {
                (Some(b), Some(a)) => {
                    b.len() == a.len() && b.iter().zip(a).all(|(&i, &j)| same(&old.features[i], &self.features[j]))
                }
                _ => false,
            };
            if !same {
                dirt.extend(b.into_iter().flatten().flat_map(|&i| old.extents[i].iter().copied()));
                dirt.extend(a.into_iter().flatten().flat_map(|&j| self.extents[j].iter().copied()));
            }
        }
        DirtySet::from_extents(dirt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    struct Identity;

    impl CrsTransform for Identity {
        fn transform(&self, _: &str, _: &str, _: &mut [f64], _: &mut [f64]) -> Result<(), SourceError> {
            Ok(())
        }
    }

    fn point(id: u64, x: f64, y: f64) -> Feature {
        Feature { id, geometry: Geometry::Points(vec![[x, y, f64::NAN]]), properties: BTreeMap::new() }
    }

    #[test]
    fn moved_features_dirty_where_they_were_and_are() {
        let grid = TileGrid::geodetic(256).unwrap();
        let old =
            FeatureIndex::new(vec![point(0, 1.0, 1.0), point(1, 5.0, 5.0)], "EPSG:4326", &grid, &Identity).unwrap();
        let new =
            FeatureIndex::new(vec![point(0, 1.0, 1.0), point(1, 7.0, 7.0)], "EPSG:4326", &grid, &Identity).unwrap();
        let dirt = new.dirt_since(&old).extents(&grid);
        assert_eq!(dirt, vec![Extent::new(5.0, 5.0, 5.0, 5.0), Extent::new(7.0, 7.0, 7.0, 7.0)]);
        assert!(new.dirt_since(&new).is_none());
    }
}
