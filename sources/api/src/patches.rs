//! MultiPatch features as meshes: the 3D surfaces (buildings) ArcGIS keeps
//! in shapefiles and geodatabases, which a vector source hands straight to
//! the `buildings` layer.
//!
//! Readers give each patch as OGR does: a triangle of a strip or a fan is a
//! polygon of three points, an outer ring with the inner rings after it is a
//! polygon with holes, all in 3D. Each polygon is triangulated here on its
//! own plane: its Newell normal in a local metric frame (degrees scaled to
//! metres on the geodetic grid, so walls a few metres wide are not lost
//! against their heights), the rings projected onto that plane and cut by
//! earcut. A polygon with fewer than three distinct points, no area, or
//! that earcut cannot cut is skipped, with its reason; the state counts
//! them. Textures are not read (a MultiPatch's material and texture parts):
//! a building is one colour, from `color_by` or `color`, as `extrude` does.

use std::collections::BTreeMap;

use crate::colors::{feature_color, parse_color};
use crate::error::SourceError;
use crate::geodesy::MEAN_RADIUS_M;
use crate::payload::{Feature, Geometry, MeshPart, MeshTile, Skipped};
use crate::source::SourceSpec;

/// The options of a source whose features are MultiPatch surfaces.
pub const OPTIONS: &[&str] = &["z", "color", "color_by", "min_level"];

/// Buildings without a colour of their own: the light warm grey `extrude` uses.
pub const DEFAULT_COLOR: [f64; 4] = [0.85, 0.82, 0.76, 1.0];

/// How a source's heights place its surfaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ZPolicy {
    /// Heights as written (metres, the terrain's datum).
    Absolute,
    /// Relative to the ground: each feature's lowest vertex on the terrain
    /// as drawn (the renderer lifts it, as it lifts extruded buildings).
    Relative,
}

impl ZPolicy {
    pub fn name(self) -> &'static str {
        match self {
            Self::Absolute => "absolute",
            Self::Relative => "relative",
        }
    }
}

/// How a MultiPatch source draws: its `z` policy, colours and first level.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchStyle {
    pub z: ZPolicy,
    pub color: [f64; 4],
    pub color_by: Option<String>,
    /// Tiles coarser than this level stay empty.
    pub min_level: u8,
}

impl PatchStyle {
    /// The style the manifest gives a MultiPatch source.
    pub fn from_spec(spec: &SourceSpec) -> Result<Self, SourceError> {
        let z = match spec.text("z")? {
            None | Some("absolute") => ZPolicy::Absolute,
            Some("relative") => ZPolicy::Relative,
            Some(other) => {
                return Err(SourceError::option("z", format!("'{other}' is not 'absolute' or 'relative'")));
            }
        };
        let color = spec.text("color")?.map(|c| parse_color("color", c)).transpose()?.unwrap_or(DEFAULT_COLOR);
        let color_by = spec.text("color_by")?.map(str::to_owned);
        let min_level = spec.level("min_level")?.unwrap_or(0);
        Ok(Self { z, color, color_by, min_level })
    }

    /// Refuses the MultiPatch options on a source whose features are not
    /// surfaces: accepted, they would do nothing.
    pub fn refuse_on_features(spec: &SourceSpec, holds: &str) -> Result<(), SourceError> {
        match OPTIONS.iter().find(|o| spec.options.contains_key(**o)) {
            Some(option) => Err(SourceError::option(
                *option,
                format!(
                    "applies to MultiPatch layers (3D surfaces drawn as buildings), and this layer holds {holds}; \
                     for footprints use an `extrude` source over it"
                ),
            )),
            None => Ok(()),
        }
    }

    /// The details the state shows for this style.
    pub fn details(&self, details: &mut BTreeMap<String, String>) {
        details.insert("z".into(), self.z.name().into());
        details.insert("min_level".into(), self.min_level.to_string());
        if let Some(a) = &self.color_by {
            details.insert("color_by".into(), a.clone());
        }
    }
}

/// One triangulated polygon: its distinct points and triangles over them,
/// counter-clockwise seen from the side its exterior ring's winding faces.
#[derive(Debug, Clone, PartialEq)]
pub struct Triangulated {
    pub points: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// A ring without its closing point or repeated points, longitudes
/// unwrapped next to `first` on the geodetic grid.
fn open_ring(ring: &[[f64; 3]], first: Option<[f64; 3]>, geodetic: bool) -> Vec<[f64; 3]> {
    let mut out: Vec<[f64; 3]> = Vec::with_capacity(ring.len());
    for p in ring {
        let mut p = *p;
        if geodetic && let Some(f) = first.or_else(|| out.first().copied()) {
            p[0] += 360.0 * ((f[0] - p[0]) / 360.0).round();
        }
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    if out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    out
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// Newell's normal of a ring (its length twice the ring's area).
fn newell(ring: &[V3]) -> V3 {
    let mut n = [0.0; 3];
    for k in 0..ring.len() {
        let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    n
}

/// Triangulates one polygon (exterior ring, then holes) in the grid's CRS.
/// Holes of under three points or without area cut nothing. Err: why the
/// polygon gives no triangles.
pub fn triangulate(rings: &[Vec<[f64; 3]>], geodetic: bool) -> Result<Triangulated, &'static str> {
    let Some(exterior) = rings.first() else { return Err("an empty patch") };
    // A missing height (NaN) is 0 here: only where a patch is drawn cares.
    if exterior.iter().any(|v| !v[0].is_finite() || !v[1].is_finite() || v[2].is_infinite()) {
        return Err("a patch with a coordinate that is not a number");
    }
    let exterior = open_ring(exterior, None, geodetic);
    if exterior.len() < 3 {
        return Err("a patch with fewer than three distinct points");
    }
    let origin = exterior[0];
    // Grid units to metres about the first point.
    let (sx, sy) = if geodetic {
        let m = MEAN_RADIUS_M.to_radians();
        (m * origin[1].to_radians().cos().max(1e-9), m)
    } else {
        (1.0, 1.0)
    };
    let z = |v: f64| if v.is_nan() { 0.0 } else { v };
    let local = |p: &V3| [(p[0] - origin[0]) * sx, (p[1] - origin[1]) * sy, z(p[2]) - z(origin[2])];
    let area_of = |ring: &[V3]| -> (V3, bool) {
        let metric: Vec<V3> = ring.iter().map(local).collect();
        let n = newell(&metric);
        let (lo, hi) = metric.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
            ([lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])], [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])])
        });
        let diagonal2 = dot(sub(hi, lo), sub(hi, lo));
        (n, norm(n) > 1e-9 * diagonal2)
    };
    let (normal, has_area) = area_of(&exterior);
    if !has_area {
        return Err("a patch without area (its points are collinear)");
    }
    let mut kept = vec![exterior];
    for hole in &rings[1..] {
        let hole = open_ring(hole, Some(origin), geodetic);
        if hole.len() >= 3 && hole.iter().all(|v| v[0].is_finite() && v[1].is_finite()) && area_of(&hole).1 {
            kept.push(hole);
        }
    }
    // The plane's axes: u level (or east-west for a level patch), v = n x u.
    let n = normal.map(|c| c / norm(normal));
    let helper = if n[2].abs() < 0.9 { [0.0, 0.0, 1.0] } else { [1.0, 0.0, 0.0] };
    let u = cross(helper, n);
    let u = u.map(|c| c / norm(u));
    let v = cross(n, u);
    let mut flat = Vec::new();
    let mut holes = Vec::new();
    let mut points = Vec::new();
    for (k, ring) in kept.iter().enumerate() {
        if k > 0 {
            holes.push(points.len());
        }
        for p in ring {
            let q = local(p);
            flat.extend([dot(q, u), dot(q, v)]);
            points.push(*p);
        }
    }
    let cut = earcutr::earcut(&flat, &holes, 2).map_err(|_| "a patch that cannot be triangulated")?;
    if cut.is_empty() {
        return Err("a patch that cannot be triangulated");
    }
    // In (u, v), counter-clockwise is counter-clockwise about n: the
    // exterior's own winding.
    let triangles = cut
        .chunks_exact(3)
        .map(|t| {
            let (a, b, c) = (t[0] * 2, t[1] * 2, t[2] * 2);
            let ccw = (flat[b] - flat[a]) * (flat[c + 1] - flat[a + 1])
                - (flat[c] - flat[a]) * (flat[b + 1] - flat[a + 1])
                >= 0.0;
            let (i, j) = if ccw { (t[1], t[2]) } else { (t[2], t[1]) };
            [t[0] as u32, i as u32, j as u32]
        })
        .collect();
    Ok(Triangulated { points, triangles })
}

/// The point a feature is drawn from: the mean of its vertices (longitudes
/// unwrapped next to its first), so it belongs to exactly one tile a level.
pub fn anchor(feature: &Feature, geodetic: bool) -> Option<(f64, f64)> {
    let Geometry::Polygons(polygons) = &feature.geometry else { return None };
    let mut first: Option<[f64; 3]> = None;
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for p in polygons.iter().flatten().flatten().filter(|p| p[0].is_finite() && p[1].is_finite()) {
        let f = *first.get_or_insert(*p);
        let x = if geodetic { p[0] + 360.0 * ((f[0] - p[0]) / 360.0).round() } else { p[0] };
        (sx, sy, n) = (sx + x, sy + p[1], n + 1.0);
    }
    (n > 0.0).then(|| (sx / n, sy / n))
}

/// Patch counts for the state: what a source's surfaces gave.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PatchCounts {
    pub patches: usize,
    pub triangles: usize,
    /// Degenerate patches, by reason.
    pub skipped: BTreeMap<&'static str, usize>,
}

impl PatchCounts {
    /// Triangulates every feature once to count what it gives.
    pub fn of<'a>(features: impl Iterator<Item = &'a Feature>, geodetic: bool) -> Self {
        let mut counts = Self::default();
        for feature in features {
            let Geometry::Polygons(polygons) = &feature.geometry else { continue };
            for polygon in polygons {
                counts.patches += 1;
                match triangulate(polygon, geodetic) {
                    Ok(t) => counts.triangles += t.triangles.len(),
                    Err(reason) => *counts.skipped.entry(reason).or_insert(0) += 1,
                }
            }
        }
        counts
    }

    /// Into the state: counts in the details, and a warning when patches
    /// were skipped.
    pub fn report(&self, details: &mut BTreeMap<String, String>, warnings: &mut Vec<String>) {
        details.insert("patches".into(), self.patches.to_string());
        details.insert("triangles".into(), self.triangles.to_string());
        let total: usize = self.skipped.values().sum();
        details.insert("skipped_patches".into(), total.to_string());
        for (reason, count) in &self.skipped {
            details.insert(format!("skipped_patches.{reason}"), count.to_string());
        }
        if total > 0 {
            let reasons: Vec<String> = self.skipped.iter().map(|(r, n)| format!("{n} × {r}")).collect();
            warnings.push(format!(
                "{total} of {} MultiPatch patches were degenerate and are not drawn: {}",
                self.patches,
                reasons.join(", ")
            ));
        }
    }
}

/// The mesh of `features` (those the tile owns), each feature one part in
/// its colour. Heights stay as written: a relative style marks the parts
/// for the renderer to set on the ground.
pub fn mesh<'a>(features: impl Iterator<Item = &'a Feature>, geodetic: bool, style: &PatchStyle) -> MeshTile {
    let mut mesh = MeshTile::default();
    let relative = style.z == ZPolicy::Relative;
    for feature in features {
        let Geometry::Polygons(polygons) = &feature.geometry else { continue };
        let first_index = mesh.indices.len() as u32;
        for polygon in polygons {
            let t = match triangulate(polygon, geodetic) {
                Ok(t) if !relative && t.points.iter().any(|p| p[2].is_nan()) => {
                    Err("a patch without heights (z), drawn at absolute heights")
                }
                other => other,
            };
            match t {
                Ok(t) => {
                    let base = mesh.positions.len() as u32;
                    mesh.positions
                        .extend(t.points.iter().map(|p| [p[0], p[1], if p[2].is_nan() { 0.0 } else { p[2] }]));
                    mesh.indices.extend(t.triangles.iter().flatten().map(|i| base + i));
                }
                Err(reason) => mesh.skipped.push(Skipped { feature_id: feature.id, reason: reason.to_owned() }),
            }
        }
        let index_count = mesh.indices.len() as u32 - first_index;
        if index_count > 0 {
            let color = feature_color(feature, style.color_by.as_deref(), style.color);
            mesh.parts.push(MeshPart { feature_id: feature.id, first_index, index_count, color, on_ground: relative });
        }
    }
    mesh
}

#[cfg(test)]
mod tests;
