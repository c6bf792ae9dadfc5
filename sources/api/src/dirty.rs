//! Dirty regions: what changed in a source, in grid coordinates.

use crate::grid::{Extent, TileGrid, TileKey};

/// The areas of a source's output that changed. Either nothing, everything,
/// or a list of extents in the grid's CRS (an antimeridian-crossing change
/// is two extents). An op that reads its input's neighbouring samples adds a
/// margin counted in samples, since a sample's size depends on the level.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DirtySet {
    everything: bool,
    extents: Vec<Extent>,
    margin_samples: u32,
}

impl DirtySet {
    pub fn none() -> Self {
        Self::default()
    }

    pub fn everything() -> Self {
        Self { everything: true, extents: Vec::new(), margin_samples: 0 }
    }

    pub fn from_extents(extents: impl IntoIterator<Item = Extent>) -> Self {
        Self { everything: false, extents: extents.into_iter().filter(Extent::is_valid).collect(), margin_samples: 0 }
    }

    pub fn is_none(&self) -> bool {
        !self.everything && self.extents.is_empty()
    }

    pub fn is_everything(&self) -> bool {
        self.everything
    }

    /// The extents, or the whole grid when everything is dirty.
    pub fn extents(&self, grid: &TileGrid) -> Vec<Extent> {
        if self.everything { vec![grid.extent()] } else { self.extents.clone() }
    }

    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        if self.everything || other.everything {
            return Self::everything();
        }
        let mut extents = self.extents.clone();
        extents.extend(other.extents.iter().copied());
        Self { margin_samples: self.margin_samples.max(other.margin_samples), ..Self::from_extents(extents) }
    }

    /// Grows the dirt by `samples` samples of whatever level a tile is at.
    #[must_use]
    pub fn dilate_samples(&self, samples: u32) -> Self {
        Self { margin_samples: self.margin_samples + samples, ..self.clone() }
    }

    /// Grows each extent by (dx, dy): an op whose output sample reads its
    /// input's neighbours (a normal map, a hillshade) dilates the dirt.
    #[must_use]
    pub fn dilate(&self, dx: f64, dy: f64) -> Self {
        if self.everything {
            return self.clone();
        }
        Self::from_extents(self.extents.iter().map(|e| e.dilate(dx, dy)))
    }

    /// True when the tile's area (and its shared edges) may have changed.
    pub fn touches_tile(&self, grid: &TileGrid, key: TileKey) -> bool {
        if self.everything {
            return true;
        }
        let lattice = grid.lattice(key, crate::grid::SampleKind::Corner);
        let margin = f64::from(self.margin_samples);
        let t = grid.tile_extent(key).dilate(margin * lattice.step_x, margin * lattice.step_y);
        self.extents.iter().any(|e| e.touches(&t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_and_dilate() {
        let grid = TileGrid::geodetic(256).unwrap();
        let a = DirtySet::from_extents([Extent::new(1.0, 1.0, 2.0, 2.0)]);
        let b = DirtySet::from_extents([Extent::new(5.0, 5.0, 6.0, 6.0)]);
        let u = a.union(&b);
        assert_eq!(u.extents(&grid).len(), 2);
        assert!(DirtySet::none().union(&DirtySet::none()).is_none());
        assert!(a.union(&DirtySet::everything()).is_everything());
        let d = a.dilate(0.5, 0.5);
        assert_eq!(d.extents(&grid)[0], Extent::new(0.5, 0.5, 2.5, 2.5));
        // A margin in samples reaches one sample further at each level.
        let edge = grid.tile_extent(TileKey::new(8, 300, 40));
        let beside =
            DirtySet::from_extents([Extent::new(edge.max_x + 0.001, edge.min_y, edge.max_x + 0.002, edge.max_y)]);
        assert!(!beside.touches_tile(&grid, TileKey::new(8, 300, 40)));
        assert!(beside.dilate_samples(1).touches_tile(&grid, TileKey::new(8, 300, 40)));
        // Inverted or non-finite extents are dropped; a point's is kept.
        assert!(
            DirtySet::from_extents([Extent::new(2.0, 1.0, 1.0, 2.0), Extent::new(f64::NAN, 0.0, 1.0, 1.0)]).is_none()
        );
        assert!(!DirtySet::from_extents([Extent::new(1.0, 1.0, 1.0, 1.0)]).is_none());
    }
}
