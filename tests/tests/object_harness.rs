//! The object-storage harness (tests/src/s3.rs) against GDAL itself, before
//! any reliefd reads through it: a COG put on moto's S3 reads back through
//! `/vsis3/` as the file on disk does, and one served by http-server
//! through `/vsicurl/`; an overwrite changes the version (ETag) a poller
//! reads; and with keys checked, moto refuses the test key and GDAL says
//! so without the secret. These need moto (scripts/setup.sh, which CI
//! runs) and npm's http-server: without them they fail, saying so.

use std::path::Path;

use gdal::config::{clear_thread_local_config_option, set_thread_local_config_option};
use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::spatial_ref::SpatialRef;
use gdal::{Dataset, DriverManager};
use relief_tests::s3::{HttpServer, S3Server, SECRET_ACCESS_KEY};

const SIDE: usize = 64;

/// A 64x64 Float32 GeoTIFF laid out as a COG is (16x16 DEFLATE tiles, the
/// header first), whose samples depend on `seed`. GDAL's COG driver wants
/// tiles of 128 or more, one tile at this size.
fn write_cog(path: &Path, seed: f32) -> anyhow::Result<()> {
    let mem = DriverManager::get_driver_by_name("MEM")?;
    let mut ds = mem.create_with_band_type::<f32, _>("", SIDE, SIDE, 1)?;
    ds.set_geo_transform(&[7.0, 0.001, 0.0, 46.0, 0.0, -0.001])?;
    ds.set_spatial_ref(&SpatialRef::from_epsg(4326)?)?;
    let samples = (0..SIDE * SIDE).map(|i| seed + (i % SIDE) as f32 * 0.5 + (i / SIDE) as f32 * 0.25).collect();
    ds.rasterband(1)?.write((0, 0), (SIDE, SIDE), &mut Buffer::new((SIDE, SIDE), samples))?;
    let options = RasterCreationOptions::from_iter([
        "TILED=YES",
        "BLOCKXSIZE=16",
        "BLOCKYSIZE=16",
        "COMPRESS=DEFLATE",
        "COPY_SRC_OVERVIEWS=YES",
    ]);
    ds.create_copy(&DriverManager::get_driver_by_name("GTiff")?, path, &options)?;
    Ok(())
}

fn samples(path: &str) -> anyhow::Result<Vec<f32>> {
    let ds = Dataset::open(path)?;
    Ok(ds.rasterband(1)?.read_band_as::<f32>()?.data().to_vec())
}

/// Sets GDAL's configuration on this thread (the test's) until dropped.
struct Config(Vec<String>);

impl Config {
    fn set(options: &[(String, String)]) -> anyhow::Result<Self> {
        for (k, v) in options {
            set_thread_local_config_option(k, v)?;
        }
        Ok(Self(options.iter().map(|(k, _)| k.clone()).collect()))
    }
}

impl Drop for Config {
    fn drop(&mut self) {
        for k in &self.0 {
            let _ = clear_thread_local_config_option(k);
        }
    }
}

fn is_md5_etag(etag: &str) -> bool {
    etag.len() == 34
        && etag.starts_with('"')
        && etag.ends_with('"')
        && etag[1..33].bytes().all(|b| b.is_ascii_hexdigit())
}

#[test]
fn a_cog_on_moto_reads_through_vsis3_as_on_disk_and_an_overwrite_changes_its_etag() {
    let s3 = S3Server::start().expect("moto starts (scripts/setup.sh installs it; CI runs it)");
    let dir = tempfile::tempdir().unwrap();
    let (first, second) = (dir.path().join("first.tif"), dir.path().join("second.tif"));
    write_cog(&first, 100.0).unwrap();
    write_cog(&second, 200.0).unwrap();

    s3.create_bucket("harness-dem").unwrap();
    assert_eq!(s3.head("harness-dem", "dem.tif").unwrap(), None, "no object before the put");
    let started = std::time::Instant::now();
    let put_etag = s3.put_file("harness-dem", "dem.tif", &first).unwrap();
    let put_ms = started.elapsed().as_millis();
    let head = s3.head("harness-dem", "dem.tif").unwrap().expect("the object is there after its put");
    assert_eq!(head.etag, put_etag);
    assert!(is_md5_etag(&head.etag), "moto's ETag is a quoted MD5: {}", head.etag);
    assert_eq!(head.len, std::fs::metadata(&first).unwrap().len());
    assert!(!head.last_modified.is_empty());
    assert_eq!(s3.get("harness-dem", "dem.tif").unwrap().unwrap(), std::fs::read(&first).unwrap());
    eprintln!("put of {} bytes: {put_ms} ms", head.len);

    {
        let _config = Config::set(&s3.gdal_config()).unwrap();
        let over_s3 = samples("/vsis3/harness-dem/dem.tif").unwrap();
        assert_eq!(over_s3, samples(first.to_str().unwrap()).unwrap(), "/vsis3/ reads what the file holds");
    }
    let ranged = s3.log().iter().filter(|l| l.contains("\"GET /harness-dem/dem.tif ")).count();
    assert!(ranged > 0, "GDAL's reads reached moto: {:#?}", s3.log());

    s3.put_file("harness-dem", "dem.tif", &second).unwrap();
    let after = s3.head("harness-dem", "dem.tif").unwrap().unwrap();
    assert_ne!(after.etag, head.etag, "an overwrite changes the ETag");

    s3.delete("harness-dem", "dem.tif").unwrap();
    assert_eq!(s3.head("harness-dem", "dem.tif").unwrap(), None, "a deleted object is gone");

    let env = s3.env();
    let get = |k: &str| env.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
    assert_eq!(get("AWS_ENDPOINT_URL"), Some(s3.endpoint().as_str()));
    assert_eq!(get("AWS_SECRET_ACCESS_KEY"), Some(SECRET_ACCESS_KEY));
    assert_eq!(get("AWS_REGION"), Some("us-east-1"));
    assert!(get("AWS_ACCESS_KEY_ID").is_some());
}

#[test]
fn with_keys_checked_moto_refuses_the_test_key_and_gdal_says_so_without_the_secret() {
    let s3 = S3Server::start_with_auth().expect("moto starts (scripts/setup.sh installs it; CI runs it)");
    let dir = tempfile::tempdir().unwrap();
    let cog = dir.path().join("dem.tif");
    write_cog(&cog, 1.0).unwrap();
    // The harness's own calls use a key moto issued, signed as botocore
    // checks: each of these fails if the signing is wrong.
    s3.create_bucket("harness-auth").unwrap();
    s3.put_file("harness-auth", "dem.tif", &cog).unwrap();
    assert!(s3.head("harness-auth", "dem.tif").unwrap().is_some());

    let mut options = s3.gdal_config();
    // GDAL remembers a file it could not read; each open here asks again.
    options.push(("CPL_VSIL_CURL_NON_CACHED".into(), "/vsis3/harness-auth".into()));
    let _config = Config::set(&options).unwrap();
    let Err(refused) = Dataset::open("/vsis3/harness-auth/dem.tif") else { panic!("the test key was not refused") };
    let message = refused.to_string();
    eprintln!("GDAL on a refused key: {message}");
    assert!(!message.contains(SECRET_ACCESS_KEY), "GDAL's error shows the secret: {message}");
    let refusals = s3.log().iter().filter(|l| l.contains("/harness-auth/dem.tif") && l.contains("\" 403 ")).count();
    assert!(refusals > 0, "moto answered GDAL with 403: {:#?}", s3.log());

    s3.accept_any_keys().unwrap();
    assert_eq!(samples("/vsis3/harness-auth/dem.tif").unwrap(), samples(cog.to_str().unwrap()).unwrap());
    s3.refuse_unknown_keys().unwrap();
    assert!(Dataset::open("/vsis3/harness-auth/dem.tif").is_err(), "refused again");
}

#[test]
fn a_cog_served_by_http_server_reads_through_vsicurl_with_ranges_and_etags() {
    let dir = tempfile::tempdir().unwrap();
    let cog = dir.path().join("public.tif");
    write_cog(&cog, 50.0).unwrap();
    let http = HttpServer::start(dir.path()).expect("http-server starts (npm ci in tests/npm; CI has node and npm)");

    let url = http.url("public.tif");
    assert_eq!(samples(&format!("/vsicurl/{url}")).unwrap(), samples(cog.to_str().unwrap()).unwrap());

    let agent: ureq::Agent = ureq::Agent::config_builder().http_status_as_error(false).build().into();
    let ranged = agent.get(&url).header("Range", "bytes=0-15").call().unwrap();
    assert_eq!(ranged.status().as_u16(), 206);
    let total = std::fs::metadata(&cog).unwrap().len();
    assert_eq!(ranged.headers().get("content-range").unwrap().to_str().unwrap(), format!("bytes 0-15/{total}"));
    assert!(ranged.headers().get("etag").is_some(), "a 206 carries the ETag");
    assert_eq!(ranged.into_body().read_to_vec().unwrap(), std::fs::read(&cog).unwrap()[..16]);

    let before = http.head("public.tif").unwrap().expect("served");
    assert_eq!(before.len, total);
    assert!(!before.last_modified.is_empty());
    // Its ETag holds the modification time to the millisecond.
    std::thread::sleep(std::time::Duration::from_millis(5));
    write_cog(&cog, 60.0).unwrap();
    let after = http.head("public.tif").unwrap().expect("served");
    assert_ne!(after.etag, before.etag, "a rewrite changes the ETag");
    assert_eq!(http.head("missing.tif").unwrap(), None);
}
