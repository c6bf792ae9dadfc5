//! ArcGIS's formats as an editor writes them: a file geodatabase edited
//! through GDAL's OpenFileGDB driver (Debian's python3-gdal, run as
//! `tests/scripts/gdb_editor.py`), each edit a save that closes the
//! geodatabase, as ArcGIS's "Save edits" does.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

use anyhow::Context;
use serde_json::{Value, json};

use crate::PYTHON;

/// True when GDAL's Python bindings with the OpenFileGDB driver are here
/// (CI always has them: scripts/setup.sh installs python3-gdal).
pub fn available(test: &str) -> bool {
    crate::python_can(test, "from osgeo import ogr; assert ogr.GetDriverByName('OpenFileGDB')", "python3-gdal")
}

/// A layer to create: name, geometry ("polygon", "point", "multipatch"),
/// string fields, and features as (WKT, attributes).
pub struct LayerSpec<'a> {
    pub name: &'a str,
    pub geom: &'a str,
    pub fields: &'a [&'a str],
    pub features: Vec<(String, Value)>,
}

/// One editor process on one geodatabase.
pub struct GdbEditor {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl GdbEditor {
    pub fn start(gdb: &Path) -> anyhow::Result<Self> {
        let script = crate::workspace_root().join("tests/scripts/gdb_editor.py");
        let mut child = Command::new(PYTHON)
            .arg(script)
            .arg(gdb)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start GDAL's python")?;
        let stdin = child.stdin.take().context("the editor's stdin")?;
        let stdout = BufReader::new(child.stdout.take().context("the editor's stdout")?);
        let mut editor = Self { child, stdin, stdout };
        editor.reply()?;
        Ok(editor)
    }

    /// Sends one command and waits for its reply.
    pub fn run(&mut self, command: &Value) -> anyhow::Result<Value> {
        writeln!(self.stdin, "{command}")?;
        self.stdin.flush()?;
        self.reply()
    }

    pub fn create(&mut self, layers: &[LayerSpec<'_>]) -> anyhow::Result<()> {
        let layers: Vec<Value> = layers
            .iter()
            .map(|l| {
                let features: Vec<Value> =
                    l.features.iter().map(|(wkt, attrs)| json!({"wkt": wkt, "attrs": attrs})).collect();
                json!({"name": l.name, "geom": l.geom, "fields": l.fields, "features": features})
            })
            .collect();
        self.run(&json!({ "create": layers }))?;
        Ok(())
    }

    /// Sets attributes (and the geometry, when given) of feature `fid`.
    pub fn update(&mut self, layer: &str, fid: u64, attrs: &Value, wkt: Option<&str>) -> anyhow::Result<Value> {
        let mut command = json!({"update": layer, "fid": fid, "attrs": attrs});
        if let Some(wkt) = wkt {
            command["wkt"] = json!(wkt);
        }
        self.run(&command)
    }

    pub fn insert(&mut self, layer: &str, wkt: &str, attrs: &Value) -> anyhow::Result<u64> {
        let reply = self.run(&json!({"insert": layer, "wkt": wkt, "attrs": attrs}))?;
        reply["fid"].as_u64().with_context(|| format!("no fid in {reply}"))
    }

    pub fn delete(&mut self, layer: &str, fid: u64) -> anyhow::Result<Value> {
        self.run(&json!({"delete": layer, "fid": fid}))
    }

    /// Moves the first `count` features by (dx, dy), in one transaction.
    pub fn move_features(&mut self, layer: &str, count: usize, (dx, dy): (f64, f64)) -> anyhow::Result<Value> {
        self.run(&json!({"move": layer, "count": count, "dx": dx, "dy": dy}))
    }

    pub fn repack(&mut self, layer: &str) -> anyhow::Result<Value> {
        self.run(&json!({ "repack": layer }))
    }

    /// The layer as OGR reads it: fid, ISO WKT and attributes of each feature.
    pub fn read(&mut self, layer: &str) -> anyhow::Result<Vec<Value>> {
        let reply = self.run(&json!({ "read": layer }))?;
        reply["features"].as_array().cloned().with_context(|| format!("no features in {reply}"))
    }

    fn reply(&mut self) -> anyhow::Result<Value> {
        let mut line = String::new();
        self.stdout.read_line(&mut line)?;
        anyhow::ensure!(!line.is_empty(), "the geodatabase editor ended without a reply");
        let reply: Value = serde_json::from_str(&line).with_context(|| format!("the editor said: {line}"))?;
        if let Some(error) = reply.get("error") {
            anyhow::bail!("GDAL: {error}");
        }
        Ok(reply)
    }
}

impl Drop for GdbEditor {
    fn drop(&mut self) {
        let _closing = writeln!(self.stdin, "{}", json!({"quit": true}));
        let _flushed = self.stdin.flush();
        if matches!(self.child.try_wait(), Ok(None)) {
            std::thread::sleep(std::time::Duration::from_millis(50));
            let _already_gone = self.child.kill();
            let _reaped = self.child.wait();
        }
    }
}

/// A square parcel `side` degrees wide with its south-west corner at (x, y).
pub fn square_wkt(x: f64, y: f64, side: f64) -> String {
    format!("POLYGON (({x} {y},{x} {y2},{x2} {y2},{x2} {y},{x} {y}))", x2 = x + side, y2 = y + side)
}

/// A MultiPatch shapefile written by GDAL (`SHPT=MULTIPATCH`), EPSG:4326,
/// with a string field `use`: one feature per (WKT, use).
pub fn write_multipatch_shapefile(shp: &Path, features: &[(String, &str)]) -> anyhow::Result<()> {
    let script = r#"
import json, sys
from osgeo import gdal, ogr, osr
gdal.UseExceptions()
srs = osr.SpatialReference(); srs.ImportFromEPSG(4326)
ds = ogr.GetDriverByName("ESRI Shapefile").CreateDataSource(sys.argv[1])
layer = ds.CreateLayer("patches", srs, ogr.wkbTINZ, options=["SHPT=MULTIPATCH"])
layer.CreateField(ogr.FieldDefn("use", ogr.OFTString))
for wkt, use in json.loads(sys.stdin.read()):
    f = ogr.Feature(layer.GetLayerDefn())
    f.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
    f.SetField("use", use)
    layer.CreateFeature(f)
ds = None
"#;
    let mut child = Command::new(PYTHON)
        .args(["-c", script])
        .arg(shp)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("cannot start GDAL's python")?;
    child.stdin.take().context("stdin")?.write_all(serde_json::to_string(features)?.as_bytes())?;
    let out = child.wait_with_output()?;
    anyhow::ensure!(
        out.status.success(),
        "GDAL could not write {}: {}",
        shp.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    Ok(())
}
