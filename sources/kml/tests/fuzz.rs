//! Mutated KML and KMZ files (bytes flipped, cut short, tags and text
//! inserted, spans dropped or repeated) read to a value or an error in
//! words: never a panic, never `Debug` output, the path last; what reads
//! is indexed and cut into tiles, without a panic too. Most byte
//! mutations break the XML, so one property edits the document as a writer
//! might get it wrong (elements put in between elements, values replaced):
//! those mostly read, and reach the kml crate and the walk.
//!
//! 256 cases per property (four properties), set in `CASES`.

mod fixtures;

use std::path::Path;

use fixtures::{DEBUG_MARKS, index_and_tile, kmz, read, sample, write};
use proptest::prelude::*;
use proptest::sample::Index;
use relief_testkit::{apply, in_words, mutation};

/// Cases per property.
const CASES: u32 = 256;

/// What the mutations insert: the markup KML files hold, broken halves of
/// it, and the characters XML gives meaning to.
const INSERTS: &[&str] = &[
    "<b>",
    "</b>",
    "<br>",
    "<Placemark>",
    "</Placemark>",
    "<Point>",
    "</Point>",
    "<Point/>",
    "<coordinates>",
    "</coordinates>",
    "<coordinates>1,2</coordinates>",
    "<coordinates></coordinates>",
    "<LineString><coordinates>1,2 3</coordinates></LineString>",
    "<Polygon><outerBoundaryIs></outerBoundaryIs></Polygon>",
    "<MultiGeometry>",
    "<Folder>",
    "</Folder>",
    "</Document>",
    "<Document>",
    "<description>",
    "</description>",
    "<name>",
    "<altitudeMode>",
    "<gx:altitudeMode>clampToSeaFloor</gx:altitudeMode>",
    "<altitudeMode>nowhere</altitudeMode>",
    "<SimpleData>x</SimpleData>",
    "<Style id=\"s\"><LineStyle><width>wide</width></LineStyle></Style>",
    "<colorMode>odd</colorMode>",
    "<![CDATA[",
    "]]>",
    "<!--",
    "-->",
    "<!DOCTYPE kml>",
    "<?pi x?>",
    "&",
    "&nbsp;",
    "&#xD800;",
    "<",
    ">",
    "\"",
    ",",
    " ",
    "\n",
    "é",
];

/// Elements a writer might put anywhere between two others.
const ELEMENTS: &[&str] = &[
    "<Placemark><Point><coordinates>1,2</coordinates></Point></Placemark>",
    "<Placemark><name>n</name></Placemark>",
    "<Point><coordinates>1,2,3</coordinates></Point>",
    "<Point><coordinates> </coordinates></Point>",
    "<Point></Point>",
    "<Point/>",
    "<LineString><coordinates>1,2 3,4</coordinates></LineString>",
    "<LineString></LineString>",
    "<LineString><coordinates></coordinates></LineString>",
    "<LinearRing><coordinates>1,2 3,4 1,2</coordinates></LinearRing>",
    "<Polygon><outerBoundaryIs><LinearRing><coordinates>1,2 3,4 5,2 1,2</coordinates></LinearRing></outerBoundaryIs></Polygon>",
    "<Polygon><outerBoundaryIs></outerBoundaryIs></Polygon>",
    "<Polygon><innerBoundaryIs><LinearRing/></innerBoundaryIs></Polygon>",
    "<MultiGeometry><Point><coordinates>1,2</coordinates></Point><MultiGeometry/></MultiGeometry>",
    "<gx:altitudeMode>relativeToSeaFloor</gx:altitudeMode>",
    "<altitudeMode>clampToSeaFloor</altitudeMode>",
    "<altitudeMode><!-- x -->absolute</altitudeMode>",
    "<altitudeMode></altitudeMode>",
    "<extrude>1</extrude>",
    "<description><p>a<br>b &nbsp; <i>c</p></description>",
    "<description><![CDATA[<b>x</b>]]> and <b>y</b></description>",
    "<name>a &amp; b <!-- c --></name>",
    "<styleUrl>#red</styleUrl>",
    "<styleUrl>#nowhere</styleUrl>",
    "<Style><LineStyle><width>2</width></LineStyle></Style>",
    "<Style id=\"s\"><PolyStyle><fill>0</fill></PolyStyle><IconStyle><scale>x</scale></IconStyle></Style>",
    "<StyleMap><Pair><key>k</key></Pair></StyleMap>",
    "<ExtendedData><SchemaData><SimpleData name=\"a\">1</SimpleData></SchemaData></ExtendedData>",
    "<SimpleData>1</SimpleData>",
    "<Folder><Folder><Document/></Folder></Folder>",
    "<Folder><name>f</name>",
    "</Folder>",
    "<Document>",
    "</Document>",
    "<GroundOverlay><LatLonBox><north>1</north></LatLonBox></GroundOverlay>",
    "<NetworkLink/>",
    "<Location><longitude>x</longitude></Location>",
    "<Scale><x>1</x></Scale>",
    "<gx:Track><gx:coord>1 2 3</gx:coord></gx:Track>",
    "<Model><Link><href>m.dae</href></Link></Model>",
    "text",
    "&amp;",
    "& ",
    "<!-- comment -->",
    "<![CDATA[ data ]]>",
    "<?pi x?>",
];

/// Values a writer might get wrong.
const VALUES: &[&str] = &[
    "",
    " ",
    "abc",
    "1",
    "1,2",
    "1,2,3,4",
    "1,,2",
    "nan,inf",
    "-1e400,1e400",
    "1 , 2",
    "relativeToSeaFloor",
    "clampToSeaFloor",
    "onTheMoon",
    "&amp;",
    "&nbsp;",
    "a & b",
    "<b>x</b>",
    "<br>",
    "<![CDATA[<i>]]>",
    "#",
    "ÿ",
];

#[derive(Debug, Clone)]
enum Edit {
    /// An element from `ELEMENTS` put in before a tag.
    Put(Index, Index),
    /// A value (text between two tags) replaced by one from `VALUES`.
    Value(Index, Index),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<Index>(), any::<Index>()).prop_map(|(at, what)| Edit::Put(at, what)),
        (any::<Index>(), any::<Index>()).prop_map(|(at, what)| Edit::Value(at, what)),
    ]
}

fn apply_edits(text: &mut String, edits: &[Edit]) {
    for e in edits {
        match e {
            Edit::Put(at, what) => {
                let tags: Vec<usize> = text.match_indices('<').map(|(i, _)| i).collect();
                let at = tags[at.index(tags.len())];
                text.insert_str(at, ELEMENTS[what.index(ELEMENTS.len())]);
            }
            Edit::Value(at, what) => {
                let values: Vec<(usize, usize)> = text
                    .match_indices('>')
                    .filter_map(|(i, _)| text[i + 1..].find('<').map(|n| (i + 1, i + 1 + n)))
                    .filter(|(start, end)| end > start)
                    .collect();
                if values.is_empty() {
                    continue;
                }
                let (start, end) = values[at.index(values.len())];
                text.replace_range(start..end, VALUES[what.index(VALUES.len())]);
            }
        }
    }
}

/// Reads `bytes` as the file `name`: a value, or an error in words that
/// ends with the path.
fn reads_or_fails_in_words(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = write(dir.path(), name, bytes);
    match read(&path) {
        Ok(read) => {
            for warning in &read.warnings {
                prop_assert_eq!(DEBUG_MARKS.find(warning), None, "warning: {}", warning);
            }
            // On to the index and the tiles, which must not panic either.
            index_and_tile(read).expect("no CRS transform to fail");
        }
        Err(e) => check_message(&e.to_string(), &path)?,
    }
    Ok(())
}

fn check_message(message: &str, path: &Path) -> Result<(), TestCaseError> {
    in_words(message, DEBUG_MARKS.find(message), path)?;
    // The reader's last resort (a parse that panicked) never fires.
    prop_assert!(!message.contains("a bug in relief"), "{}", message);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn mutated_kml_reads_or_fails_in_words(mutations in prop::collection::vec(mutation(INSERTS), 1..5)) {
        let mut bytes = sample().into_bytes();
        apply(&mut bytes, &mutations);
        reads_or_fails_in_words("mutated.kml", &bytes)?;
    }

    #[test]
    fn miswritten_kml_reads_or_fails_in_words(edits in prop::collection::vec(edit(), 1..6)) {
        let mut text = sample();
        apply_edits(&mut text, &edits);
        reads_or_fails_in_words("miswritten.kml", text.as_bytes())?;
    }

    #[test]
    fn a_kmz_of_mutated_kml_reads_or_fails_in_words(mutations in prop::collection::vec(mutation(INSERTS), 1..5)) {
        let mut bytes = sample().into_bytes();
        apply(&mut bytes, &mutations);
        reads_or_fails_in_words("mutated-doc.kmz", &kmz(&[("doc.kml", &bytes), ("files/map.png", b"png")]))?;
    }

    #[test]
    fn mutated_kmz_bytes_read_or_fail_in_words(mutations in prop::collection::vec(mutation(INSERTS), 1..4)) {
        let mut bytes = kmz(&[("doc.kml", sample().as_bytes()), ("files/map.png", b"png")]);
        apply(&mut bytes, &mutations);
        reads_or_fails_in_words("mutated.kmz", &bytes)?;
    }
}
