//! Scene files are untrusted input to GDAL (issue "security", finding 2):
//! VRTs generated with raw bands, nested VRTs, `/vsi` paths, relative
//! paths climbing out and links out of the folder, and web-service XML
//! (`GDAL_WMS`, `GDAL_WMTS`, `WCS_GDAL`), each handed to `reliefd check`
//! and to a serving reliefd. No byte of the secret outside the scene's
//! folders reaches an answer (its heights are 4242.5 m, which no answer
//! may hold), and no network request is made: a listening socket in the
//! test counts every connection, and must count none.

#![allow(clippy::unwrap_used, reason = "a test")]

use std::fmt::Write as _;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use relief_tests::daemon::{Reliefd, check};
use relief_tests::fixtures::{self, Lcg, RasterSpec};
use relief_tests::http::{get, request};

/// The secret's height everywhere: no answer may hold it.
const SECRET_M: f32 = 4242.5;

/// A socket on loopback that counts the connections made to it.
struct Listener {
    port: u16,
    connections: Arc<AtomicUsize>,
    stop: Arc<AtomicBool>,
}

impl Listener {
    fn start() -> Self {
        let socket = TcpListener::bind("127.0.0.1:0").unwrap();
        socket.set_nonblocking(true).unwrap();
        let port = socket.local_addr().unwrap().port();
        let (connections, stop) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicBool::new(false)));
        let (counted, stopping) = (Arc::clone(&connections), Arc::clone(&stop));
        let _ = std::thread::Builder::new().name("listener".into()).spawn(move || {
            while !stopping.load(Ordering::Relaxed) {
                match socket.accept() {
                    Ok(_) => {
                        counted.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(_) => std::thread::sleep(std::time::Duration::from_millis(5)),
                }
            }
        });
        Self { port, connections, stop }
    }

    fn connections(&self) -> usize {
        self.connections.load(Ordering::Relaxed)
    }
}

impl Drop for Listener {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// The scene's folder (with the hill in `tiles/`) and, beside it, a
/// secret raster and the same heights as raw bytes.
struct Layout {
    _dir: tempfile::TempDir,
    scene: PathBuf,
    secret_tif: PathBuf,
    secret_raw: PathBuf,
}

fn layout() -> Layout {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let outside = dir.path().join("outside");
    std::fs::create_dir_all(scene.join("tiles")).unwrap();
    std::fs::create_dir_all(&outside).unwrap();
    fixtures::write_dem(&scene.join("tiles/hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let spec = RasterSpec { width: 40, height: 40, ..fixtures::hill_spec() };
    let secret_tif = fixtures::write_dem(&outside.join("secret.tif"), &spec, |_, _| f64::from(SECRET_M)).unwrap();
    let secret_raw = outside.join("secret.raw");
    let bytes: Vec<u8> = std::iter::repeat_n(SECRET_M.to_le_bytes(), 40 * 40).flatten().collect();
    std::fs::write(&secret_raw, bytes).unwrap();
    Layout { _dir: dir, scene, secret_tif, secret_raw }
}

/// The frame of a VRT over the hill's extent (10..10.5 E, 45..45.5 N).
const FRAME: &str = "<SRS>EPSG:4326</SRS><GeoTransform>10, 0.0125, 0, 45.5, 0, -0.0125</GeoTransform>";

/// A VRT of 40 x 40 Float32 pixels over the hill whose band reads `name`
/// through `wrapper`.
fn vrt(wrapper: usize, name: &str, relative: bool) -> String {
    let rel = u8::from(relative);
    let file = format!("<SourceFilename relativeToVRT=\"{rel}\">{name}</SourceFilename>");
    // The hill's 400 x 400 pixels onto the VRT's 40 x 40.
    let rects = "<SrcRect xOff=\"0\" yOff=\"0\" xSize=\"400\" ySize=\"400\"/><DstRect xOff=\"0\" yOff=\"0\" xSize=\"40\" ySize=\"40\"/>";
    let simple = |kind: &str| format!("<{kind}>{file}<SourceBand>1</SourceBand>{rects}</{kind}>");
    let band = |inner: &str| format!("<VRTRasterBand dataType=\"Float32\" band=\"1\">{inner}</VRTRasterBand>");
    let body = match wrapper {
        0 => band(&simple("SimpleSource")),
        1 => band(&simple("ComplexSource")),
        2 => band(&simple("AveragedSource")),
        3 => format!(
            "<VRTRasterBand dataType=\"Float32\" band=\"1\" subClass=\"VRTRawRasterBand\">{file}\
             <ImageOffset>0</ImageOffset><PixelOffset>4</PixelOffset><LineOffset>160</LineOffset>\
             <ByteOrder>LSB</ByteOrder></VRTRasterBand>"
        ),
        4 => band(&format!("<Overview>{file}<SourceBand>1</SourceBand></Overview>")),
        5 => band(&format!(
            "<MaskBand><VRTRasterBand dataType=\"Byte\">{}</VRTRasterBand></MaskBand>",
            simple("SimpleSource")
        )),
        _ => {
            return format!(
                "<VRTDataset rasterXSize=\"40\" rasterYSize=\"40\" subClass=\"VRTWarpedDataset\">{FRAME}\
                 <VRTRasterBand dataType=\"Float32\" band=\"1\" subClass=\"VRTWarpedRasterBand\"/>\
                 <GDALWarpOptions><WorkingDataType>Float32</WorkingDataType>\
                 <SourceDataset relativeToVRT=\"{rel}\">{name}</SourceDataset>\
                 <BandList><BandMapping src=\"1\" dst=\"1\"/></BandList></GDALWarpOptions></VRTDataset>"
            );
        }
    };
    format!("<VRTDataset rasterXSize=\"40\" rasterYSize=\"40\">{FRAME}{body}</VRTDataset>")
}

/// The hostile names a VRT may hold: (name, relative to the VRT).
fn hostile_names(l: &Layout, port: u16, link: &Path) -> Vec<(String, bool)> {
    let (tif, raw) = (l.secret_tif.display().to_string(), l.secret_raw.display().to_string());
    let outside = l.secret_tif.parent().unwrap().display().to_string();
    vec![
        ("../outside/secret.tif".into(), true),
        ("tiles/../../outside/secret.tif".into(), true),
        (format!("../../../../../../../..{tif}"), true),
        (tif.clone(), false),
        (link.display().to_string(), false),
        (raw.clone(), false),
        (format!("/vsicurl/http://127.0.0.1:{port}/secret.tif"), false),
        (format!("/vsicurl_streaming/http://127.0.0.1:{port}/secret.tif"), false),
        (format!("http://127.0.0.1:{port}/secret.tif"), false),
        (format!("vrt://{tif}"), false),
        (format!("/vsizip/{outside}/secret.zip/secret.tif"), false),
        (format!("/vsisubfile/0_6400,{raw}"), false),
        (format!("/vsitar/{{{outside}/secret.tar}}/secret.tif"), false),
        ("/vsis3/bucket/secret.tif".into(), false),
        ("/vsimem/secret.tif".into(), false),
        (format!("GTiff:{tif}"), false),
    ]
}

/// Web-service XML and code: (file name, text).
fn services(port: u16) -> Vec<(&'static str, String)> {
    vec![
        (
            "wms.xml",
            format!(
                "<GDAL_WMS><Service name=\"TMS\"><ServerUrl>http://127.0.0.1:{port}/${{z}}/${{x}}/${{y}}.png</ServerUrl>\
                 </Service><DataWindow><UpperLeftX>10</UpperLeftX><UpperLeftY>45.5</UpperLeftY><LowerRightX>10.5</LowerRightX>\
                 <LowerRightY>45</LowerRightY><TileLevel>1</TileLevel><TileCountX>1</TileCountX><TileCountY>1</TileCountY>\
                 </DataWindow><Projection>EPSG:4326</Projection><BlockSizeX>256</BlockSizeX><BlockSizeY>256</BlockSizeY>\
                 <BandsCount>1</BandsCount></GDAL_WMS>"
            ),
        ),
        (
            "wmts.xml",
            format!("<GDAL_WMTS><GetCapabilitiesUrl>http://127.0.0.1:{port}/wmts</GetCapabilitiesUrl></GDAL_WMTS>"),
        ),
        (
            "wcs.xml",
            format!(
                "<WCS_GDAL><ServiceURL>http://127.0.0.1:{port}/wcs</ServiceURL><CoverageName>x</CoverageName></WCS_GDAL>"
            ),
        ),
        (
            "python.vrt",
            format!(
                "<VRTDataset rasterXSize=\"40\" rasterYSize=\"40\">{FRAME}<VRTRasterBand dataType=\"Float32\" band=\"1\" \
                 subClass=\"VRTDerivedRasterBand\"><PixelFunctionType>leak</PixelFunctionType>\
                 <PixelFunctionLanguage>Python</PixelFunctionLanguage><PixelFunctionCode><![CDATA[\
                 import urllib.request\ndef leak(*a, **k): urllib.request.urlopen('http://127.0.0.1:{port}/')]]>\
                 </PixelFunctionCode><SimpleSource><SourceFilename relativeToVRT=\"1\">tiles/hill.tif</SourceFilename>\
                 </SimpleSource></VRTRasterBand></VRTDataset>"
            ),
        ),
    ]
}

fn manifest(scene: &Path, sources: &[(&str, &str)]) -> PathBuf {
    let mut text = String::from("[scene]\nname = \"hostile\"\n\n");
    for (id, file) in sources {
        let _ = write!(text, "[[source]]\nid = \"{id}\"\nkind = \"gdal\"\npath = \"{file}\"\n\n");
    }
    let _ = write!(text, "[layers]\nheight = \"{}\"\n", sources[0].0);
    fixtures::write_manifest(scene, &text).unwrap()
}

/// Hostile VRTs, generated (a wrapper, a name, nested 0 to 2 deep inside
/// the folder), and service XML: `reliefd check` refuses each, naming the
/// file, without a byte of the secret and without a connection.
#[test]
fn generated_hostile_scene_files_are_refused_without_reading_out_or_calling_out() {
    let l = layout();
    let listener = Listener::start();
    let link = l.scene.join("tiles/link.tif");
    std::os::unix::fs::symlink(&l.secret_tif, &link).unwrap();
    let names = hostile_names(&l, listener.port, &link);
    let mut rng = Lcg(0x5eed);
    let mut cases: Vec<(String, String)> = Vec::new();
    // Every name once, then random wrappers and nesting.
    for n in 0..names.len() + 40 {
        let (name, relative) = &names[n % names.len()];
        let wrapper = (rng.next_f64() * 7.0) as usize;
        let depth = (rng.next_f64() * 3.0) as usize;
        let mut file = format!("case{n}.vrt");
        std::fs::write(l.scene.join(&file), vrt(wrapper, name, *relative)).unwrap();
        for d in 0..depth {
            let outer = format!("case{n}-outer{d}.vrt");
            let via = (rng.next_f64() * 3.0) as usize;
            std::fs::write(l.scene.join(&outer), vrt(via, &file, true)).unwrap();
            file = outer;
        }
        cases.push((file, format!("{name} in wrapper {wrapper}, {depth} deep")));
    }
    for (file, text) in services(listener.port) {
        std::fs::write(l.scene.join(file), text).unwrap();
        cases.push((file.to_owned(), file.to_owned()));
    }
    for (file, what) in &cases {
        let (code, stderr) = check(&manifest(&l.scene, &[("dem", file)])).unwrap();
        assert_ne!(code, 0, "{what}: reliefd check passed\n{stderr}");
        assert!(stderr.contains(file.as_str()), "{what}: the error does not name {file}\n{stderr}");
        assert!(!stderr.contains("4242"), "{what}: the secret reached the error\n{stderr}");
        assert!(!stderr.contains("panicked"), "{what}\n{stderr}");
    }
    assert_eq!(listener.connections(), 0, "reliefd called out");
    // The same files inside the folder, and a root declared, pass.
    std::fs::write(l.scene.join("good.vrt"), vrt(1, "tiles/hill.tif", true)).unwrap();
    let (code, stderr) = check(&manifest(&l.scene, &[("dem", "good.vrt")])).unwrap();
    assert_eq!(code, 0, "{stderr}");
    // The drivers refused are only those this GDAL has: no warning of the others.
    assert!(!stderr.contains("GDAL_SKIP"), "GDAL warned of its skip list: {stderr}");
    std::fs::write(l.scene.join("rooted.vrt"), vrt(0, "../outside/secret.tif", true)).unwrap();
    let rooted = manifest(&l.scene, &[("dem", "rooted.vrt")]);
    let text = std::fs::read_to_string(&rooted).unwrap().replace("[scene]\n", "[scene]\nroots = [\"../outside\"]\n");
    std::fs::write(&rooted, text).unwrap();
    let (code, stderr) = check(&rooted).unwrap();
    assert_eq!(code, 0, "a declared root: {stderr}");
}

/// A serving reliefd: hostile sources fail (named in the state), their
/// elevations are errors, and a good VRT turned hostile by an edit keeps
/// its last good heights; no answer holds the secret, nothing calls out.
#[test]
fn a_serving_reliefd_answers_nothing_of_hostile_files() {
    let l = layout();
    let listener = Listener::start();
    let link = l.scene.join("tiles/link.tif");
    std::os::unix::fs::symlink(&l.secret_tif, &link).unwrap();
    let mut sources = vec![("dem".to_owned(), "dem.vrt".to_owned())];
    std::fs::write(l.scene.join("dem.vrt"), vrt(0, "tiles/hill.tif", true)).unwrap();
    for (n, (name, relative)) in hostile_names(&l, listener.port, &link).iter().enumerate() {
        let file = format!("h{n}.vrt");
        std::fs::write(l.scene.join(&file), vrt(n % 7, name, *relative)).unwrap();
        sources.push((format!("h{n}"), file));
    }
    for (n, (file, text)) in services(listener.port).into_iter().enumerate() {
        std::fs::write(l.scene.join(file), text).unwrap();
        sources.push((format!("s{n}"), file.to_owned()));
    }
    let listed: Vec<(&str, &str)> = sources.iter().map(|(i, f)| (i.as_str(), f.as_str())).collect();
    let daemon = Reliefd::start(&manifest(&l.scene, &listed), &["--keep-going"]).unwrap();
    let url = daemon.url();

    let state = get(&format!("{url}/api/state")).unwrap();
    let text = String::from_utf8_lossy(&state.body).into_owned();
    let json = state.json().unwrap();
    let failed: Vec<&str> = json["sources"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| !s["error"].as_str().unwrap_or_default().is_empty())
        .map(|s| s["id"].as_str().unwrap())
        .collect();
    assert_eq!(failed.len(), sources.len() - 1, "every hostile source fails: {text}");
    assert!(!text.contains("4242"), "{text}");
    for (id, _) in &sources {
        let answer = get(&format!("{url}/api/elevation?points=10.25,45.25&source={id}")).unwrap();
        let body = String::from_utf8_lossy(&answer.body);
        assert!(!body.contains("4242"), "{id}: {body}");
    }
    let hill = get(&format!("{url}/api/elevation?points=10.25,45.25&source=dem")).unwrap().json().unwrap();
    let height = hill["samples"][0]["heightM"].as_f64().unwrap();
    // (The hill at a tenth of its pixels: its top is some metres lower.)
    assert!((height - 2000.0).abs() < 20.0, "{hill}");

    // The good VRT edited to read the secret: refused, the hill stays.
    std::fs::write(l.scene.join("dem.vrt"), vrt(0, "../outside/secret.tif", true)).unwrap();
    let reload = request("POST", &format!("{url}/api/reload"), Some("{\"sourceIds\":[\"dem\"]}")).unwrap();
    let text = String::from_utf8_lossy(&reload.body).into_owned();
    assert!(text.contains("dem.vrt") && text.contains("outside"), "{text}");
    let hill = get(&format!("{url}/api/elevation?points=10.25,45.25&source=dem")).unwrap().json().unwrap();
    let height = hill["samples"][0]["heightM"].as_f64().unwrap();
    assert!((height - 2000.0).abs() < 20.0, "the last good heights stay: {hill}");
    assert_eq!(listener.connections(), 0, "reliefd called out");
    daemon
        .stop(&[
            "outside the scene's folders",
            "not read",
            "cannot open",
            "keeping the last good",
            "none of the VRT's files is there",
        ])
        .unwrap();
}
