//! Shapes and records into relief features (in the file's own CRS), from
//! a dataset's bytes, with or without its attribute table.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Cursor;

use relief_source::{Feature, Geometry, SourceError};
use shapefile::{PolygonRing, Shape, dbase};

use crate::dataset::{Dataset, Part};
use crate::message;

/// What a read found.
pub(crate) struct Read {
    pub features: Vec<Feature>,
    pub null_shapes: usize,
    /// Records marked deleted in the .dbf, left out.
    pub deleted: usize,
    pub shape_types: BTreeMap<String, usize>,
    /// The header says MultiPatch: the features are 3D surfaces.
    pub surfaces: bool,
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
        Shape::NullShape => return None,
        Shape::Multipatch(m) => Geometry::Polygons(crate::multipatch::polygons(m)),
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

fn iso_date(d: &dbase::Date) -> String {
    format!("{:04}-{:02}-{:02}", d.year(), d.month(), d.day())
}

/// A dBase value as text; None for an empty (null) value.
fn text(value: dbase::FieldValue) -> Option<String> {
    use dbase::FieldValue as V;
    match value {
        V::Character(s) => s.map(|s| s.trim().to_owned()),
        V::Memo(s) => Some(s),
        V::Numeric(n) => n.map(|n| n.to_string()),
        V::Float(n) => n.map(|n| n.to_string()),
        V::Integer(n) => Some(n.to_string()),
        V::Double(n) | V::Currency(n) => Some(n.to_string()),
        V::Logical(b) => b.map(|b| b.to_string()),
        V::Date(d) => d.map(|d| iso_date(&d)),
        V::DateTime(dt) => {
            let (date, time) = (dt.date(), dt.time());
            Some(format!("{}T{:02}:{:02}:{:02}", iso_date(&date), time.hours(), time.minutes(), time.seconds()))
        }
    }
}

type Table<'a> = dbase::Reader<Cursor<Cow<'a, [u8]>>>;

/// The attribute table, its text decoded per the .cpg where there is one
/// that names an encoding (and per the .dbf's code page mark otherwise),
/// and its field names.
fn table<'a>(dbf: &'a Part, cpg: Option<&Part>) -> Result<(Table<'a>, Vec<String>), SourceError> {
    let encoding = cpg
        .and_then(|cpg| std::str::from_utf8(&cpg.bytes).ok())
        .and_then(|name| dbase::encoding::DynEncoding::from_name(name.trim()));
    let builder = match encoding {
        Some(encoding) => dbase::ReaderBuilder::new().with_encoding(encoding),
        None => dbase::ReaderBuilder::new(),
    };
    let table = builder
        .build(Cursor::new(with_valid_date(&dbf.bytes)))
        .map_err(|e| SourceError::format(format!("cannot read the .dbf: {}", message::table(&e, &[])), &dbf.path))?;
    let fields = table.fields().iter().map(|f| f.name().to_owned()).collect();
    Ok((table, fields))
}

/// The .dbf with a last-update date the dBase crate accepts. Writers leave
/// it zero or out of range (GDAL reads on regardless); the crate refuses
/// the table for it, and nothing here reads it.
fn with_valid_date(dbf: &[u8]) -> Cow<'_, [u8]> {
    let valid = match dbf.get(1..4) {
        Some(&[_, month, day]) => (1..=12).contains(&month) && (1..=31).contains(&day),
        _ => true,
    };
    if valid {
        return Cow::Borrowed(dbf);
    }
    let mut fixed = dbf.to_vec();
    fixed[1..4].copy_from_slice(&[0, 1, 1]);
    Cow::Owned(fixed)
}

/// Which of the first `records` records are marked deleted ('*'), found
/// where the dBase reader reads them: from the header's offset to the first
/// record, each one flag byte and its fields long. The reader skips them;
/// their shapes are skipped with them, as OGR does, so that every shape
/// keeps its own record.
fn deleted(dbf: &[u8], table: &Table<'_>, records: usize) -> Vec<bool> {
    let first = dbf.get(8..10).and_then(|b| b.try_into().ok()).map_or(0, |b| usize::from(u16::from_le_bytes(b)));
    let record_len = 1 + table.fields().iter().map(|f| usize::from(f.length())).sum::<usize>();
    (0..records).map(|index| dbf.get(first + index * record_len) == Some(&b'*')).collect()
}

/// Reads every shape, each from where `shx` (the dataset's own index or
/// one rebuilt, of `records` entries) says it starts, and its record from
/// the .dbf when there is one.
pub(crate) fn read(dataset: &Dataset, shx: &[u8], records: usize) -> Result<Read, SourceError> {
    let shp = &dataset.shp.path;
    let mut shapes = shapefile::ShapeReader::with_shx(Cursor::new(dataset.shp.bytes.as_slice()), Cursor::new(shx))
        .map_err(|e| SourceError::format(format!("cannot read shapefile: {}", message::shape(&e)), shp))?;
    let (mut table, fields, deleted) = match &dataset.dbf {
        Some(dbf) => {
            let (table, fields) = table(dbf, dataset.cpg.as_ref())?;
            let deleted = deleted(&dbf.bytes, &table, records);
            (Some((dbf, table)), fields, deleted)
        }
        None => (None, Vec::new(), Vec::new()),
    };
    let mut rows = table.as_mut().map(|(dbf, table)| (*dbf, table.iter_records()));
    const MULTIPATCH: i32 = 31;
    let header_type = dataset.shp.bytes.get(32..36).and_then(|b| b.try_into().ok()).map(i32::from_le_bytes);
    let surfaces = header_type == Some(MULTIPATCH);
    let mut read = Read { features: Vec::new(), null_shapes: 0, deleted: 0, shape_types: BTreeMap::new(), surfaces };
    for index in 0..records {
        if deleted.get(index) == Some(&true) {
            read.deleted += 1;
            continue;
        }
        // Each shape is read from its own offset: one that reads short or
        // long leaves the next one where it is.
        let shape = match shapes.read_nth_shape(index) {
            Some(Ok(shape)) => shape,
            Some(Err(e)) => {
                return Err(SourceError::format(format!("cannot read record {index}: {}", message::shape(&e)), shp));
            }
            None => return Err(SourceError::format(format!("record {index} is missing from the index"), shp)),
        };
        let properties = match rows.as_mut() {
            None => BTreeMap::new(),
            Some((dbf, rows)) => match rows.next() {
                Some(Ok(record)) => {
                    record.into_iter().filter_map(|(name, value)| text(value).map(|v| (name, v))).collect()
                }
                Some(Err(e)) => {
                    return Err(SourceError::format(
                        format!("cannot read the .dbf: {}", message::table(&e, &fields)),
                        &dbf.path,
                    ));
                }
                None => return Err(SourceError::format(format!("the .dbf ends before record {index}"), &dbf.path)),
            },
        };
        read.take(index, &shape, properties);
    }
    Ok(read)
}

impl Read {
    /// Counts `shape` and keeps it as feature `index`, unless it is null.
    fn take(&mut self, index: usize, shape: &Shape, properties: BTreeMap<String, String>) {
        *self.shape_types.entry(shape_type(shape).to_owned()).or_insert(0) += 1;
        match geometry(shape) {
            Some(geometry) => self.features.push(Feature { id: index as u64, geometry, properties }),
            None => self.null_shapes += 1,
        }
    }
}
