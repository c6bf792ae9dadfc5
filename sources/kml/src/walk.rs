//! The kml tree into features (WGS84 longitude, latitude, altitude).

use std::collections::{BTreeMap, HashMap};

use kml::Kml;
use kml::types::{AltitudeMode, Element, Geometry as KmlGeometry};
use relief_source::{Feature, Geometry};

/// What a walk found.
#[derive(Default)]
pub(crate) struct Found {
    pub features: Vec<Feature>,
    /// Placemarks and ground overlays, as GDAL's LIBKML driver counts them.
    pub counted: usize,
    pub without_geometry: usize,
    pub network_links: Vec<String>,
}

/// Default styling from a `<Style>`: KML colours are aabbggrr.
#[derive(Debug, Clone, Default)]
struct StyleProps(BTreeMap<String, String>);

fn styles(kml: &Kml, out: &mut HashMap<String, StyleProps>) {
    match kml {
        Kml::Style(s) => {
            let mut props = BTreeMap::new();
            if let Some(line) = &s.line {
                props.insert("line_color".into(), line.color.clone());
                props.insert("line_width".into(), line.width.to_string());
            }
            if let Some(poly) = &s.poly {
                props.insert("fill_color".into(), poly.color.clone());
                props.insert("fill".into(), poly.fill.to_string());
                props.insert("outline".into(), poly.outline.to_string());
            }
            if let Some(id) = &s.id {
                out.insert(format!("#{id}"), StyleProps(props));
            }
        }
        Kml::KmlDocument(d) => d.elements.iter().for_each(|k| styles(k, out)),
        Kml::Document { elements, .. } => elements.iter().for_each(|k| styles(k, out)),
        Kml::Folder(f) => f.elements.iter().for_each(|k| styles(k, out)),
        _ => {}
    }
}

fn mode(m: AltitudeMode) -> &'static str {
    match m {
        AltitudeMode::ClampToGround => "clampToGround",
        AltitudeMode::RelativeToGround => "relativeToGround",
        AltitudeMode::Absolute => "absolute",
    }
}

fn xyz(c: &kml::types::Coord) -> [f64; 3] {
    [c.x, c.y, c.z.unwrap_or(f64::NAN)]
}

/// Splits a geometry into relief's three kinds, noting altitude mode and
/// extrude of the last part that states them.
fn collect(
    g: &KmlGeometry,
    points: &mut Vec<[f64; 3]>,
    lines: &mut Vec<Vec<[f64; 3]>>,
    polygons: &mut Vec<Vec<Vec<[f64; 3]>>>,
    props: &mut BTreeMap<String, String>,
) {
    let mut note = |m: AltitudeMode, extrude: bool| {
        props.insert("altitude_mode".into(), mode(m).into());
        props.insert("extrude".into(), extrude.to_string());
    };
    match g {
        KmlGeometry::Point(p) => {
            note(p.altitude_mode, p.extrude);
            points.push(xyz(&p.coord));
        }
        KmlGeometry::LineString(l) => {
            note(l.altitude_mode, l.extrude);
            lines.push(l.coords.iter().map(xyz).collect());
        }
        KmlGeometry::LinearRing(r) => {
            note(r.altitude_mode, r.extrude);
            lines.push(r.coords.iter().map(xyz).collect());
        }
        KmlGeometry::Polygon(p) => {
            note(p.altitude_mode, p.extrude);
            let mut rings = vec![p.outer.coords.iter().map(xyz).collect::<Vec<_>>()];
            rings.extend(p.inner.iter().map(|r| r.coords.iter().map(xyz).collect()));
            polygons.push(rings);
        }
        KmlGeometry::MultiGeometry(m) => m.geometries.iter().for_each(|g| collect(g, points, lines, polygons, props)),
        // Models (an Element to the kml crate) are not drawn as features.
        _ => {}
    }
}

fn child<'a>(e: &'a Element, name: &str) -> Option<&'a Element> {
    e.children.iter().find(|c| c.name == name)
}

pub(crate) fn walk(root: &Kml, text: &str) -> Found {
    let mut style_map = HashMap::new();
    styles(root, &mut style_map);
    let mut found = Found::default();
    visit(root, "", &style_map, &mut found);
    ground_overlays(text, &mut found);
    found
}

/// Ground overlays, found in the text: the kml crate drops them inside
/// folders. Each is a feature (as GDAL's LIBKML driver counts them), its
/// geometry the LatLonBox.
fn ground_overlays(text: &str, found: &mut Found) {
    let value = |body: &str, tag: &str| -> Option<String> {
        let open = format!("<{tag}>");
        let start = body.find(&open)? + open.len();
        let len = body[start..].find(&format!("</{tag}>"))?;
        Some(body[start..start + len].trim().to_owned())
    };
    let mut rest = text;
    while let Some(start) = rest.find("<GroundOverlay") {
        let Some(len) = rest[start..].find("</GroundOverlay>") else { break };
        let body = &rest[start..start + len];
        rest = &rest[start + len..];
        let id = found.counted as u64;
        found.counted += 1;
        let n = |tag| value(body, tag).and_then(|v| v.parse::<f64>().ok());
        let Some((w, s, e, north)) =
            n("west").zip(n("south")).zip(n("east")).zip(n("north")).map(|(((w, s), e), n)| (w, s, e, n))
        else {
            found.without_geometry += 1;
            continue;
        };
        let mut props = BTreeMap::new();
        props.insert("kind".into(), "GroundOverlay".into());
        if let Some(name) = value(body, "name") {
            props.insert("name".into(), name);
        }
        let ring =
            vec![[w, s, f64::NAN], [e, s, f64::NAN], [e, north, f64::NAN], [w, north, f64::NAN], [w, s, f64::NAN]];
        found.features.push(Feature { id, geometry: Geometry::Polygons(vec![vec![ring]]), properties: props });
    }
}

fn visit(kml: &Kml, folder: &str, style_map: &HashMap<String, StyleProps>, found: &mut Found) {
    match kml {
        Kml::KmlDocument(d) => d.elements.iter().for_each(|k| visit(k, folder, style_map, found)),
        Kml::Document { elements, .. } => elements.iter().for_each(|k| visit(k, folder, style_map, found)),
        Kml::Folder(f) => {
            let name = f.name.clone().unwrap_or_default();
            let path = if folder.is_empty() { name } else { format!("{folder}/{name}") };
            f.elements.iter().for_each(|k| visit(k, &path, style_map, found));
        }
        Kml::Placemark(p) => {
            let id = found.counted as u64;
            found.counted += 1;
            let mut props = BTreeMap::new();
            if let Some(url) = &p.style_url {
                if let Some(style) = style_map.get(url) {
                    props.extend(style.0.clone());
                }
                props.insert("style_url".into(), url.clone());
            }
            for (k, v) in [("name", &p.name), ("description", &p.description)] {
                if let Some(v) = v {
                    props.insert(k.into(), v.trim().to_owned());
                }
            }
            if !folder.is_empty() {
                props.insert("folder".into(), folder.to_owned());
            }
            let (mut points, mut lines, mut polygons) = (Vec::new(), Vec::new(), Vec::new());
            if let Some(g) = &p.geometry {
                collect(g, &mut points, &mut lines, &mut polygons, &mut props);
            }
            let parts = [
                (!points.is_empty()).then_some(Geometry::Points(points)),
                (!lines.is_empty()).then_some(Geometry::Lines(lines)),
                (!polygons.is_empty()).then_some(Geometry::Polygons(polygons)),
            ];
            let mut any = false;
            for geometry in parts.into_iter().flatten() {
                any = true;
                found.features.push(Feature { id, geometry, properties: props.clone() });
            }
            if !any {
                found.without_geometry += 1;
            }
        }
        Kml::Element(e) if e.name == "NetworkLink" => {
            let href = child(e, "Link")
                .or_else(|| child(e, "Url"))
                .and_then(|l| child(l, "href"))
                .and_then(|h| h.content.clone());
            found.network_links.push(href.unwrap_or_else(|| "(no href)".into()).trim().to_owned());
        }
        Kml::Element(e) if e.name == "Document" || e.name == "Folder" => {
            // Containers the kml crate did not type: nothing of ours inside is typed either.
            let _ = e;
        }
        _ => {}
    }
}
