//! KML that the kml crate refuses but other readers open, read here; and
//! refusals that speak in sentences.

mod fixtures;

use fixtures::{DEBUG_MARKS, document, kmz, names, placemark, read, sample, write};

const POINT: &str = "<coordinates>7,45,10</coordinates>";

#[test]
fn sea_floor_altitude_modes_load_as_ground_modes_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut body = String::new();
    for (name, mode) in [("a", "relativeToSeaFloor"), ("b", "relativeToSeaFloor"), ("c", "clampToSeaFloor")] {
        body += &placemark(name, &format!("<Point><gx:altitudeMode>{mode}</gx:altitudeMode>{POINT}</Point>"));
    }
    body += &placemark(
        "d",
        "<LineString><altitudeMode>relativeToSeaFloor</altitudeMode><coordinates>7,45 8,46</coordinates></LineString>",
    );
    body += &placemark("e", &format!("<Point><gx:altitudeMode>absolute</gx:altitudeMode>{POINT}</Point>"));
    let path = write(dir.path(), "sea.kml", document(&body).as_bytes());

    let read = read(&path).unwrap();
    assert_eq!(read.features.len(), 5);
    assert_eq!(read.details["features"], "5");
    let modes: Vec<&str> = read.features.iter().map(|f| f.properties["altitude_mode"].as_str()).collect();
    assert_eq!(modes, ["relativeToGround", "relativeToGround", "clampToGround", "relativeToGround", "absolute"]);
    assert_eq!(
        read.warnings,
        [
            "altitude mode 'clampToSeaFloor' read as 'clampToGround' in 1 placemark: relief has no sea floor",
            "altitude mode 'relativeToSeaFloor' read as 'relativeToGround' in 3 placemarks: relief has no sea floor",
        ]
    );
}

#[test]
fn an_unknown_altitude_mode_is_read_as_the_default_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let body = placemark("a", &format!("<Point><altitudeMode>onTheMoon</altitudeMode>{POINT}</Point>"));
    let read = read(&write(dir.path(), "moon.kml", document(&body).as_bytes())).unwrap();
    assert_eq!(read.features[0].properties["altitude_mode"], "clampToGround");
    assert_eq!(
        read.warnings,
        ["altitude mode 'onTheMoon' read as 'clampToGround' in 1 placemark: it is not a KML altitude mode"]
    );
}

#[test]
fn html_in_a_description_loads_as_the_descriptions_text() {
    let dir = tempfile::tempdir().unwrap();
    let html = r#"<b>bold</b> <a href="x">link</a><br>&nbsp;"#;
    let body = placemark("a", &format!("<description>{html}</description><Point>{POINT}</Point>"))
        + "<Folder><name>f</name><description><p>folder<br></description>\n"
        + &placemark("b", &format!("<description>plain &amp; simple</description><Point>{POINT}</Point>"))
        + "</Folder>\n";
    let read = read(&write(dir.path(), "html.kml", document(&body).as_bytes())).unwrap();
    assert_eq!(names(&read), ["a", "b"]);
    assert_eq!(read.features[0].properties["description"], html);
    assert_eq!(read.features[1].properties["description"], "plain & simple");
    assert!(read.warnings.is_empty(), "{:?}", read.warnings);
}

/// Guards the message a user once saw for a bare HTML description:
/// `malformed KML: Invalid XML event: Start(BytesStart { buf: Borrowed("b"), name_len: 1 })`.
#[test]
fn no_message_shows_the_kml_crates_debug_output() {
    let dir = tempfile::tempdir().unwrap();
    let body = placemark("a", "<description><b>bold</b></description><Point><coordinates>7,45</coordinates></Point>");
    read(&write(dir.path(), "bold.kml", document(&body).as_bytes())).unwrap();

    // Markup where a value belongs is still refused, in words.
    for (name, inner) in [
        ("extrude.kml", "<Point><extrude><b>1</b></extrude><coordinates>7,45</coordinates></Point>"),
        ("style.kml", "<styleUrl><b>#x</b></styleUrl><Point><coordinates>7,45</coordinates></Point>"),
        ("coordinates.kml", "<Point><coordinates><b>7,45</b></coordinates></Point>"),
        ("number.kml", "<Point><coordinates>7,north</coordinates></Point>"),
    ] {
        let path = write(dir.path(), name, document(&placemark("a", inner)).as_bytes());
        let message = read(&path).unwrap_err().to_string();
        assert!(message.starts_with("malformed KML: "), "{message}");
        assert!(message.ends_with(&path.display().to_string()), "{message}");
        assert_eq!(DEBUG_MARKS.find(&message), None, "{message}");
    }
}

#[test]
fn broken_xml_is_refused_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = sample();
    let cut = &text[..text.find("<Folder><name>inner").unwrap()];
    let path = write(dir.path(), "cut.kml", cut.as_bytes());
    let message = read(&path).unwrap_err().to_string();
    assert!(message.contains("<Folder> opened at line 6 is never closed (the file may be cut short)"), "{message}");

    let body = placemark("a", "<Point><coordinates>7,45</coordinates></LineString>");
    let path = write(dir.path(), "crossed.kml", document(&body).as_bytes());
    let message = read(&path).unwrap_err().to_string();
    assert!(message.contains("<Point> opened at line 4 is closed by </LineString> at line 4"), "{message}");
}

#[test]
fn a_point_without_coordinates_is_left_out_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let body = placemark("empty", "<Point><coordinates> </coordinates></Point>")
        + &placemark("none", "<Point><altitudeMode>absolute</altitudeMode></Point>")
        + &placemark("here", &format!("<Point>{POINT}</Point>"));
    let read = read(&write(dir.path(), "points.kml", document(&body).as_bytes())).unwrap();
    assert_eq!(names(&read), ["here"]);
    assert_eq!(read.details["features"], "3");
    assert_eq!(read.details["without_geometry"], "2");
    assert_eq!(read.warnings, ["2 points without coordinates left out"]);
}

/// Guards a panic the fuzzer found: the kml crate reads the last
/// `coordinates` anywhere inside a Point, and panics when it is empty.
#[test]
fn a_point_whose_last_coordinates_are_empty_is_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let body = placemark(
        "nested",
        "<Point><coordinates>7,45</coordinates><LineString><coordinates></coordinates></LineString></Point>",
    ) + &placemark(
        "inner",
        "<Point><coordinates></coordinates><Point><coordinates>7,45</coordinates></Point></Point>",
    );
    let read = read(&write(dir.path(), "nested.kml", document(&body).as_bytes())).unwrap();
    assert_eq!(names(&read), ["inner"]);
    assert_eq!(read.warnings, ["1 point without coordinates left out"]);
}

#[test]
fn the_sample_reads_from_kml_and_kmz_alike() {
    let dir = tempfile::tempdir().unwrap();
    let text = sample();
    let kml = read(&write(dir.path(), "sample.kml", text.as_bytes())).unwrap();
    let zipped = kmz(&[("doc.kml", text.as_bytes()), ("files/map.png", b"png")]);
    let from_kmz = read(&write(dir.path(), "sample.kmz", &zipped)).unwrap();
    // Debug text, as the missing altitudes (NaN) compare unequal.
    assert_eq!(format!("{:?}", kml.features), format!("{:?}", from_kmz.features));
    assert_eq!(kml.warnings, from_kmz.warnings);
    // Placemarks and the ground overlay; MultiGeometry is a point and a line.
    assert_eq!(kml.details["features"], "6");
    assert_eq!(names(&kml), ["summit", "buoy", "trail", "reef", "both", "both", "map"]);
    assert_eq!(kml.features[0].properties["description"], r#"<b>bold</b> <a href="x">link</a><br>"#);
    assert_eq!(kml.features[2].properties["folder"], "points/inner");
    assert_eq!(kml.features[2].properties["line_color"], "ff0000ff");
    assert_eq!(kml.details["network_links_not_followed"], "http://example.com/more.kml?a=1&b=2");
    assert_eq!(
        kml.warnings,
        [
            "altitude mode 'clampToSeaFloor' read as 'clampToGround' in 1 placemark (and 1 element outside placemarks): relief has no sea floor",
            "altitude mode 'relativeToSeaFloor' read as 'relativeToGround' in 1 placemark: relief has no sea floor",
        ]
    );
}

/// The shared KML files (real ones, from GDAL's and Google's samples) read
/// with the counts `ogrinfo` reports, and nothing to warn about.
#[test]
fn shared_kml_files_read_with_the_counts_ogrinfo_reports() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/kml");
    if !data.exists() {
        eprintln!("skipping: no shared KML data at {}", data.display());
        return;
    }
    for (file, features) in [("kmlsamples.kml", 21), ("all-altitudemodes.kml", 5), ("gnis-ak-first-101.kml", 101)] {
        let read = read(&data.join(file)).unwrap();
        assert_eq!(read.details["features"], features.to_string(), "{file}");
        assert!(read.warnings.is_empty(), "{file}: {:?}", read.warnings);
    }
}

/// The kml crate reads nesting by recursion (a 2 MiB stack overflowed at
/// about 40 folders): nesting up to the limit reads, past it is refused.
#[test]
fn deep_nesting_reads_up_to_the_limit_and_is_refused_past_it() {
    let dir = tempfile::tempdir().unwrap();
    let point = format!("<Point>{POINT}</Point>");
    let nest = |tag: &str, depth: usize, inner: &str| {
        format!("{}{inner}{}", format!("<{tag}>").repeat(depth), format!("</{tag}>").repeat(depth))
    };
    // Under kml and Document; a placemark and its point take two more.
    let depth = 256 - 4;
    for (tag, body) in [
        ("Folder", nest("Folder", depth, &placemark("deep", &point))),
        ("MultiGeometry", placemark("deep", &nest("MultiGeometry", depth - 1, &point))),
        ("ExtendedData", placemark("deep", &(nest("ExtendedData", depth, "") + &point))),
    ] {
        let path = write(dir.path(), "deep.kml", document(&body).as_bytes());
        let deep = read(&path).unwrap_or_else(|e| panic!("{tag}: {e}"));
        assert_eq!(deep.details["features"], "1", "{tag}");
        assert_eq!(deep.features.len(), 1, "{tag}");

        let path = write(dir.path(), "deeper.kml", document(&nest(tag, 300, "")).as_bytes());
        let message = read(&path).unwrap_err().to_string();
        assert!(message.contains("elements nest more than 256 deep at line 4"), "{message}");
    }
}
