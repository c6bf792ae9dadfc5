//! One OGR layer's features into relief features (in the layer's own CRS).

use std::collections::BTreeMap;
use std::path::Path;

use gdal::vector::{
    FieldValue, Geometry as OgrGeometry, LayerAccess, OGRFieldType, OGRwkbGeometryType as Wkb, field_type_to_name,
    geometry_type_flatten, geometry_type_has_z,
};
use relief_source::{Feature, Geometry, SourceError};

/// What a read of one layer found.
pub(crate) struct LayerRead {
    pub features: Vec<Feature>,
    /// Features without a geometry, or with an empty one: left out.
    pub null_geometries: usize,
    /// Features left out, by reason ("curve", "mixed_collection"...).
    pub skipped: BTreeMap<&'static str, usize>,
    /// Every attribute field as "name:Type", in the layer's order.
    pub fields: Vec<String>,
    /// Some features are surfaces (TINs, polyhedral surfaces).
    pub surfaces: bool,
}

/// The parts of one geometry, sorted by family.
#[derive(Default)]
struct Parts {
    points: Vec<[f64; 3]>,
    lines: Vec<Vec<[f64; 3]>>,
    polygons: Vec<Vec<Vec<[f64; 3]>>>,
    /// Some of the polygons came from a surface (a TIN or a polyhedral
    /// surface, as OGR reads a MultiPatch's strips and fans).
    surfaces: bool,
}

/// The vertices of a curve or ring; z is NaN when the geometry has none.
fn positions(g: &OgrGeometry) -> Vec<[f64; 3]> {
    let has_z = geometry_type_has_z(g.geometry_type());
    let mut points = Vec::new();
    g.get_points(&mut points);
    points.into_iter().map(|(x, y, z)| [x, y, if has_z { z } else { f64::NAN }]).collect()
}

/// Adds `g`'s parts to `parts`, collections flattened; the reason when
/// relief cannot take it.
fn collect(g: &OgrGeometry, parts: &mut Parts) -> Result<(), &'static str> {
    if g.is_empty() {
        return Ok(());
    }
    match geometry_type_flatten(g.geometry_type()) {
        Wkb::wkbPoint => {
            let (x, y, z) = g.get_point(0);
            parts.points.push([x, y, if geometry_type_has_z(g.geometry_type()) { z } else { f64::NAN }]);
        }
        Wkb::wkbLineString | Wkb::wkbLinearRing => parts.lines.push(positions(g)),
        Wkb::wkbPolygon | Wkb::wkbTriangle => {
            let rings: Vec<_> =
                (0..g.geometry_count()).map(|i| positions(&g.get_geometry(i))).filter(|r| !r.is_empty()).collect();
            if !rings.is_empty() {
                parts.polygons.push(rings);
            }
        }
        Wkb::wkbMultiPoint | Wkb::wkbMultiLineString | Wkb::wkbMultiPolygon | Wkb::wkbGeometryCollection => {
            for i in 0..g.geometry_count() {
                collect(&g.get_geometry(i), parts)?;
            }
        }
        Wkb::wkbCircularString
        | Wkb::wkbCompoundCurve
        | Wkb::wkbCurvePolygon
        | Wkb::wkbMultiCurve
        | Wkb::wkbMultiSurface
        | Wkb::wkbCurve
        | Wkb::wkbSurface => return Err("curve"),
        // A MultiPatch's strips and fans, as OGR reads them: their
        // triangles (or faces) as polygons.
        Wkb::wkbPolyhedralSurface | Wkb::wkbTIN => {
            parts.surfaces = true;
            for i in 0..g.geometry_count() {
                collect(&g.get_geometry(i), parts)?;
            }
        }
        _ => return Err("unknown_geometry"),
    }
    Ok(())
}

/// A relief geometry (and whether it holds surfaces), `Ok(None)` for an
/// empty one, or why it is skipped.
fn geometry(g: &OgrGeometry) -> Result<Option<(Geometry, bool)>, &'static str> {
    let mut parts = Parts::default();
    collect(g, &mut parts)?;
    let Parts { points, lines, polygons, surfaces } = parts;
    Ok(Some(match (points.is_empty(), lines.is_empty(), polygons.is_empty()) {
        (true, true, true) => return Ok(None),
        (false, true, true) => (Geometry::Points(points), false),
        (true, false, true) => (Geometry::Lines(lines), false),
        (true, true, false) => (Geometry::Polygons(polygons), surfaces),
        _ => return Err("mixed_collection"),
    }))
}

/// GDAL's own text of a date-time ("2024/05/01 12:30:00.5+02") as
/// ISO 8601 ("2024-05-01T12:30:00.5+02:00"); a time zone GDAL does not
/// know stays absent. Anything else is kept as GDAL wrote it.
fn iso_datetime(gdal: &str) -> String {
    let Some((date, time)) = gdal.split_once(' ') else {
        return gdal.replace('/', "-");
    };
    let date = date.replace('/', "-");
    let time = time.trim();
    // The zone: "Z", "+HH" or "+HHMM" after the seconds.
    let split = time.rfind(['+', '-']).filter(|&i| i > 0);
    let (clock, zone) = match split {
        Some(i) => (&time[..i], &time[i..]),
        None => time.strip_suffix('Z').map_or((time, ""), |c| (c, "Z")),
    };
    let zone = match zone.len() {
        3 => format!("{zone}:00"),
        5 => format!("{}:{}", &zone[..3], &zone[3..]),
        _ => zone.to_owned(),
    };
    format!("{date}T{clock}{zone}")
}

fn join<T: ToString>(items: &[T]) -> String {
    items.iter().map(ToString::to_string).collect::<Vec<_>>().join(",")
}

/// A field value as text: integers without decimals, reals in Rust's
/// shortest round-trip form, dates ISO 8601, lists comma-separated.
fn text(value: FieldValue) -> String {
    match value {
        FieldValue::IntegerValue(n) => n.to_string(),
        FieldValue::Integer64Value(n) => n.to_string(),
        FieldValue::RealValue(x) => x.to_string(),
        FieldValue::StringValue(s) => s,
        FieldValue::DateValue(d) => d.to_string(),
        FieldValue::DateTimeValue(dt) => {
            format!("{}{}", dt.naive_local().to_string().replacen(' ', "T", 1), dt.offset())
        }
        FieldValue::IntegerListValue(v) => join(&v),
        FieldValue::Integer64ListValue(v) => join(&v),
        FieldValue::RealListValue(v) => join(&v),
        FieldValue::StringListValue(v) => v.join(","),
    }
}

/// One attribute of a feature as text; None when it is null or unset.
/// The gdal crate cannot ask whether a field is set, and OGR gives an
/// unset field as empty text (a missing GeoJSON property, a blank dBase
/// value), so empty text counts as absent, as it does in the shapefile
/// reader.
fn property(feature: &gdal::vector::Feature<'_>, index: usize, ty: OGRFieldType::Type) -> Option<String> {
    let gdal_text = feature.field_as_string(index).ok().flatten().filter(|s| !s.is_empty())?;
    if ty == OGRFieldType::OFTDateTime {
        // GDAL's text keeps fractions of seconds and an unknown time zone
        // unknown; the typed value has neither.
        return Some(iso_datetime(&gdal_text));
    }
    match feature.field(index) {
        Ok(value) => value.map(text),
        // A type the gdal crate does not decode (binary, wide strings):
        // GDAL's own text for it.
        Err(_) => Some(gdal_text),
    }
}

/// Reads every feature of `layer` in one pass. `stable_fids`: the driver
/// keeps FIDs across edits, so they serve as ids; else ids are the read
/// order (counting features without geometry too).
pub(crate) fn read_layer(
    layer: &mut gdal::vector::Layer<'_>,
    stable_fids: bool,
    path: &Path,
) -> Result<LayerRead, SourceError> {
    let fields: Vec<(usize, String, OGRFieldType::Type)> =
        layer.defn().fields().enumerate().map(|(i, f)| (i, f.name(), f.field_type())).collect();
    let mut features = Vec::new();
    let mut null_geometries = 0;
    let mut skipped = BTreeMap::new();
    let mut read = 0u64;
    let mut surfaces = false;
    for (index, feature) in layer.features().enumerate() {
        read += 1;
        // A feature without geometry gives a geometry with no GDAL object.
        let geometry = match feature.geometry().filter(|g| g.has_gdal_ptr()).map(geometry) {
            None | Some(Ok(None)) => {
                null_geometries += 1;
                continue;
            }
            Some(Ok(Some((g, surface)))) => {
                surfaces |= surface;
                g
            }
            Some(Err(reason)) => {
                *skipped.entry(reason).or_insert(0) += 1;
                continue;
            }
        };
        let properties =
            fields.iter().filter_map(|(i, name, ty)| property(&feature, *i, *ty).map(|v| (name.clone(), v))).collect();
        let id = if stable_fids { feature.fid().unwrap_or(index as u64) } else { index as u64 };
        features.push(Feature { id, geometry, properties });
    }
    // OGR ends a read at an error the same way it ends it at the last
    // feature; a count the layer knows cheaply tells the two apart.
    if let Some(expected) = layer.try_feature_count()
        && expected != read
    {
        return Err(SourceError::format(
            format!(
                "layer '{}' ended after {read} of its {expected} features: the file is truncated or corrupt",
                layer.name()
            ),
            path,
        ));
    }
    let fields = fields.into_iter().map(|(_, name, ty)| format!("{name}:{}", field_type_to_name(ty))).collect();
    Ok(LayerRead { features, null_geometries, skipped, fields, surfaces })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gdal_datetimes_become_iso_8601() {
        assert_eq!(iso_datetime("2024/05/01 12:30:00"), "2024-05-01T12:30:00");
        assert_eq!(iso_datetime("2024/05/01 12:30:00.250+02"), "2024-05-01T12:30:00.250+02:00");
        assert_eq!(iso_datetime("2024/05/01 12:30:00-0330"), "2024-05-01T12:30:00-03:30");
        assert_eq!(iso_datetime("2024/05/01 12:30:00+00"), "2024-05-01T12:30:00+00:00");
        assert_eq!(iso_datetime("2024/05/01"), "2024-05-01");
    }

    #[test]
    fn collections_of_one_family_flatten_and_mixed_ones_are_skipped() {
        let g = |wkt: &str| OgrGeometry::from_wkt(wkt).expect("valid WKT");
        assert_eq!(
            geometry(&g("GEOMETRYCOLLECTION (POINT (1 2), MULTIPOINT ((3 4)))")).map(|g| g.map(|g| match g {
                (Geometry::Points(p), false) => p.len(),
                _ => 0,
            })),
            Ok(Some(2))
        );
        assert_eq!(geometry(&g("GEOMETRYCOLLECTION (POINT (1 2), LINESTRING (0 0, 1 1))")), Err("mixed_collection"));
        assert_eq!(geometry(&g("POINT EMPTY")), Ok(None));
        assert_eq!(geometry(&g("CIRCULARSTRING (0 0, 1 1, 2 0)")), Err("curve"));
        let Ok(Some((Geometry::Points(p), _))) = geometry(&g("POINT Z (1 2 3)")) else { panic!("a point") };
        assert_eq!(p, vec![[1.0, 2.0, 3.0]]);
        let Ok(Some((Geometry::Points(p), _))) = geometry(&g("POINT (1 2)")) else { panic!("a point") };
        assert!(p[0][2].is_nan());
        // A MultiPatch as OGR reads it from a geodatabase: a TIN and a
        // polygon with a hole, as four polygons.
        let patch = g("GEOMETRYCOLLECTION Z (TIN Z (((0 0 10,1 0 10,0 1 10,0 0 10)),((1 0 10,1 1 10,0 1 10,1 0 10))),\
                       MULTIPOLYGON Z (((0 0 0,10 0 0,10 10 0,0 0 0),(2 1 0,3 1 0,3 2 0,2 1 0))))");
        let Ok(Some((Geometry::Polygons(p), true))) = geometry(&patch) else { panic!("surfaces") };
        assert_eq!(p.iter().map(Vec::len).collect::<Vec<_>>(), vec![1, 1, 2]);
    }
}
