//! The source graph: a manifest's sources opened, checked and ordered so
//! that every source comes after its inputs.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

use relief_source::{GridKind, PayloadKind, ProjectedGrid, Source, SourceError, SourceSpec, TileGrid};

use crate::manifest::{EFFECTS, GridSpec, Manifest, ManifestError};
use crate::registry::Registry;

/// Why a scene could not be loaded as declared.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    #[error(transparent)]
    Manifest(#[from] ManifestError),
    /// A source's files or options were rejected by the source itself.
    #[error("source '{source_id}', field '{field}': {error}")]
    Source { source_id: String, field: String, error: SourceError },
}

/// The manifest field a source error is about, for messages.
fn field_of(error: &SourceError, spec: &SourceSpec) -> String {
    match error {
        SourceError::InvalidOption { field, .. } => field.clone(),
        SourceError::Crs { .. } if spec.options.contains_key("crs") => "crs".into(),
        SourceError::Input { .. } => "inputs".into(),
        SourceError::Unsupported(_) => "kind".into(),
        _ if spec.paths.len() > 1 => "paths".into(),
        _ => "path".into(),
    }
}

pub fn source_error(spec: &SourceSpec, error: SourceError) -> LoadError {
    LoadError::Source { source_id: spec.id.clone(), field: field_of(&error, spec), error }
}

/// One node of the graph in one scene generation.
#[derive(Debug, Clone)]
pub struct Slot {
    pub spec: SourceSpec,
    /// The last good version; None if the source never loaded.
    pub source: Option<Arc<dyn Source>>,
    /// Why the last load or refresh failed, when it did.
    pub error: Option<String>,
    /// Bumped each time a new version of the source is taken in.
    pub version: u64,
    /// Changes when this source or anything upstream changes: part of the
    /// tile cache key, so stale tiles are never served.
    pub effective_version: u64,
    /// Indices of the inputs in `SceneSnapshot::slots`.
    pub inputs: Vec<usize>,
    /// Needed by a layer or a declared effect.
    pub active: bool,
    /// This version's content address, for tile stores outside the process
    /// (`content.rs`); new whenever the effective version changes.
    pub content: crate::content::ContentKey,
}

impl Slot {
    pub fn output(&self, registry: &Registry) -> Option<PayloadKind> {
        self.source.as_ref().map(|s| s.output()).or_else(|| registry.get(&self.spec.kind).and_then(|k| k.output))
    }
}

/// Everything a request needs to see one consistent scene.
#[derive(Debug, Clone)]
pub struct SceneSnapshot {
    pub generation: u64,
    pub manifest: Arc<Manifest>,
    pub grid: TileGrid,
    /// Inputs before dependents.
    pub slots: Vec<Slot>,
}

impl SceneSnapshot {
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.slots.iter().position(|s| s.spec.id == id)
    }

    pub fn layer(&self, name: &str) -> Option<&Slot> {
        self.layer_index(name).map(|i| &self.slots[i])
    }

    /// The slot of the source that draws layer `name`.
    pub fn layer_index(&self, name: &str) -> Option<usize> {
        self.index_of(self.manifest.layers.get(name)?)
    }

    /// Recomputes effective versions, in graph order.
    pub fn recompute_versions(&mut self) {
        for i in 0..self.slots.len() {
            let mut h = mix_hash(self.slots[i].spec.id.as_bytes(), self.slots[i].version);
            for &input in &self.slots[i].inputs {
                h = mix_hash(&h.to_le_bytes(), self.slots[input].effective_version);
            }
            if self.slots[i].effective_version != h {
                self.slots[i].content = crate::content::ContentKey::taken_in(self.slots[i].source.as_ref());
            }
            self.slots[i].effective_version = h;
        }
    }
}

/// A small, stable mixing hash (FNV-1a over the bytes, then the number).
fn mix_hash(bytes: &[u8], n: u64) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes.iter().chain(&n.to_le_bytes()) {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// Orders the sources so inputs come first; reports unknown kinds, missing
/// inputs and cycles.
fn order(manifest: &Manifest, registry: &Registry) -> Result<Vec<usize>, Vec<LoadError>> {
    let mut errors = Vec::new();
    let err = |spec: &SourceSpec, field: &str, message: String| {
        LoadError::Manifest(ManifestError::Source {
            path: manifest.path.clone(),
            source_id: spec.id.clone(),
            field: field.into(),
            message,
        })
    };
    let index: HashMap<&str, usize> = manifest.sources.iter().enumerate().map(|(i, s)| (s.id.as_str(), i)).collect();
    for spec in &manifest.sources {
        match registry.get(&spec.kind) {
            None => errors.push(err(
                spec,
                "kind",
                format!("unknown kind '{}' (known: {})", spec.kind, registry.names().join(", ")),
            )),
            Some(kind) if !(kind.required_inputs..=kind.inputs.len()).contains(&spec.inputs.len()) => {
                let takes = if kind.required_inputs == kind.inputs.len() {
                    kind.inputs.len().to_string()
                } else {
                    format!("{} to {}", kind.required_inputs, kind.inputs.len())
                };
                errors.push(err(
                    spec,
                    "inputs",
                    format!("kind '{}' takes {takes} input(s), got {}", spec.kind, spec.inputs.len()),
                ));
            }
            Some(_) => {}
        }
        for input in &spec.inputs {
            if !index.contains_key(input.as_str()) {
                errors.push(err(spec, "inputs", format!("no source has id '{input}'")));
            }
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    // Depth-first topological sort; a grey node met again closes a cycle.
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Visiting,
        Done,
    }
    fn visit(
        i: usize,
        manifest: &Manifest,
        index: &HashMap<&str, usize>,
        marks: &mut [Mark],
        stack: &mut Vec<usize>,
        out: &mut Vec<usize>,
    ) -> Result<(), Vec<usize>> {
        match marks[i] {
            Mark::Done => return Ok(()),
            Mark::Visiting => {
                let start = stack.iter().position(|&s| s == i).unwrap_or(0);
                let mut cycle = stack[start..].to_vec();
                cycle.push(i);
                return Err(cycle);
            }
            Mark::New => {}
        }
        marks[i] = Mark::Visiting;
        stack.push(i);
        for input in &manifest.sources[i].inputs {
            visit(index[input.as_str()], manifest, index, marks, stack, out)?;
        }
        stack.pop();
        marks[i] = Mark::Done;
        out.push(i);
        Ok(())
    }
    let mut marks = vec![Mark::New; manifest.sources.len()];
    let mut out = Vec::new();
    for i in 0..manifest.sources.len() {
        if let Err(cycle) = visit(i, manifest, &index, &mut marks, &mut Vec::new(), &mut out) {
            let names: Vec<&str> = cycle.iter().map(|&c| manifest.sources[c].id.as_str()).collect();
            return Err(vec![err(&manifest.sources[cycle[0]], "inputs", format!("cycle {}", names.join(" -> ")))]);
        }
    }
    Ok(out)
}

fn grid_for(manifest: &Manifest, extents: impl Iterator<Item = relief_source::Extent>) -> Result<TileGrid, LoadError> {
    let field = |field: &str, message: String| {
        LoadError::Manifest(ManifestError::Field { path: manifest.path.clone(), field: field.into(), message })
    };
    let kind = match &manifest.grid {
        GridSpec::Geodetic => GridKind::Geodetic,
        GridSpec::Projected { crs, extent } => {
            let [min_x, min_y, max_x, max_y] = match extent {
                Some(e) => *e,
                None => {
                    let Some(u) = extents.reduce(|a, b| a.union(&b)) else {
                        return Err(field(
                            "scene.grid.extent",
                            "cannot derive it: no source has data here; give extent = [min_x, min_y, max_x, max_y]"
                                .into(),
                        ));
                    };
                    [u.min_x, u.min_y, u.max_x, u.max_y]
                }
            };
            GridKind::Projected(ProjectedGrid {
                crs: crs.clone(),
                min_x,
                min_y,
                size: (max_x - min_x).max(max_y - min_y),
            })
        }
    };
    TileGrid::new(kind, manifest.tile_size).map_err(|m| field("scene.grid", m))
}

/// Opens one source for `grid`.
pub fn open_source(spec: &SourceSpec, grid: &TileGrid, registry: &Registry) -> Result<Arc<dyn Source>, LoadError> {
    let kind = registry.get(&spec.kind).ok_or_else(|| source_error(spec, SourceError::Unsupported("this kind")))?;
    (kind.open)(spec, grid).map_err(|e| source_error(spec, e))
}

/// Builds a scene generation from a manifest. Structural problems (unknown
/// kinds, missing inputs, cycles, type mismatches, bad layers) fail the
/// build; sources that fail to open are kept as failed slots and their
/// errors returned beside the snapshot.
///
/// With a `previous` generation (a manifest edit), every source whose
/// declaration did not change keeps its loaded value and version, so its
/// cached tiles stay valid; the grid stays as it was unless `[scene]`
/// changed it.
pub fn build(
    manifest: Manifest,
    registry: &Registry,
    previous: Option<&SceneSnapshot>,
) -> Result<(SceneSnapshot, Vec<LoadError>), Vec<LoadError>> {
    relief_source_gdal::guard::set_roots(&manifest.roots);
    let reaches_objects = manifest.roots.iter().any(|r| relief_source::objects::is_object(r));
    relief_source_gdal::objects::configure_storage(&manifest.storage, reaches_objects);
    let generation = previous.map_or(1, |p| p.generation + 1);
    let same_grid =
        previous.is_some_and(|p| p.manifest.grid == manifest.grid && p.manifest.tile_size == manifest.tile_size);
    let kept =
        |spec: &SourceSpec| -> Option<&Slot> { previous.filter(|_| same_grid)?.slots.iter().find(|s| s.spec == *spec) };
    let order = order(&manifest, registry)?;
    if let GridSpec::Projected { crs, .. } = &manifest.grid
        && let Err(e) = relief_source_gdal::describe_crs(crs)
    {
        return Err(vec![LoadError::Manifest(ManifestError::Field {
            path: manifest.path.clone(),
            field: "scene.grid.crs".into(),
            message: e.to_string(),
        })]);
    }
    // A projected grid's CRS is all a source needs to open; its extent may
    // come from the sources themselves.
    let provisional = match &manifest.grid {
        GridSpec::Geodetic => grid_for(&manifest, std::iter::empty()).map_err(|e| vec![e])?,
        GridSpec::Projected { crs, .. } => TileGrid::new(
            GridKind::Projected(ProjectedGrid { crs: crs.clone(), min_x: 0.0, min_y: 0.0, size: 1.0 }),
            manifest.tile_size,
        )
        .map_err(|m| {
            vec![LoadError::Manifest(ManifestError::Field {
                path: manifest.path.clone(),
                field: "scene.tile_size".into(),
                message: m,
            })]
        })?,
    };
    let mut open_errors = Vec::new();
    let opened: Vec<Option<Arc<dyn Source>>> = order
        .iter()
        .map(|&i| {
            let spec = &manifest.sources[i];
            if let Some(slot) = kept(spec) {
                return slot.source.clone();
            }
            open_source(spec, &provisional, registry).map_err(|e| open_errors.push(e)).ok()
        })
        .collect();
    let grid = match previous {
        Some(p) if same_grid => p.grid.clone(),
        _ => grid_for(&manifest, opened.iter().flatten().filter_map(|s| s.info().extent)).map_err(|e| vec![e])?,
    };

    let position: HashMap<&str, usize> =
        order.iter().enumerate().map(|(pos, &i)| (manifest.sources[i].id.as_str(), pos)).collect();
    let mut slots: Vec<Slot> = order
        .iter()
        .zip(opened)
        .zip(&open_errors_for(&order, &manifest, &open_errors))
        .map(|((&i, source), error)| {
            let spec = manifest.sources[i].clone();
            let inputs = spec.inputs.iter().map(|id| position[id.as_str()]).collect();
            // A kept source keeps its version (and error); a new or changed
            // one gets a version no earlier value of it ever had.
            let (version, error) = match kept(&spec) {
                Some(old) => (old.version, old.error.clone()),
                None => (generation, error.clone()),
            };
            Slot {
                spec,
                source,
                error,
                version,
                effective_version: 0,
                inputs,
                active: false,
                content: crate::content::ContentKey::default(),
            }
        })
        .collect();

    // Type checks: op inputs and layers.
    let mut errors = Vec::new();
    let type_err = |id: &str, field: String, message: String| {
        LoadError::Manifest(ManifestError::Source { path: manifest.path.clone(), source_id: id.into(), field, message })
    };
    for slot in &slots {
        let Some(kind) = registry.get(&slot.spec.kind) else {
            continue;
        };
        for (n, (&input, expected)) in slot.inputs.iter().zip(kind.expected_inputs(&slot.spec)).enumerate() {
            if let Some(actual) = slots[input].output(registry)
                && actual != expected
            {
                errors.push(type_err(
                    &slot.spec.id,
                    format!("inputs[{n}]"),
                    format!(
                        "'{}' gives {actual} tiles, kind '{}' needs {expected}",
                        slots[input].spec.id, slot.spec.kind
                    ),
                ));
            }
        }
    }
    for (layer, id) in &manifest.layers {
        if let Some(expected) = crate::manifest::layer_payloads(layer)
            && let Some(slot) = slots.iter().find(|s| &s.spec.id == id)
            && let Some(actual) = slot.output(registry)
            && !expected.contains(&actual)
        {
            let needs: Vec<&str> = expected.iter().map(|k| k.name()).collect();
            errors.push(LoadError::Manifest(ManifestError::Field {
                path: manifest.path.clone(),
                field: format!("layers.{layer}"),
                message: format!("source '{id}' gives {actual} tiles, the {layer} layer needs {}", needs.join(" or ")),
            }));
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }

    // Active: what the layers and the declared effects need, and their inputs.
    let mut needed: BTreeSet<usize> = BTreeSet::new();
    let mut wanted: Vec<&str> = manifest.layers.values().map(String::as_str).collect();
    for effect in &manifest.effects {
        if let Some((_, layers)) = EFFECTS.iter().find(|(e, _)| e == effect) {
            wanted.extend(layers.iter().filter_map(|l| manifest.layers.get(*l)).map(String::as_str));
        }
    }
    let mut stack: Vec<usize> = wanted.iter().filter_map(|id| position.get(id).copied()).collect();
    while let Some(i) = stack.pop() {
        if needed.insert(i) {
            stack.extend(slots[i].inputs.iter().copied());
        }
    }
    for i in needed {
        slots[i].active = true;
    }

    let mut snapshot = SceneSnapshot { generation, manifest: Arc::new(manifest), grid, slots };
    snapshot.recompute_versions();
    Ok((snapshot, open_errors))
}

/// The error text of each source in `order`, None where it opened.
fn open_errors_for(order: &[usize], manifest: &Manifest, errors: &[LoadError]) -> Vec<Option<String>> {
    order
        .iter()
        .map(|&i| {
            let id = &manifest.sources[i].id;
            errors.iter().find_map(|e| match e {
                LoadError::Source { source_id, .. } if source_id == id => Some(e.to_string()),
                _ => None,
            })
        })
        .collect()
}
