//! Shapes and records into relief features (in the file's own CRS).

use std::collections::BTreeMap;
use std::path::Path;

use relief_source::{Feature, Geometry, SourceError};
use shapefile::{PolygonRing, Shape};

/// What a read found.
pub(crate) struct Read {
    pub features: Vec<Feature>,
    pub null_shapes: usize,
    pub shape_types: BTreeMap<String, usize>,
}

trait Xyz {
    fn xyz(&self) -> [f64; 3];
}

impl Xyz for shapefile::Point {
    fn xyz(&self) -> [f64; 3] {
        [self.x, self.y, f64::NAN]
    }
}

impl Xyz for shapefile::PointM {
    fn xyz(&self) -> [f64; 3] {
        [self.x, self.y, f64::NAN]
    }
}

impl Xyz for shapefile::PointZ {
    fn xyz(&self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }
}

fn points<P: Xyz>(ps: &[P]) -> Vec<[f64; 3]> {
    ps.iter().map(Xyz::xyz).collect()
}

/// Each outer ring starts a polygon; the inner rings after it are its holes.
fn polygons<P: Xyz>(rings: &[PolygonRing<P>]) -> Vec<Vec<Vec<[f64; 3]>>> {
    let mut out: Vec<Vec<Vec<[f64; 3]>>> = Vec::new();
    for ring in rings {
        match ring {
            PolygonRing::Outer(ps) => out.push(vec![points(ps)]),
            PolygonRing::Inner(ps) => match out.last_mut() {
                Some(polygon) => polygon.push(points(ps)),
                // A hole before any outer ring: keep it as its own polygon
                // rather than lose it.
                None => out.push(vec![points(ps)]),
            },
        }
    }
    out
}

fn geometry(shape: &Shape) -> Option<Geometry> {
    Some(match shape {
        Shape::NullShape | Shape::Multipatch(_) => return None,
        Shape::Point(p) => Geometry::Points(vec![p.xyz()]),
        Shape::PointM(p) => Geometry::Points(vec![p.xyz()]),
        Shape::PointZ(p) => Geometry::Points(vec![p.xyz()]),
        Shape::Multipoint(m) => Geometry::Points(points(m.points())),
        Shape::MultipointM(m) => Geometry::Points(points(m.points())),
        Shape::MultipointZ(m) => Geometry::Points(points(m.points())),
        Shape::Polyline(l) => Geometry::Lines(l.parts().iter().map(|p| points(p)).collect()),
        Shape::PolylineM(l) => Geometry::Lines(l.parts().iter().map(|p| points(p)).collect()),
        Shape::PolylineZ(l) => Geometry::Lines(l.parts().iter().map(|p| points(p)).collect()),
        Shape::Polygon(p) => Geometry::Polygons(polygons(p.rings())),
        Shape::PolygonM(p) => Geometry::Polygons(polygons(p.rings())),
        Shape::PolygonZ(p) => Geometry::Polygons(polygons(p.rings())),
    })
}

fn shape_type(shape: &Shape) -> &'static str {
    match shape {
        Shape::NullShape => "null",
        Shape::Point(_) => "point",
        Shape::PointM(_) => "point m",
        Shape::PointZ(_) => "point z",
        Shape::Multipoint(_) => "multipoint",
        Shape::MultipointM(_) => "multipoint m",
        Shape::MultipointZ(_) => "multipoint z",
        Shape::Polyline(_) => "polyline",
        Shape::PolylineM(_) => "polyline m",
        Shape::PolylineZ(_) => "polyline z",
        Shape::Polygon(_) => "polygon",
        Shape::PolygonM(_) => "polygon m",
        Shape::PolygonZ(_) => "polygon z",
        Shape::Multipatch(_) => "multipatch",
    }
}

/// A dBase value as text; None for an empty (null) value.
fn text(value: shapefile::dbase::FieldValue) -> Option<String> {
    use shapefile::dbase::FieldValue as V;
    match value {
        V::Character(s) => s.map(|s| s.trim().to_owned()),
        V::Memo(s) => Some(s),
        V::Numeric(n) => n.map(|n| n.to_string()),
        V::Float(n) => n.map(|n| n.to_string()),
        V::Integer(n) => Some(n.to_string()),
        V::Double(n) | V::Currency(n) => Some(n.to_string()),
        V::Logical(b) => b.map(|b| b.to_string()),
        V::Date(d) => d.map(|d| format!("{:04}-{:02}-{:02}", d.year(), d.month(), d.day())),
        V::DateTime(dt) => Some(format!("{dt:?}")),
    }
}

/// Reads every shape and record. Attributes are decoded per the .cpg.
pub(crate) fn read(shp: &Path) -> Result<Read, SourceError> {
    let err = |e: shapefile::Error| SourceError::format(format!("cannot read shapefile: {e}"), shp);
    let mut reader = shapefile::Reader::from_path(shp).map_err(err)?;
    let mut features = Vec::new();
    let mut null_shapes = 0;
    let mut shape_types = BTreeMap::new();
    for (index, item) in reader.iter_shapes_and_records().enumerate() {
        let (shape, record) = item.map_err(|e| SourceError::format(format!("cannot read record {index}: {e}"), shp))?;
        *shape_types.entry(shape_type(&shape).to_owned()).or_insert(0) += 1;
        if let Shape::Multipatch(_) = shape {
            return Err(SourceError::format(
                format!(
                    "record {index} is a MultiPatch (3D surfaces), which relief does not read; export it as PolygonZ"
                ),
                shp,
            ));
        }
        let Some(geometry) = geometry(&shape) else {
            null_shapes += 1;
            continue;
        };
        let properties = record.into_iter().filter_map(|(name, value)| text(value).map(|v| (name, v))).collect();
        features.push(Feature { id: index as u64, geometry, properties });
    }
    Ok(Read { features, null_shapes, shape_types })
}
