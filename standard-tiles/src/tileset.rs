//! 3D Tiles 1.1 `tileset.json` over relief's glTF tiles: one root that
//! adds (`refine: "ADD"`) one child per tile of content.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use relief_source::TileGrid;
use relief_source::geodesy::MEAN_RADIUS_M;
use serde_json::{Value, json};

use crate::Glb;

/// One tile of content in a tileset.
#[derive(Debug, Clone, PartialEq)]
pub struct TilesetEntry {
    /// The content's address, relative to the tileset's.
    pub uri: String,
    /// `boundingVolume.region` (see [`Glb::region`]).
    pub region: [f64; 6],
    /// The tile transform (see [`Glb::transform`]).
    pub transform: [f64; 16],
    pub geometric_error_m: f64,
}

impl TilesetEntry {
    /// The entry for a GLB served at `uri`.
    pub fn new(uri: impl Into<String>, glb: &Glb, geometric_error_m: f64) -> Self {
        Self { uri: uri.into(), region: glb.region, transform: glb.transform, geometric_error_m }
    }
}

/// A 3D Tiles 1.1 tileset of `entries` under one root whose region holds
/// them all (the whole planet when there are none), with `root_error_m`
/// as both the tileset's and the root's geometric error.
///
/// A child's `transform` places its content; its region is geographic and
/// so, as 3D Tiles specifies, not moved by it.
pub fn tileset_json(version: &str, entries: &[TilesetEntry], root_error_m: f64) -> Value {
    let children: Vec<Value> = entries
        .iter()
        .map(|e| {
            json!({
                "boundingVolume": { "region": e.region },
                "transform": e.transform,
                "geometricError": e.geometric_error_m,
                "content": { "uri": e.uri },
            })
        })
        .collect();
    json!({
        "asset": { "version": "1.1", "tilesetVersion": version },
        "geometricError": root_error_m,
        "root": {
            "boundingVolume": { "region": enclosing_region(entries.iter().map(|e| &e.region)) },
            "geometricError": root_error_m,
            "refine": "ADD",
            "children": children,
        },
    })
}

/// The smallest region holding `regions`: latitudes and heights by their
/// extremes; longitudes as the circle less the widest gap between them,
/// so that regions on both sides of the antimeridian give one across it
/// (west east of east) rather than one round the planet.
fn enclosing_region<'a>(regions: impl Iterator<Item = &'a [f64; 6]>) -> [f64; 6] {
    let mut spans: Vec<(f64, f64)> = Vec::new();
    let mut rest = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
    for &[west, south, east, north, low, high] in regions {
        // A span across the antimeridian in two, each within [-pi, pi].
        if west <= east {
            spans.push((west, east));
        } else {
            spans.extend([(west, PI), (-PI, east)]);
        }
        rest = [rest[0].min(south), rest[1].max(north), rest[2].min(low), rest[3].max(high)];
    }
    if spans.is_empty() {
        return [-PI, -FRAC_PI_2, PI, FRAC_PI_2, 0.0, 0.0];
    }
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for (w, e) in spans {
        match merged.last_mut() {
            Some(last) if w <= last.1 => last.1 = last.1.max(e),
            _ => merged.push((w, e)),
        }
    }
    // The widest gap is where the region is not: round the back of the
    // planet (from the last span's east to the first's west) gives a plain
    // region, one between two spans a region across the antimeridian.
    let (first, last) = (merged[0], merged[merged.len() - 1]);
    let (mut gap, mut west, mut east) = (first.0 + TAU - last.1, first.0, last.1);
    for pair in merged.windows(2) {
        if pair[1].0 - pair[0].1 > gap {
            (gap, west, east) = (pair[1].0 - pair[0].1, pair[1].0, pair[0].1);
        }
    }
    if gap <= 0.0 {
        (west, east) = (-PI, PI);
    }
    [west, rest[0], east, rest[1], rest[2], rest[3]]
}

/// The geometric error for tiles of `level`: the ground length of a tile's
/// side at that level, in metres.
///
/// On the geodetic grid that is the tile's north-south side along a
/// meridian on the mean sphere (a tile is as many degrees tall as wide, and
/// its height, unlike its width, does not shrink towards the poles):
/// 20,015 km / 2^level. Content drawn from one level of tiles misses at
/// most detail of about that size, and Cesium's screen-space error then
/// asks for the content when a tile is a few dozen pixels on screen. On a
/// projected grid it is the tile's side in the CRS's units, metres for the
/// usual projected CRSs.
pub fn geometric_error_for_level(grid: &TileGrid, level: u8) -> f64 {
    let (_, height) = grid.tile_span(level);
    if grid.is_geodetic() { height.to_radians() * MEAN_RADIUS_M } else { height }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(region: [f64; 6]) -> TilesetEntry {
        TilesetEntry { uri: "a.glb".into(), region, transform: [0.0; 16], geometric_error_m: 1.0 }
    }

    fn root_region(entries: &[TilesetEntry]) -> Vec<f64> {
        let v = tileset_json("7", entries, 100.0);
        v["root"]["boundingVolume"]["region"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
    }

    #[test]
    fn tileset_has_the_asset_root_and_one_child_per_entry() {
        let glb = Glb { bytes: vec![], transform: [2.0; 16], region: [0.1, 0.2, 0.3, 0.4, -5.0, 50.0] };
        let entries = [TilesetEntry::new("16/1/2.glb", &glb, 12.5), entry([0.2, 0.1, 0.25, 0.5, 0.0, 80.0])];
        let v = tileset_json("gen-42", &entries, 400.0);
        assert_eq!(v["asset"], json!({ "version": "1.1", "tilesetVersion": "gen-42" }));
        assert_eq!(v["geometricError"], 400.0);
        assert_eq!(v["root"]["refine"], "ADD");
        assert_eq!(v["root"]["geometricError"], 400.0);
        let children = v["root"]["children"].as_array().unwrap();
        assert_eq!(children.len(), 2);
        assert_eq!(children[0]["content"]["uri"], "16/1/2.glb");
        assert_eq!(children[0]["transform"], json!(vec![2.0; 16]));
        assert_eq!(children[0]["geometricError"], 12.5);
        assert_eq!(children[0]["boundingVolume"]["region"], json!([0.1, 0.2, 0.3, 0.4, -5.0, 50.0]));
        assert_eq!(root_region(&entries), [0.1, 0.1, 0.3, 0.5, -5.0, 80.0]);
    }

    #[test]
    fn root_region_crosses_the_antimeridian_when_the_entries_do() {
        let east = entry([3.13, 0.0, 3.138, 0.1, 0.0, 1.0]);
        let west = entry([-3.138, 0.0, -3.13, 0.1, 0.0, 1.0]);
        let across = entry([3.135, 0.0, -3.135, 0.1, 0.0, 1.0]);
        assert_eq!(root_region(&[east.clone(), west.clone()]), [3.13, 0.0, -3.13, 0.1, 0.0, 1.0]);
        assert_eq!(root_region(&[across.clone(), east.clone()]), [3.13, 0.0, -3.135, 0.1, 0.0, 1.0]);
        // Far apart on one side: not across.
        let a = entry([-1.0, 0.0, -0.9, 0.1, 0.0, 1.0]);
        let b = entry([1.0, 0.0, 1.1, 0.1, 0.0, 1.0]);
        assert_eq!(root_region(&[b, a]), [-1.0, 0.0, 1.1, 0.1, 0.0, 1.0]);
        // Reaching to 180 exactly stays east of its west.
        let to_180 = entry([3.0, 0.0, PI, 0.1, 0.0, 1.0]);
        assert_eq!(root_region(&[to_180]), [3.0, 0.0, PI, 0.1, 0.0, 1.0]);
        // No entries: the planet.
        assert_eq!(root_region(&[]), [-PI, -FRAC_PI_2, PI, FRAC_PI_2, 0.0, 0.0]);
        // Covering every longitude.
        let half_e = entry([0.0, 0.0, PI, 0.1, 0.0, 1.0]);
        let half_w = entry([-PI, 0.0, 0.0, 0.1, 0.0, 1.0]);
        assert_eq!(root_region(&[half_e, half_w])[..4], [-PI, 0.0, PI, 0.1]);
    }

    #[test]
    fn geometric_error_is_a_tiles_side_on_the_ground() {
        let grid = TileGrid::geodetic(256).unwrap();
        // Level 0: 180 degrees of meridian, half the mean great circle.
        assert!((geometric_error_for_level(&grid, 0) - PI * MEAN_RADIUS_M).abs() < 1e-6);
        // Level 16: about 305 m; halving with each level.
        let e16 = geometric_error_for_level(&grid, 16);
        assert!((e16 - 305.4).abs() < 0.1, "{e16}");
        assert!((geometric_error_for_level(&grid, 17) * 2.0 - e16).abs() < 1e-9);
    }
}
