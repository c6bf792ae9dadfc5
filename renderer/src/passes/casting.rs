//! What the shadow maps are drawn from, as the shadows pass sees it. Each
//! pass that casts (the terrain, the buildings, the instances' models)
//! implements [`ShadowCaster`]: it says where what it casts changed since
//! the maps last took it in, chooses what falls inside a region of a
//! cascade, and records that into the region's pass. The shadows pass
//! knows only this trait, never the passes behind it.

use std::collections::HashMap;

use glam::DVec3;
use relief_source::TileKey;

use crate::camera::Sees;
use crate::gpu::Gpu;
use crate::surface::Surface;
use crate::uniforms::FrameUniform;
use relief_source::Extent;

/// A part of the world that changed: points (world axes) whose hull holds
/// it, so a cascade can find the texels it covers.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    pub points: Vec<DVec3>,
}

impl Area {
    /// The box round a sphere (world axes).
    pub fn sphere(centre: DVec3, radius: f64) -> Self {
        let r = radius.max(0.0);
        let points = [-1.0, 1.0]
            .into_iter()
            .flat_map(|x| [-1.0, 1.0].into_iter().flat_map(move |y| [-1.0, 1.0].map(|z| DVec3::new(x, y, z) * r)))
            .map(|d| centre + d)
            .collect();
        Self { points }
    }

    /// The ground over grid `extent` between heights `low_m` and `high_m`:
    /// a lattice of its points at both heights, fine enough that the
    /// planet's curve between them stays under a thousandth of the side.
    pub fn ground(surface: &Surface, extent: &Extent, (low_m, high_m): (f64, f64)) -> Self {
        // Sides of up to ~1/30 of a radian between lattice points (a sag
        // under a thousandth of the chord) on the planet; a flat grid
        // needs its corners only.
        let steps = if surface.is_planet() {
            let degrees = (extent.max_x - extent.min_x).abs().max((extent.max_y - extent.min_y).abs());
            ((degrees / 2.0).ceil() as usize).clamp(1, 64)
        } else {
            1
        };
        let mut points = Vec::with_capacity((steps + 1) * (steps + 1) * 2);
        for i in 0..=steps {
            for j in 0..=steps {
                let t = |k: usize| k as f64 / steps as f64;
                let x = extent.min_x + (extent.max_x - extent.min_x) * t(i);
                let y = extent.min_y + (extent.max_y - extent.min_y) * t(j);
                points.push(surface.world(x, y, low_m));
                points.push(surface.world(x, y, high_m));
            }
        }
        Self { points }
    }
}

/// Areas past this many, or points past `MOST_POINTS` in all, are taken
/// as a change of everything: the maps are drawn whole (and what a caster
/// keeps between shadow draws stays small however many edits come).
const MOST_AREAS: usize = 256;
const MOST_POINTS: usize = 16_384;

/// Where what a caster casts changed since the maps last took it in.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Changes {
    #[default]
    Nothing,
    Areas(Vec<Area>),
    /// Everything (nothing cast yet, or too many areas to keep apart).
    Everything,
}

impl Changes {
    /// Adds a changed area.
    pub fn add(&mut self, area: Area) {
        match self {
            Self::Everything => {}
            Self::Nothing => *self = Self::Areas(vec![area]),
            Self::Areas(areas)
                if areas.len() >= MOST_AREAS
                    || areas.iter().map(|a| a.points.len()).sum::<usize>() + area.points.len() > MOST_POINTS =>
            {
                *self = Self::Everything;
            }
            Self::Areas(areas) => areas.push(area),
        }
    }

    /// These changes and `other`'s.
    pub fn merge(&mut self, other: Self) {
        match other {
            Self::Nothing => {}
            Self::Everything => *self = Self::Everything,
            Self::Areas(areas) => areas.into_iter().for_each(|a| self.add(a)),
        }
    }
}

/// What the shadow maps took in of one tile of a layer: a digest of what
/// was drawn of it and a sphere (world) holding it.
#[derive(Debug, Clone, PartialEq)]
pub struct TileCast {
    pub key: u64,
    pub centre: DVec3,
    pub radius: f64,
}

impl TileCast {
    fn area(&self) -> Area {
        Area::sphere(self.centre, self.radius)
    }
}

/// Where a layer's tiles as drawn now (`now`) differ from what the maps
/// hold (`was`): each tile changed, where it was and where it is; each
/// tile gone or come.
pub fn tile_changes(was: &HashMap<TileKey, TileCast>, now: &HashMap<TileKey, TileCast>) -> Changes {
    let mut changes = Changes::Nothing;
    for (key, tile) in now {
        match was.get(key) {
            Some(before) if before == tile => {}
            Some(before) => {
                changes.add(before.area());
                changes.add(tile.area());
            }
            None => changes.add(tile.area()),
        }
    }
    for (key, before) in was {
        if !now.contains_key(key) {
            changes.add(before.area());
        }
    }
    changes
}

/// A region of one cascade's map being drawn: what casters are chosen by
/// and the frame uniform they are drawn with (the cascade's matrix).
pub struct CastInto<'a> {
    /// What the region sees from the sun: casters wholly outside it are
    /// left out.
    pub volume: &'a dyn Sees,
    /// Samples closer than this add nothing the map can hold, metres.
    pub finest_m: f64,
    pub frame: &'a FrameUniform,
}

/// A pass whose geometry casts shadows.
pub trait ShadowCaster {
    /// Where what it casts changed since the last `cast`.
    fn changes(&self) -> Changes;
    /// Chooses what it casts into the region `into` and writes what the
    /// draw reads (before that region's commands are submitted); builds
    /// its depth-only pipeline the first time.
    fn ready(&mut self, gpu: &Gpu, into: &CastInto<'_>);
    /// Records what `ready` chose into the region's depth-only pass.
    fn record(&self, pass: &mut wgpu::RenderPass<'_>);
    /// The maps now hold what it casts: its changes start again from here.
    fn cast(&mut self);
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_source::TileGrid;

    #[test]
    fn areas_past_the_most_are_everything() {
        let mut c = Changes::Nothing;
        for _ in 0..MOST_AREAS {
            c.add(Area::sphere(DVec3::ZERO, 1.0));
        }
        assert!(matches!(&c, Changes::Areas(a) if a.len() == MOST_AREAS));
        c.add(Area::sphere(DVec3::ZERO, 1.0));
        assert_eq!(c, Changes::Everything);
        let mut d = Changes::Nothing;
        d.merge(Changes::Areas(vec![Area::sphere(DVec3::X, 2.0)]));
        assert!(matches!(&d, Changes::Areas(a) if a.len() == 1));
    }

    #[test]
    fn areas_past_the_most_points_are_everything() {
        let surface = Surface::new(TileGrid::geodetic(256).expect("a grid"));
        let world = Extent { min_x: -180.0, min_y: -90.0, max_x: 180.0, max_y: 90.0 };
        let mut c = Changes::Nothing;
        c.add(Area::ground(&surface, &world, (0.0, 1.0)));
        assert!(matches!(&c, Changes::Areas(a) if a.len() == 1), "one planet's lattice is kept");
        c.add(Area::ground(&surface, &world, (0.0, 1.0)));
        assert_eq!(c, Changes::Everything, "two planets' lattices are more points than are kept");
    }

    #[test]
    fn the_ground_of_an_extent_holds_its_corners_at_both_heights() {
        let surface = Surface::new(TileGrid::geodetic(256).expect("a grid"));
        let e = Extent { min_x: 6.0, min_y: 45.0, max_x: 6.1, max_y: 45.1 };
        let a = Area::ground(&surface, &e, (100.0, 2000.0));
        for (x, y, h) in [(6.0, 45.0, 100.0), (6.1, 45.1, 2000.0), (6.0, 45.1, 2000.0)] {
            let p = surface.world(x, y, h);
            assert!(a.points.iter().any(|q| (*q - p).length() < 1e-6), "{x} {y} {h}");
        }
    }
}
