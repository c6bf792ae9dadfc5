#![allow(clippy::unwrap_used, reason = "a test")]

use std::fmt::Write as _;
use std::fs;

use super::*;

/// A VRT of one band whose sources are `names` (relative to it when
/// `relative`).
fn vrt(names: &[&str], relative: bool) -> String {
    let mut sources = String::new();
    for n in names {
        let _ = write!(
            sources,
            "<SimpleSource><SourceFilename relativeToVRT=\"{}\">{n}</SourceFilename><SourceBand>1</SourceBand></SimpleSource>",
            u8::from(relative)
        );
    }
    format!(
        "<VRTDataset rasterXSize=\"4\" rasterYSize=\"4\"><VRTRasterBand dataType=\"Float32\" band=\"1\">{sources}</VRTRasterBand></VRTDataset>"
    )
}

/// A scene folder and a folder beside it holding a secret.
struct Folders {
    _dir: tempfile::TempDir,
    scene: PathBuf,
    secret: PathBuf,
}

fn folders() -> Folders {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let outside = dir.path().join("outside");
    fs::create_dir_all(scene.join("tiles")).unwrap();
    fs::create_dir_all(&outside).unwrap();
    fs::write(scene.join("tiles/a.tif"), b"not read").unwrap();
    let secret = outside.join("secret.tif");
    fs::write(&secret, b"secret bytes").unwrap();
    Folders { _dir: dir, scene, secret }
}

fn write(path: &Path, text: &str) -> PathBuf {
    fs::write(path, text).unwrap();
    path.to_path_buf()
}

#[test]
fn members_in_the_folder_pass_and_members_outside_are_refused() {
    let f = folders();
    let inside = write(&f.scene.join("in.vrt"), &vrt(&["tiles/a.tif"], true));
    check_dataset(&inside).unwrap();
    let absolute = f.scene.join("tiles/a.tif").display().to_string();
    check_dataset(&write(&f.scene.join("abs.vrt"), &vrt(&[&absolute], false))).unwrap();

    for (name, vrt_text) in [
        ("climbs.vrt", vrt(&["../outside/secret.tif"], true)),
        ("absolute.vrt", vrt(&[&f.secret.display().to_string()], false)),
        (
            "raw.vrt",
            (
                "<VRTDataset rasterXSize=\"4\" rasterYSize=\"4\"><VRTRasterBand dataType=\"Byte\" band=\"1\" subClass=\"VRTRawRasterBand\">\
             <SourceFilename relativetoVRT=\"1\">../outside/secret.tif</SourceFilename><ImageOffset>0</ImageOffset>\
             <PixelOffset>1</PixelOffset><LineOffset>4</LineOffset></VRTRasterBand></VRTDataset>"
                .to_owned()
            ),
        ),
        (
            "warped.vrt",
            format!(
                "<VRTDataset rasterXSize=\"4\" rasterYSize=\"4\" subClass=\"VRTWarpedDataset\"><GDALWarpOptions>\
             <SourceDataset relativeToVRT=\"0\">{}</SourceDataset></GDALWarpOptions></VRTDataset>",
                f.secret.display()
            ),
        ),
    ] {
        let error = check_dataset(&write(&f.scene.join(name), &vrt_text)).unwrap_err();
        assert!(error.contains("outside the scene's folders") && error.contains(name), "{name}: {error}");
    }
}

#[test]
fn a_nested_vrt_is_checked_and_an_edit_to_it_is_checked_again() {
    let f = folders();
    let inner = write(&f.scene.join("inner.vrt"), &vrt(&["tiles/a.tif"], true));
    let outer = write(&f.scene.join("outer.vrt"), &vrt(&["inner.vrt"], true));
    check_dataset(&outer).unwrap();
    // The inner VRT turned to point out: the outer one is refused now.
    write(&inner, &vrt(&["../outside/secret.tif"], true));
    let error = check_dataset(&outer).unwrap_err();
    assert!(error.contains("inner.vrt") && error.contains("outside"), "{error}");
    // A cycle ends.
    write(&inner, &vrt(&["outer.vrt"], true));
    check_dataset(&outer).unwrap();
}

#[test]
fn links_out_of_the_folder_are_followed_and_refused() {
    let f = folders();
    std::os::unix::fs::symlink(&f.secret, f.scene.join("tiles/link.tif")).unwrap();
    let error = check_dataset(&write(&f.scene.join("link.vrt"), &vrt(&["tiles/link.tif"], true))).unwrap_err();
    assert!(error.contains("secret.tif"), "{error}");
    // A side file GDAL reads beside a named file (overviews) linked out.
    let dem = write(&f.scene.join("dem.tif"), "not read");
    check_dataset(&dem).unwrap();
    std::os::unix::fs::symlink(&f.secret, f.scene.join("dem.tif.ovr")).unwrap();
    let error = check_dataset(&dem).unwrap_err();
    assert!(error.contains("side file") && error.contains("dem.tif.ovr"), "{error}");
}

#[test]
fn urls_network_file_systems_and_connection_strings_are_refused() {
    let f = folders();
    let zip = write(&f.scene.join("tiles.zip"), "a zip");
    for (name, why) in [
        // Objects only in the buckets and hosts of the scene's (none here).
        ("/vsicurl/http://127.0.0.1:9/dem.tif", "outside the scene's buckets and hosts"),
        ("http://127.0.0.1:9/dem.tif", "outside the scene's buckets and hosts"),
        ("s3://bucket/dem.tif", "outside the scene's buckets and hosts"),
        ("/vsis3/bucket/dem.tif", "outside the scene's buckets and hosts"),
        ("ftp://127.0.0.1:9/dem.tif", "URL"),
        ("/vsimem/relief/1-1.vrt", "/vsimem/"),
        ("/vsicurl_streaming/x", "/vsicurl_streaming/"),
        ("vrt://tiles/a.tif?bands=1", "URL"),
        ("NETCDF:\"x.nc\":z", "connection string"),
        ("PG:dbname=gis", "connection string"),
        ("DERIVED_SUBDATASET:AMPLITUDE:x.tif", "connection string"),
    ] {
        let error = check_dataset(&write(&f.scene.join("n.vrt"), &vrt(&[name], false))).unwrap_err();
        assert!(error.contains(why), "{name}: {error}");
    }
    // An archive in the folder passes; one outside does not.
    check_dataset(&write(&f.scene.join("z.vrt"), &vrt(&[&format!("/vsizip/{}/a.tif", zip.display())], false))).unwrap();
    let outside = f.secret.with_file_name("x.zip");
    fs::write(&outside, "a zip").unwrap();
    for name in [format!("/vsizip/{}/a.tif", outside.display()), format!("/vsisubfile/0_4,{}", f.secret.display())] {
        let error = check_dataset(&write(&f.scene.join("z.vrt"), &vrt(&[&name], false))).unwrap_err();
        assert!(error.contains("outside"), "{name}: {error}");
    }
}

#[test]
fn python_pixel_functions_and_service_descriptions_are_refused() {
    let f = folders();
    let python = "<VRTDataset rasterXSize=\"4\" rasterYSize=\"4\"><VRTRasterBand dataType=\"Float32\" band=\"1\" \
        subClass=\"VRTDerivedRasterBand\"><PixelFunctionType>f</PixelFunctionType>\
        <PixelFunctionLanguage>Python</PixelFunctionLanguage><PixelFunctionCode>import os</PixelFunctionCode>\
        </VRTRasterBand></VRTDataset>";
    let error = check_dataset(&write(&f.scene.join("py.vrt"), python)).unwrap_err();
    assert!(error.contains("runs no code"), "{error}");
    for (name, text) in [
        (
            "wms.xml",
            "<GDAL_WMS><Service name=\"TMS\"><ServerUrl>http://127.0.0.1:9/${z}</ServerUrl></Service></GDAL_WMS>",
        ),
        ("wmts.xml", "<GDAL_WMTS><GetCapabilitiesUrl>http://127.0.0.1:9/</GetCapabilitiesUrl></GDAL_WMTS>"),
        ("wcs.xml", "<WCS_GDAL><ServiceURL>http://127.0.0.1:9/</ServiceURL></WCS_GDAL>"),
        ("dem.mrf", "<MRF_META><Raster><DataFile>/etc/passwd</DataFile></Raster></MRF_META>"),
    ] {
        let error = check_dataset(&write(&f.scene.join(name), text)).unwrap_err();
        assert!(error.contains(name), "{name}: {error}");
    }
    // An OGR VRT's data source is a reference like any other.
    let ogr = "<OGRVRTDataSource><OGRVRTLayer name=\"x\"><SrcDataSource relativeToVRT=\"1\">../outside/secret.tif\
        </SrcDataSource></OGRVRTLayer></OGRVRTDataSource>";
    assert!(check_dataset(&write(&f.scene.join("v.vrt"), ogr)).unwrap_err().contains("outside"));
}

#[test]
fn names_are_told_apart() {
    assert!(refusal("/vsizip/a.zip/b.tif").is_none());
    assert!(refusal("tiles/a.tif").is_none());
    assert!(refusal("/vsicurl/https://x/y.tif").is_some());
    assert!(refusal("https://x/y.tif").is_some());
    assert!(driver_prefix("GPKG:x.gpkg:t") && !driver_prefix("C:/x.tif") && !driver_prefix("tiles/a:b.tif"));
    assert_eq!(archive("{/x/a.zip}/b.tif"), Some(PathBuf::from("/x/a.zip")));
}
