//! A real QGIS, headless, editing a GeoPackage layer: the driver of
//! `tests/scripts/qgis_editor.py` (which documents the protocol).

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

use anyhow::Context;
use serde_json::{Value, json};

/// Debian's python3 has the `qgis` module (pyenv's or a venv's may not).
use crate::PYTHON;

/// One feature as QGIS reads it back.
#[derive(Debug, Clone, PartialEq)]
pub struct QgisFeature {
    pub fid: u64,
    pub attrs: serde_json::Map<String, Value>,
    pub coords: Vec<[f64; 2]>,
}

/// One commit: the wall clock just before and after `commitChanges`, and
/// the layer afterwards.
#[derive(Debug, Clone)]
pub struct Commit {
    pub t0: f64,
    pub t1: f64,
    pub features: Vec<QgisFeature>,
}

/// An edit of the layer in QGIS's edit buffer.
#[derive(Debug, Clone)]
pub enum Edit {
    MoveVertex { fid: u64, vertex: usize, dx: f64, dy: f64 },
    Add { wkt: String, attrs: Value },
    Delete { fid: u64 },
    Set { fid: u64, field: String, value: Value },
}

impl Edit {
    fn json(&self) -> Value {
        match self {
            Self::MoveVertex { fid, vertex, dx, dy } => {
                json!({"kind": "move_vertex", "fid": fid, "vertex": vertex, "dx": dx, "dy": dy})
            }
            Self::Add { wkt, attrs } => json!({"kind": "add", "wkt": wkt, "attrs": attrs}),
            Self::Delete { fid } => json!({"kind": "delete", "fid": fid}),
            Self::Set { fid, field, value } => json!({"kind": "set", "fid": fid, "field": field, "value": value}),
        }
    }
}

/// True when Debian's QGIS Python bindings are installed. Absent, a test
/// skips with a note, except under CI (`CI` set), which always has them.
pub fn available(test: &str) -> bool {
    crate::python_can(test, "import qgis.core", "qgis and python3-qgis")
}

/// A QGIS process with one layer of a GeoPackage loaded.
pub struct QgisEditor {
    child: Child,
    _runtime: tempfile::TempDir,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl QgisEditor {
    /// Starts QGIS on `layer` of `gpkg`, with the layers `also` loaded
    /// beside it; the layer's features as QGIS reads them.
    pub fn start(gpkg: &Path, layer: &str, also: &[&str]) -> anyhow::Result<(Self, Vec<QgisFeature>)> {
        let script = crate::workspace_root().join("tests/scripts/qgis_editor.py");
        let runtime = tempfile::tempdir()?;
        let mut child = Command::new(PYTHON)
            .arg(script)
            .arg(gpkg)
            .arg(layer)
            .args(also)
            .env("QT_QPA_PLATFORM", "offscreen")
            .env("XDG_RUNTIME_DIR", runtime.path())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start QGIS's python")?;
        let stdin = child.stdin.take().context("QGIS's stdin")?;
        let stdout = BufReader::new(child.stdout.take().context("QGIS's stdout")?);
        let mut editor = Self { child, _runtime: runtime, stdin, stdout };
        let ready = editor.reply()?;
        let features = features(&ready)?;
        Ok((editor, features))
    }

    /// Makes `edits` in one edit session and commits them; `stay_editing`
    /// keeps the layer in edit mode, as "Save Layer Edits" does.
    pub fn commit(&mut self, edits: &[Edit], stay_editing: bool) -> anyhow::Result<Commit> {
        self.send(edits, stay_editing)?;
        self.committed()
    }

    /// Asks for a commit of `edits` without waiting for it: commits sent
    /// one after another are made back to back.
    pub fn send(&mut self, edits: &[Edit], stay_editing: bool) -> anyhow::Result<()> {
        let edits: Vec<Value> = edits.iter().map(Edit::json).collect();
        writeln!(self.stdin, "{}", json!({"edits": edits, "stay_editing": stay_editing}))?;
        Ok(self.stdin.flush()?)
    }

    /// The next commit asked for with `send`, once QGIS has made it.
    pub fn committed(&mut self) -> anyhow::Result<Commit> {
        let reply = self.reply()?;
        let time = |k: &str| reply[k].as_f64().with_context(|| format!("no {k} in {reply}"));
        Ok(Commit { t0: time("t0")?, t1: time("t1")?, features: features(&reply)? })
    }

    fn reply(&mut self) -> anyhow::Result<Value> {
        let mut line = String::new();
        self.stdout.read_line(&mut line)?;
        anyhow::ensure!(!line.is_empty(), "QGIS ended without a reply");
        let reply: Value = serde_json::from_str(&line).with_context(|| format!("QGIS said: {line}"))?;
        if let Some(error) = reply.get("error") {
            anyhow::bail!("QGIS: {error}");
        }
        Ok(reply)
    }

    /// Closes QGIS (the layers unloaded, as when QGIS quits).
    pub fn quit(mut self) -> anyhow::Result<()> {
        writeln!(self.stdin, "{}", json!({"quit": true}))?;
        self.stdin.flush()?;
        anyhow::ensure!(self.child.wait()?.success(), "QGIS did not end cleanly");
        Ok(())
    }
}

impl Drop for QgisEditor {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _already_gone = self.child.kill();
            let _reaped = self.child.wait();
        }
    }
}

fn features(reply: &Value) -> anyhow::Result<Vec<QgisFeature>> {
    let list = reply["features"].as_array().with_context(|| format!("no features in {reply}"))?;
    list.iter()
        .map(|f| {
            let coords = f["coords"]
                .as_array()
                .context("coords")?
                .iter()
                .map(|p| Ok([p[0].as_f64().context("x")?, p[1].as_f64().context("y")?]))
                .collect::<anyhow::Result<_>>()?;
            Ok(QgisFeature {
                fid: f["fid"].as_u64().context("fid")?,
                attrs: f["attrs"].as_object().context("attrs")?.clone(),
                coords,
            })
        })
        .collect()
}
