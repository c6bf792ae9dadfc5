//! `extrude`: building footprints (polygons) become closed-top meshes:
//! walls from the ground up to a flat roof, the roof triangulated with its
//! holes (courtyards). The height comes from an attribute, from KML's
//! altitude and extrude, or from a default.

use relief_source::{
    Feature, GenerateContext, Geometry, MeshPart, MeshTile, Payload, PayloadKind, Skipped, Source, SourceError,
    SourceInfo, SourceSpec, TileKey,
};

use crate::placement::{AltitudeMode, AttributeOr, Ground, check_inputs};
use relief_source::colors::{feature_color, parse_color};
use relief_source::patches::DEFAULT_COLOR;

pub const EXTRUDE_KIND: &str = "extrude";
/// Footprints, then (optional) the terrain the buildings stand on.
pub const EXTRUDE_INPUTS: &[PayloadKind] = &[PayloadKind::Features, PayloadKind::Height];

#[derive(Debug)]
pub struct Extrude {
    id: String,
    inputs: Vec<String>,
    /// `height_attribute` and `height` (metres above the ground).
    height: AttributeOr,
    /// Tiles coarser than this level stay empty: a building a few metres
    /// wide is less than a texel there, and meshing it costs for nothing.
    min_level: u8,
    /// `color`: every building's colour unless `color_by` or a KML style
    /// gives one.
    color: [f64; 4],
    /// `color_by`: colour by this attribute's value (a fixed palette).
    color_by: Option<String>,
}

impl Extrude {
    pub fn open(spec: &SourceSpec) -> Result<Self, SourceError> {
        spec.only_options(&["height_attribute", "height", "min_level", "color", "color_by"])?;
        check_inputs(spec, EXTRUDE_KIND, false)?;
        let height = AttributeOr::from_spec(spec, "height")?;
        if height.value.is_some_and(|h| h <= 0.0) {
            return Err(SourceError::option("height", "a default height is more than 0 m"));
        }
        let min_level = spec.level("min_level")?.unwrap_or(0);
        let color = spec.text("color")?.map(|c| parse_color("color", c)).transpose()?.unwrap_or(DEFAULT_COLOR);
        let color_by = spec.text("color_by")?.map(str::to_owned);
        Ok(Self { id: spec.id.clone(), inputs: spec.inputs.clone(), height, min_level, color, color_by })
    }

    /// A building's colour: by `color_by`'s value, else its KML style's
    /// fill (made opaque), else `color`.
    fn color_of(&self, feature: &Feature) -> [u8; 4] {
        feature_color(feature, self.color_by.as_deref(), self.color)
    }

    /// The roof height of `feature` (metres, same datum as the ground), given
    /// the ground `base` under it.
    fn roof(&self, feature: &Feature, rings: &[Vec<[f64; 3]>], base: f64) -> Result<f64, String> {
        if let Some(h) = self.height.of(&feature.properties)? {
            return if h > 0.0 { Ok(base + h) } else { Err(format!("height {h} m is not above the ground")) };
        }
        let extruded = feature.properties.get("extrude").is_some_and(|e| e == "true" || e == "1");
        let zs: Vec<f64> = rings.iter().take(1).flatten().map(|p| p[2]).filter(|z| z.is_finite()).collect();
        let z = (!zs.is_empty()).then(|| zs.iter().sum::<f64>() / zs.len() as f64);
        match (extruded, AltitudeMode::of(&feature.properties), z) {
            (true, AltitudeMode::Absolute, Some(z)) => Ok(z),
            (true, AltitudeMode::RelativeToGround, Some(z)) => Ok(base + z),
            _ => Err("no height: no height attribute, no KML extrude with altitude, no default".into()),
        }
    }
}

/// The ring without its closing point, x unwrapped next to the first
/// point on the geodetic grid (a footprint on the antimeridian stays whole).
fn open_ring(ring: &[[f64; 3]], geodetic: bool) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::with_capacity(ring.len());
    for p in ring {
        let mut x = p[0];
        if geodetic && let Some(first) = out.first() {
            x += 360.0 * ((first[0] - x) / 360.0).round();
        }
        if out.last() != Some(&[x, p[1]]) {
            out.push([x, p[1]]);
        }
    }
    if out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    out
}

/// Twice the signed area (positive counter-clockwise, x east, y north).
/// A ring whose area is lost in rounding against its own size: collinear
/// points (whose computed area is 1e-16, not 0), or lobes that cancel.
fn has_no_area(ring: &[[f64; 2]]) -> bool {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in ring {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let diagonal2 = (hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2);
    signed_area2(ring).abs() <= 1e-9 * diagonal2
}

/// Twice the ring's signed area, from its first point (so coordinates far
/// from the origin do not cancel away the area of a small ring).
fn signed_area2(ring: &[[f64; 2]]) -> f64 {
    let Some(&o) = ring.first() else { return 0.0 };
    (0..ring.len())
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            (a[0] - o[0]) * (b[1] - o[1]) - (b[0] - o[0]) * (a[1] - o[1])
        })
        .sum()
}

/// Appends one building to `mesh`: walls for every ring edge (four
/// vertices each, so each wall keeps its own flat normal) and the roof.
fn build(mesh: &mut MeshTile, rings: &[Vec<[f64; 2]>], base: f64, roof: f64) -> Result<(), String> {
    let vertex = |mesh: &mut MeshTile, p: [f64; 2], z: f64| {
        mesh.positions.push([p[0], p[1], z]);
        mesh.positions.len() as u32 - 1
    };
    // Roof first: a footprint earcut cannot triangulate is left out whole.
    let flat: Vec<f64> = rings.iter().flatten().flat_map(|p| *p).collect();
    let mut holes = Vec::new();
    let mut start = 0;
    for ring in &rings[..rings.len() - 1] {
        start += ring.len();
        holes.push(start);
    }
    let triangles = earcutr::earcut(&flat, &holes, 2).map_err(|e| format!("roof cannot be triangulated: {e:?}"))?;
    if triangles.is_empty() {
        return Err("roof cannot be triangulated".into());
    }
    let all: Vec<[f64; 2]> = rings.iter().flatten().copied().collect();
    let roof_first = mesh.positions.len() as u32;
    for p in &all {
        vertex(mesh, *p, roof);
    }
    for t in triangles.chunks_exact(3) {
        let (a, b, c) = (all[t[0]], all[t[1]], all[t[2]]);
        let ccw = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]) >= 0.0;
        let (i, j) = if ccw { (t[1], t[2]) } else { (t[2], t[1]) };
        mesh.indices.extend([roof_first + t[0] as u32, roof_first + i as u32, roof_first + j as u32]);
    }
    // Walls: the exterior runs counter-clockwise and holes clockwise, so the
    // outside of every wall is to the right of its edge.
    for ring in rings {
        for k in 0..ring.len() {
            let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
            let v0 = vertex(mesh, a, base);
            let v1 = vertex(mesh, b, base);
            let v2 = vertex(mesh, b, roof);
            let v3 = vertex(mesh, a, roof);
            mesh.indices.extend([v0, v1, v2, v0, v2, v3]);
        }
    }
    Ok(())
}

impl Source for Extrude {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        EXTRUDE_KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Mesh
    }

    fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn info(&self) -> SourceInfo {
        let mut info = SourceInfo::default();
        if let Some(a) = &self.height.attribute {
            info.details.insert("height_attribute".into(), a.clone());
        }
        if let Some(h) = self.height.value {
            info.details.insert("height".into(), h.to_string());
        }
        info.details.insert("min_level".into(), self.min_level.to_string());
        if let Some(a) = &self.color_by {
            info.details.insert("color_by".into(), a.clone());
        }
        info.details.insert("ground".into(), self.inputs.get(1).cloned().unwrap_or_else(|| "0 m".into()));
        info
    }

    /// A building belongs to the one tile that owns the average of its
    /// exterior ring's points, so no building is drawn twice.
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let mut mesh = MeshTile::default();
        if key.level < self.min_level {
            return Ok(Payload::Mesh(mesh));
        }
        let input = ctx.inputs.tile(0, key)?;
        let Payload::Features(features) = input.as_ref() else {
            return Err(SourceError::Input { input: self.inputs[0].clone(), message: "expected feature tiles".into() });
        };
        let geodetic = ctx.grid.is_geodetic();
        let mut ground = Ground::new(ctx, key, self.inputs.len() > 1);
        for feature in &features.features {
            let Geometry::Polygons(polygons) = &feature.geometry else { continue };
            let first_index = mesh.indices.len() as u32;
            for polygon in polygons {
                let Some(exterior) = polygon.first().map(|r| open_ring(r, geodetic)) else { continue };
                if exterior.is_empty() {
                    continue;
                }
                let n = exterior.len() as f64;
                let (cx, cy) = exterior.iter().fold((0.0, 0.0), |(x, y), p| (x + p[0] / n, y + p[1] / n));
                if ctx.grid.key_at(key.level, cx, cy) != Some(key) {
                    continue;
                }
                let skip = |mesh: &mut MeshTile, reason: String| {
                    mesh.skipped.push(Skipped { feature_id: feature.id, reason });
                };
                if exterior.len() < 3 {
                    skip(&mut mesh, format!("the footprint has {} distinct points, fewer than three", exterior.len()));
                    continue;
                }
                if has_no_area(&exterior) {
                    skip(&mut mesh, "the footprint has no area (its points are collinear, or its lobes cancel)".into());
                    continue;
                }
                // Holes of under three points or no area cut nothing.
                let mut rings: Vec<Vec<[f64; 2]>> = std::iter::once(exterior)
                    .chain(
                        polygon[1..].iter().map(|r| open_ring(r, geodetic)).filter(|r| r.len() >= 3 && !has_no_area(r)),
                    )
                    .collect();
                for (k, ring) in rings.iter_mut().enumerate() {
                    if (signed_area2(ring) > 0.0) != (k == 0) {
                        ring.reverse();
                    }
                }
                let mut base = f64::INFINITY;
                for p in &rings[0] {
                    match ground.at(p[0], p[1])? {
                        Some(h) => base = base.min(h),
                        None => base = f64::NAN,
                    }
                }
                if !base.is_finite() {
                    skip(&mut mesh, "the terrain has no data under the footprint".into());
                    continue;
                }
                let outcome = self.roof(feature, polygon, base).and_then(|roof| {
                    if roof > base {
                        build(&mut mesh, &rings, base, roof)
                    } else {
                        Err(format!("roof at {roof} m is not above the ground at {base} m"))
                    }
                });
                if let Err(reason) = outcome {
                    skip(&mut mesh, reason);
                }
            }
            let index_count = mesh.indices.len() as u32 - first_index;
            if index_count > 0 {
                let color = self.color_of(feature);
                mesh.parts.push(MeshPart { feature_id: feature.id, first_index, index_count, color, on_ground: true });
            }
        }
        Ok(Payload::Mesh(mesh))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Volume by the divergence theorem over roof and walls, plus the open
    /// floor at `base` (area times base, facing down).
    fn volume(mesh: &MeshTile, base: f64) -> f64 {
        let mut v = 0.0;
        let mut floor_area = 0.0;
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            let nz = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / 2.0;
            v += nz * (a[2] + b[2] + c[2]) / 3.0;
            floor_area += nz;
        }
        v - floor_area * base
    }

    #[test]
    fn a_courtyard_building_is_closed_and_has_its_volume() {
        // 20 x 10 m with a 4 x 4 m courtyard, given clockwise (as shapefiles
        // store exteriors): the mesh must still face outwards.
        let exterior = open_ring(
            &[[0.0, 0.0, 0.0], [0.0, 10.0, 0.0], [20.0, 10.0, 0.0], [20.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
            false,
        );
        let hole = open_ring(&[[8.0, 3.0, 0.0], [12.0, 3.0, 0.0], [12.0, 7.0, 0.0], [8.0, 7.0, 0.0]], false);
        let mut rings = vec![exterior, hole];
        for (k, ring) in rings.iter_mut().enumerate() {
            if (signed_area2(ring) > 0.0) != (k == 0) {
                ring.reverse();
            }
        }
        let mut mesh = MeshTile::default();
        build(&mut mesh, &rings, 100.0, 112.5).unwrap();
        assert!((volume(&mesh, 100.0) - (200.0 - 16.0) * 12.5).abs() < 1e-9, "{}", volume(&mesh, 100.0));
        // Every roof triangle faces up.
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            if a[2] == 112.5 && b[2] == 112.5 && c[2] == 112.5 {
                assert!((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]) > 0.0);
            }
        }
        // 8 walls of two triangles, and the roof of a square ring with a hole: 8 triangles.
        assert_eq!(mesh.indices.len() / 3, 8 * 2 + 8);
    }

    #[test]
    fn a_footprint_on_the_antimeridian_stays_whole() {
        let ring = open_ring(
            &[[179.9999, 0.0, 0.0], [-179.9999, 0.0, 0.0], [-179.9999, 0.0001, 0.0], [179.9999, 0.0001, 0.0]],
            true,
        );
        let xs: Vec<f64> = ring.iter().map(|p| p[0]).collect();
        assert!(xs.iter().all(|x| (x - 180.0).abs() < 0.001), "{xs:?}");
        assert!(signed_area2(&ring).abs() > 0.0);
    }

    #[test]
    fn a_building_takes_its_colour_from_color_by_then_its_kml_style_then_color()
    -> Result<(), Box<dyn std::error::Error>> {
        let spec = |options: &[(&str, &str)]| SourceSpec {
            id: "b".into(),
            kind: EXTRUDE_KIND.into(),
            inputs: vec!["f".into()],
            options: options
                .iter()
                .map(|(k, v)| ((*k).to_owned(), relief_source::OptionValue::Text((*v).to_owned())))
                .collect(),
            ..Default::default()
        };
        let mut feature =
            Feature { id: 1, geometry: Geometry::Polygons(vec![]), properties: std::collections::BTreeMap::default() };
        let plain = Extrude::open(&spec(&[("color", "#102030")]))?;
        assert_eq!(plain.color_of(&feature), [0x10, 0x20, 0x30, 255]);
        // KML's aabbggrr: a half-transparent red style is drawn opaque red.
        feature.properties.insert("fill_color".into(), "7f0000ff".into());
        assert_eq!(plain.color_of(&feature), [255, 0, 0, 255]);
        // color_by wins, the same value the same colour in every tile.
        let by = Extrude::open(&spec(&[("color_by", "use")]))?;
        feature.properties.insert("use".into(), "school".into());
        let school = by.color_of(&feature);
        assert_ne!(school, [255, 0, 0, 255]);
        let other = Feature { id: 2, ..feature.clone() };
        assert_eq!(by.color_of(&other), school);
        assert!(Extrude::open(&spec(&[("color", "blue")])).unwrap_err().to_string().contains("color"));
        Ok(())
    }

    #[test]
    fn kml_altitudes_give_the_roof() {
        let spec =
            SourceSpec { id: "b".into(), kind: EXTRUDE_KIND.into(), inputs: vec!["f".into()], ..Default::default() };
        let op = Extrude::open(&spec).unwrap();
        let ring = vec![vec![[0.0, 0.0, 30.0], [1.0, 0.0, 30.0], [1.0, 1.0, 30.0]]];
        let mut feature = Feature {
            id: 1,
            geometry: Geometry::Polygons(vec![ring.clone()]),
            properties: std::collections::BTreeMap::default(),
        };
        assert!(op.roof(&feature, &ring, 5.0).is_err(), "clamped, not extruded: no height");
        feature.properties.insert("extrude".into(), "true".into());
        feature.properties.insert("altitude_mode".into(), "absolute".into());
        assert_eq!(op.roof(&feature, &ring, 5.0), Ok(30.0));
        feature.properties.insert("altitude_mode".into(), "relativeToGround".into());
        assert_eq!(op.roof(&feature, &ring, 5.0), Ok(35.0));
        feature.properties.insert("height".into(), "abc".into());
        let spec = SourceSpec {
            options: [("height_attribute".to_owned(), relief_source::OptionValue::Text("height".into()))].into(),
            ..spec
        };
        let op = Extrude::open(&spec).unwrap();
        assert_eq!(op.roof(&feature, &ring, 5.0), Err("attribute 'height' is 'abc', not a number".into()));
    }
}
