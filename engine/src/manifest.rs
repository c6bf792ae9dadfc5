//! The scene manifest (TOML): parsing and the checks that need no file.
//! Every error names the manifest, the source id (when there is one) and
//! the field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use relief_source::{OptionValue, PayloadKind, Quality, SourceSpec};
use serde::Deserialize;

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ManifestError {
    #[error("cannot read manifest: {source}: {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("invalid manifest: {message}: {}", path.display())]
    Parse { path: PathBuf, message: String },
    #[error("invalid manifest: field '{field}': {message}: {}", path.display())]
    Field { path: PathBuf, field: String, message: String },
    #[error("invalid manifest: source '{source_id}', field '{field}': {message}: {}", path.display())]
    Source { path: PathBuf, source_id: String, field: String, message: String },
}

/// The effects a scene may declare, and the layers each one reads.
pub const EFFECTS: &[(&str, &[&str])] = &[
    ("lighting", &["height"]),
    ("atmosphere", &["height"]),
    ("fog", &["height"]),
    ("shadows", &["height"]),
    ("water", &["height", "water"]),
    ("detail", &["height"]),
];
/// The effects the sun lights: a `[sun]` (or a request's sun) needs one.
pub const SUNLIT: &[&str] = &["lighting", "atmosphere", "fog", "shadows", "water"];
/// Effects relief knows of but does not draw yet: refused by name, never
/// accepted and ignored.
pub const EFFECTS_NOT_YET: &[&str] = &["vegetation"];

/// Layers the renderer draws, and the payloads each may have: the water
/// mask is a colour tile's alpha (a rasterized polygon layer) or a
/// raster's values (water above 0.5).
pub const LAYERS: &[(&str, &[PayloadKind])] = &[
    ("height", &[PayloadKind::Height]),
    ("color", &[PayloadKind::Color]),
    ("buildings", &[PayloadKind::Mesh]),
    ("instances", &[PayloadKind::Instances]),
    ("water", &[PayloadKind::Color, PayloadKind::Height]),
];
/// Layers relief knows of but does not draw yet: refused by name (their
/// sources still serve tiles without them).
pub const LAYERS_NOT_YET: &[&str] = &["vegetation"];

/// The payloads layer `name` may have, None for an unknown layer.
pub fn layer_payloads(name: &str) -> Option<&'static [PayloadKind]> {
    LAYERS.iter().find(|(n, _)| *n == name).map(|(_, kinds)| *kinds)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawManifest {
    scene: RawScene,
    #[serde(default, rename = "source")]
    sources: Vec<RawSource>,
    #[serde(default)]
    layers: BTreeMap<String, String>,
    #[serde(default)]
    effects: BTreeMap<String, toml::Table>,
    #[serde(default)]
    quality: RawQuality,
    #[serde(default)]
    cache: RawCache,
    #[serde(default)]
    watch: RawWatch,
    #[serde(default)]
    storage: RawStorage,
    camera: Option<RawCamera>,
    #[serde(default)]
    sun: SunSection,
}

/// `[sun]`: a date-time, or a fixed azimuth and elevation, as written.
#[derive(Debug, Default, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunSection {
    /// RFC 3339 with its offset, quoted or as a TOML date-time.
    pub time: Option<toml::Value>,
    pub azimuth_deg: Option<f64>,
    pub elevation_deg: Option<f64>,
}

/// The camera a scene opens with; fields left out are chosen from the
/// height layer's extent.
#[derive(Debug, Default, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCamera {
    pub lon_deg: Option<f64>,
    pub lat_deg: Option<f64>,
    pub altitude_m: Option<f64>,
    pub heading_deg: Option<f64>,
    pub pitch_deg: Option<f64>,
    pub roll_deg: Option<f64>,
    pub vertical_fov_deg: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    name: String,
    #[serde(default = "default_grid")]
    grid: RawGrid,
    #[serde(default)]
    tile_size: Option<u32>,
    /// Folders (relative to the manifest's) that files named by scene
    /// files may lie under, besides their own folder and the manifest's.
    #[serde(default)]
    roots: Vec<String>,
}

fn default_grid() -> RawGrid {
    RawGrid::Named("geodetic".into())
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum RawGrid {
    Named(String),
    Projected(RawProjected),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProjected {
    crs: String,
    /// [min x, min y, max x, max y]; derived from the sources when absent.
    extent: Option<[f64; 4]>,
}

#[derive(Debug, Deserialize)]
struct RawSource {
    id: Option<String>,
    kind: Option<String>,
    path: Option<String>,
    paths: Option<Vec<String>>,
    #[serde(default)]
    inputs: Vec<String>,
    #[serde(flatten)]
    options: BTreeMap<String, toml::Value>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawQuality {
    resampling: Option<String>,
    reprojection_error_px: Option<f64>,
    clipmap_grid_size: Option<usize>,
    clipmap_levels: Option<usize>,
    color_detail: Option<usize>,
    interactive_scale: Option<f64>,
    frame_jpeg_quality: Option<u32>,
    instance_bands_m: Option<Vec<f64>>,
    instance_band_densities: Option<Vec<f64>>,
    instance_model_distance_m: Option<f64>,
    atmosphere_steps: Option<u32>,
    atmosphere_downsample: Option<u32>,
    shadow_cascades: Option<u32>,
    shadow_map_size: Option<u32>,
    detail_octaves: Option<u32>,
    terrain_mesh_error_m: Option<f64>,
}

/// The `[quality]` knobs of the picture (the renderer's), as written.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct PictureKnobs {
    pub clipmap_grid_size: Option<usize>,
    pub clipmap_levels: Option<usize>,
    pub color_detail: Option<usize>,
    pub interactive_scale: Option<f64>,
    pub frame_jpeg_quality: Option<u32>,
    pub instance_bands_m: Option<Vec<f64>>,
    pub instance_band_densities: Option<Vec<f64>>,
    pub instance_model_distance_m: Option<f64>,
    pub atmosphere_steps: Option<u32>,
    pub atmosphere_downsample: Option<u32>,
    pub shadow_cascades: Option<u32>,
    pub shadow_map_size: Option<u32>,
    pub detail_octaves: Option<u32>,
    /// The quantized-mesh terrain's largest vertical error at its finest
    /// level, metres (each coarser level allows twice its child's).
    pub terrain_mesh_error_m: Option<f64>,
}

/// What the manifest says of the picture, as written: the declared
/// effects' options, the picture's `[quality]` knobs, `[camera]` and
/// `[sun]`. The manifest checks the effects' names and the layers they
/// read; what draws the picture checks the rest (the daemon's
/// `picture.rs`, through the check a scene is loaded with).
#[derive(Debug, Default, Clone, PartialEq)]
pub struct PictureSection {
    pub effects: BTreeMap<String, toml::Table>,
    pub knobs: PictureKnobs,
    pub camera: RawCamera,
    pub sun: SunSection,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCache {
    memory_mb: Option<u64>,
    raster_mb: Option<u64>,
    disk_mb: Option<u64>,
    disk_dir: Option<String>,
    redis: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWatch {
    settle_ms: Option<u64>,
    debounce_ms: Option<u64>,
    write_timeout_ms: Option<u64>,
    fast_path: Option<bool>,
    poll_ms: Option<u64>,
    poll_s: Option<f64>,
}

/// `[storage]`: where the scene's objects are, over the AWS environment.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStorage {
    endpoint: Option<String>,
    region: Option<String>,
    anonymous: Option<bool>,
}

/// How file changes are picked up: the `[watch]` section. The quiet period
/// trades latency against the risk of reading a file mid-save.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WatchSettings {
    /// After a save's closing event (close-after-write, rename into place),
    /// wait this long for its sibling files before reading.
    pub settle_ms: u64,
    /// The quiet period: read only after no event for this long when the
    /// save's pattern is not recognised (or a fast read failed). Errors are
    /// reported only from reads after a quiet period.
    pub debounce_ms: u64,
    /// A file written to but never closed is read after this long quiet.
    pub write_timeout_ms: u64,
    /// Act on recognised closing patterns at once (after `settle_ms`).
    pub fast_path: bool,
    /// Also poll file fingerprints this often (0: off), for file systems
    /// without change notification.
    pub poll_ms: u64,
    /// Ask the store for the version of every object the scene reads this
    /// often (`poll_s`; 0: off, changes then come by `POST /api/notify`).
    /// Local files keep change notification.
    pub object_poll_ms: u64,
}

/// How often objects are polled unless `[watch] poll_s` says.
pub const DEFAULT_OBJECT_POLL_MS: u64 = 5000;

impl Default for WatchSettings {
    fn default() -> Self {
        Self {
            settle_ms: 5,
            debounce_ms: 500,
            write_timeout_ms: 2000,
            fast_path: true,
            poll_ms: 0,
            object_poll_ms: DEFAULT_OBJECT_POLL_MS,
        }
    }
}

/// How the scene's grid is declared.
#[derive(Debug, Clone, PartialEq)]
pub enum GridSpec {
    Geodetic,
    Projected { crs: String, extent: Option<[f64; 4]> },
}

/// A parsed manifest: shape checked, paths resolved, graph not yet built.
#[derive(Debug, Clone)]
pub struct Manifest {
    pub path: PathBuf,
    pub name: String,
    pub grid: GridSpec,
    pub tile_size: u32,
    pub sources: Vec<SourceSpec>,
    pub layers: BTreeMap<String, String>,
    pub effects: Vec<String>,
    /// The tiles' quality knobs.
    pub quality: Quality,
    /// The picture's sections, as written.
    pub picture: PictureSection,
    pub cache_budget_bytes: u64,
    /// The folders files named by scene files (a VRT's members) may lie
    /// under besides their own: the manifest's, then `[scene] roots`.
    pub roots: Vec<PathBuf>,
    /// The budget of decoded raster blocks (`[cache] raster_mb`), for the
    /// process: the first scene loaded sets it.
    pub raster_budget_bytes: u64,
    /// The tiles kept on disk for warm restarts (`[cache] disk_mb`,
    /// `disk_dir`); `None` when `disk_mb = 0`.
    pub disk: Option<DiskCache>,
    /// A Redis shared by replicas of the scene (`[cache] redis`).
    pub redis: Option<String>,
    pub watch: WatchSettings,
    /// `[storage]`: the scene's objects' endpoint and region, over the
    /// environment's.
    pub storage: relief_source_gdal::objects::Storage,
}

/// Where the disk tile cache is, and how large it may grow.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DiskCache {
    pub dir: PathBuf,
    pub budget_bytes: u64,
}

/// The disk cache's default size.
pub const DEFAULT_DISK_MB: u64 = 2048;

/// The user's cache folder for relief's tiles: `$XDG_CACHE_HOME/relief/tiles`,
/// else `~/.cache/relief/tiles`, else beside the scene. Tiles are keyed by
/// content, so every scene can share it.
fn default_disk_dir(manifest_dir: &Path) -> PathBuf {
    let home_cache = || std::env::var_os("HOME").filter(|h| !h.is_empty()).map(|h| PathBuf::from(h).join(".cache"));
    std::env::var_os("XDG_CACHE_HOME")
        .filter(|x| !x.is_empty())
        .map(PathBuf::from)
        .or_else(home_cache)
        .map_or_else(|| manifest_dir.join(".relief-cache"), |c| c.join("relief").join("tiles"))
}

impl Manifest {
    /// Whether a frame drawn with this manifest and one drawn with `other`
    /// are drawn alike (the same grid, layers, effects and their knobs,
    /// quality and sun): a manifest edit elsewhere (a source no layer
    /// reads, the caches, the watcher) changes no frame, and the sources
    /// it changed are dirt of their own.
    pub fn draws_as(&self, other: &Self) -> bool {
        (self.grid == other.grid)
            && (self.tile_size == other.tile_size)
            && (self.layers == other.layers)
            && (self.effects == other.effects)
            && (self.quality == other.quality)
            && (self.picture == other.picture)
    }

    pub fn load(path: &Path) -> Result<Self, ManifestError> {
        Self::parse(&Self::read(path)?, path)
    }

    /// The manifest's text.
    pub fn read(path: &Path) -> Result<String, ManifestError> {
        relief_source::regular::read_regular_to_string(path)
            .map_err(|source| ManifestError::Read { path: path.to_path_buf(), source })
    }

    /// The manifest's TOML, as written (for values laid over it).
    pub fn table(text: &str, path: &Path) -> Result<toml::Table, ManifestError> {
        toml::from_str(text).map_err(|e| ManifestError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim().replace('\n', " "),
        })
    }

    pub fn parse(text: &str, path: &Path) -> Result<Self, ManifestError> {
        let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
        let raw: RawManifest = toml::from_str(text).map_err(|e| ManifestError::Parse {
            path: path.clone(),
            message: e.to_string().trim().replace('\n', " "),
        })?;
        let field =
            |field: &str, message: String| ManifestError::Field { path: path.clone(), field: field.into(), message };
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();

        let mut roots = vec![base.clone()];
        for (n, given) in raw.scene.roots.iter().enumerate() {
            if let Some(object) = relief_source::objects::root_from_url(given) {
                roots.push(object);
                continue;
            }
            let root = base.join(given);
            if !root.is_dir() {
                return Err(field(&format!("scene.roots[{n}]"), format!("{} is not a folder", root.display())));
            }
            roots.push(root);
        }

        let grid = match raw.scene.grid {
            RawGrid::Named(name) if name == "geodetic" => GridSpec::Geodetic,
            RawGrid::Named(other) => {
                return Err(field(
                    "scene.grid",
                    format!("'{other}' is not a grid (use \"geodetic\" or {{ crs = \"EPSG:...\" }})"),
                ));
            }
            RawGrid::Projected(p) => {
                if let Some(e) = p.extent
                    && !(e.iter().all(|v| v.is_finite()) && e[2] > e[0] && e[3] > e[1])
                {
                    let [a, b, c, d] = e;
                    return Err(field(
                        "scene.grid.extent",
                        format!("[{a}, {b}, {c}, {d}] is not [min_x, min_y, max_x, max_y]"),
                    ));
                }
                GridSpec::Projected { crs: p.crs, extent: p.extent }
            }
        };

        let mut sources: Vec<SourceSpec> = Vec::new();
        for (index, s) in raw.sources.into_iter().enumerate() {
            let id =
                s.id.filter(|id| !id.trim().is_empty())
                    .ok_or_else(|| field(&format!("source[{index}].id"), "every source needs an id".into()))?;
            let source_err = |f: &str, message: String| ManifestError::Source {
                path: path.clone(),
                source_id: id.clone(),
                field: f.into(),
                message,
            };
            if sources.iter().any(|other| other.id == id) {
                return Err(source_err("id", "two sources have this id".into()));
            }
            let kind = s.kind.ok_or_else(|| source_err("kind", "missing".into()))?;
            let mut paths: Vec<PathBuf> = Vec::new();
            let (field_name, given) = match (s.path, s.paths) {
                (Some(_), Some(_)) => {
                    return Err(source_err("paths", "give 'path' or 'paths', not both".into()));
                }
                (Some(p), None) => ("path", vec![p]),
                (None, Some(ps)) => ("paths", ps),
                (None, None) => ("paths", Vec::new()),
            };
            for p in given {
                paths.extend(expand(&base, &p).map_err(|message| source_err(field_name, message))?);
            }
            /// A TOML value as an option value, arrays and tables nested;
            /// the error is the path below the option (`[1].planted`) and why.
            fn option_value(value: toml::Value) -> Result<OptionValue, (String, String)> {
                Ok(match value {
                    toml::Value::String(s) => OptionValue::Text(s),
                    toml::Value::Integer(i) => OptionValue::Number(i as f64),
                    toml::Value::Float(f) => OptionValue::Number(f),
                    toml::Value::Boolean(b) => OptionValue::Bool(b),
                    toml::Value::Array(items) => {
                        let mut list = Vec::with_capacity(items.len());
                        for (n, v) in items.into_iter().enumerate() {
                            list.push(option_value(v).map_err(|(at, m)| (format!("[{n}]{at}"), m))?);
                        }
                        OptionValue::List(list)
                    }
                    toml::Value::Table(table) => {
                        let mut map = BTreeMap::new();
                        for (k, v) in table {
                            let v = option_value(v).map_err(|(at, m)| (format!(".{k}{at}"), m))?;
                            map.insert(k, v);
                        }
                        OptionValue::Table(map)
                    }
                    other @ toml::Value::Datetime(_) => {
                        return Err((String::new(), format!("unsupported value {other}")));
                    }
                })
            }
            let mut options = BTreeMap::new();
            for (key, value) in s.options {
                let v = option_value(value).map_err(|(at, message)| source_err(&format!("{key}{at}"), message))?;
                options.insert(key, v);
            }
            sources.push(SourceSpec { id, kind, paths, inputs: s.inputs, options });
        }

        for (layer, id) in &raw.layers {
            if layer_payloads(layer).is_none() {
                let known: Vec<&str> = LAYERS.iter().map(|(n, _)| *n).collect();
                let why = if LAYERS_NOT_YET.contains(&layer.as_str()) { "not drawn yet" } else { "unknown layer" };
                return Err(field(&format!("layers.{layer}"), format!("{why} (drawn: {})", known.join(", "))));
            }
            if !sources.iter().any(|s| &s.id == id) {
                return Err(field(&format!("layers.{layer}"), format!("no source has id '{id}'")));
            }
        }
        let mut effects = Vec::new();
        for name in raw.effects.keys() {
            let Some((_, needs)) = EFFECTS.iter().find(|(e, _)| *e == name) else {
                let known: Vec<&str> = EFFECTS.iter().map(|(e, _)| *e).collect();
                let why = if EFFECTS_NOT_YET.contains(&name.as_str()) { "not drawn yet" } else { "unknown effect" };
                return Err(field(&format!("effects.{name}"), format!("{why} (drawn: {})", known.join(", "))));
            };
            if let Some(missing) = needs.iter().find(|l| !raw.layers.contains_key(**l)) {
                return Err(field(&format!("effects.{name}"), format!("needs a '{missing}' layer in [layers]")));
            }
            effects.push(name.clone());
        }

        if effects.iter().any(|e| e == "shadows") && !effects.iter().any(|e| e == "lighting") {
            return Err(field(
                "effects.shadows",
                "shadows take away the lighting's sunlight: declare lighting too".into(),
            ));
        }
        let mut quality = Quality::default();
        if let Some(r) = raw.quality.resampling {
            quality.resampling = r.parse().map_err(|e: String| field("quality.resampling", e))?;
        }
        if let Some(e) = raw.quality.reprojection_error_px {
            if !(e.is_finite() && (0.0..=16.0).contains(&e)) {
                return Err(field("quality.reprojection_error_px", format!("{e} is not between 0 and 16")));
            }
            quality.reprojection_error_px = e;
        }
        let tile_size = raw.scene.tile_size.unwrap_or(relief_source::TileGrid::DEFAULT_TILE_SIZE);
        if !(16..=4096).contains(&tile_size) || !tile_size.is_power_of_two() {
            return Err(field("scene.tile_size", format!("{tile_size} is not a power of two from 16 to 4096")));
        }
        let memory_mb = raw.cache.memory_mb.unwrap_or(512);
        if memory_mb == 0 {
            return Err(field("cache.memory_mb", "must be at least 1".into()));
        }
        let raster_mb = raw.cache.raster_mb.unwrap_or(relief_source_gdal::DEFAULT_BLOCK_BUDGET >> 20);
        if raster_mb == 0 {
            return Err(field("cache.raster_mb", "must be at least 1".into()));
        }
        let disk_mb = raw.cache.disk_mb.unwrap_or(DEFAULT_DISK_MB);
        let disk = (disk_mb > 0).then(|| DiskCache {
            dir: raw.cache.disk_dir.as_deref().map_or_else(|| default_disk_dir(&base), |d| base.join(d)),
            budget_bytes: disk_mb * 1024 * 1024,
        });
        let redis = raw.cache.redis.clone();
        if let Some(url) = &redis
            && !(url.starts_with("redis://") || url.starts_with("unix://") || url.starts_with("rediss://"))
        {
            return Err(field("cache.redis", format!("'{url}' is not a redis://HOST:PORT or unix:///PATH address")));
        }
        let storage = relief_source_gdal::objects::Storage {
            endpoint: raw.storage.endpoint.filter(|e| !e.trim().is_empty()),
            region: raw.storage.region.filter(|r| !r.trim().is_empty()),
            anonymous: raw.storage.anonymous.unwrap_or(false),
        };
        if let Some(endpoint) = &storage.endpoint
            && !(endpoint.starts_with("http://") || endpoint.starts_with("https://"))
        {
            return Err(field("storage.endpoint", format!("'{endpoint}' is not an http:// or https:// URL")));
        }
        // Objects the manifest names open their buckets and hosts to the
        // scene's files (a VRT object's members beside it).
        for source in &sources {
            for object_root in source.paths.iter().filter_map(|p| relief_source::objects::root_of(p)) {
                let root = PathBuf::from(object_root);
                if !roots.contains(&root) {
                    roots.push(root);
                }
            }
        }
        let defaults = WatchSettings::default();
        let watch = WatchSettings {
            settle_ms: raw.watch.settle_ms.unwrap_or(defaults.settle_ms),
            debounce_ms: raw.watch.debounce_ms.unwrap_or(defaults.debounce_ms),
            write_timeout_ms: raw.watch.write_timeout_ms.unwrap_or(defaults.write_timeout_ms),
            fast_path: raw.watch.fast_path.unwrap_or(defaults.fast_path),
            poll_ms: raw.watch.poll_ms.unwrap_or(defaults.poll_ms),
            object_poll_ms: match raw.watch.poll_s {
                None => defaults.object_poll_ms,
                Some(s) if s.is_finite() && (s == 0.0 || (0.05..=3600.0).contains(&s)) => (s * 1000.0).round() as u64,
                Some(s) => {
                    return Err(field("watch.poll_s", format!("{s} is not 0 (off) or 0.05 to 3600 seconds")));
                }
            },
        };
        for (name, value, max) in [
            ("watch.settle_ms", watch.settle_ms, 10_000),
            ("watch.debounce_ms", watch.debounce_ms, 60_000),
            ("watch.write_timeout_ms", watch.write_timeout_ms, 600_000),
        ] {
            if value > max {
                return Err(field(name, format!("{value} is above {max}")));
            }
        }
        if watch.poll_ms != 0 && watch.poll_ms < 10 {
            return Err(field("watch.poll_ms", format!("{} is below 10 ms (0 turns polling off)", watch.poll_ms)));
        }
        Ok(Self {
            path,
            name: raw.scene.name,
            roots,
            grid,
            tile_size,
            sources,
            layers: raw.layers,
            effects,
            quality,
            picture: PictureSection {
                effects: raw.effects,
                knobs: PictureKnobs {
                    clipmap_grid_size: raw.quality.clipmap_grid_size,
                    clipmap_levels: raw.quality.clipmap_levels,
                    color_detail: raw.quality.color_detail,
                    interactive_scale: raw.quality.interactive_scale,
                    frame_jpeg_quality: raw.quality.frame_jpeg_quality,
                    instance_bands_m: raw.quality.instance_bands_m,
                    instance_band_densities: raw.quality.instance_band_densities,
                    instance_model_distance_m: raw.quality.instance_model_distance_m,
                    atmosphere_steps: raw.quality.atmosphere_steps,
                    atmosphere_downsample: raw.quality.atmosphere_downsample,
                    shadow_cascades: raw.quality.shadow_cascades,
                    shadow_map_size: raw.quality.shadow_map_size,
                    detail_octaves: raw.quality.detail_octaves,
                    terrain_mesh_error_m: raw.quality.terrain_mesh_error_m,
                },
                camera: raw.camera.unwrap_or_default(),
                sun: raw.sun,
            },
            cache_budget_bytes: memory_mb * 1024 * 1024,
            raster_budget_bytes: raster_mb * 1024 * 1024,
            disk,
            redis,
            watch,
            storage,
        })
    }
}

/// A path of the manifest, relative to its folder; a pattern (`*`, `?`,
/// `[...]`, as in `tiles/*.tif`) is every file it matches, sorted, and
/// must match at least one.
fn expand(base: &Path, given: &str) -> Result<Vec<PathBuf>, String> {
    // An object (`s3://bucket/key`, `https://host/path`): read as GDAL
    // names it. No patterns: a listing is not a version.
    if let Some(object) = relief_source::objects::from_url(given) {
        return Ok(vec![object]);
    }
    if let Some(why) = relief_source_gdal::guard::refusal(given) {
        return Err(format!("'{}' is not a scene file: {why}", relief_source::echo::echoed(given)));
    }
    if !given.contains(['*', '?', '[']) {
        return Ok(vec![base.join(given)]);
    }
    let pattern = base.join(given);
    let text = pattern.to_str().ok_or_else(|| format!("'{given}' is not valid UTF-8"))?;
    let entries = glob::glob(text).map_err(|e| format!("'{given}' is not a valid pattern: {}", e.msg))?;
    let mut files: Vec<PathBuf> = entries.filter_map(Result::ok).filter(|p| p.is_file()).collect();
    files.sort();
    if files.is_empty() {
        return Err(format!("'{given}' matches no file (in {})", base.display()));
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Manifest, ManifestError> {
        Manifest::parse(text, Path::new("/scenes/alps/scene.toml"))
    }

    #[test]
    fn the_documented_shape_parses() {
        let m = parse(
            r#"
            [scene]
            name = "alps"
            grid = "geodetic"
            [[source]]
            id = "dem"
            kind = "gdal"
            path = "N43E007.hgt"
            [[source]]
            id = "ortho"
            kind = "gdal"
            path = "ortho.tif"
            [layers]
            height = "dem"
            color = "ortho"
            [effects]
            lighting = {}
            [quality]
            resampling = "bilinear"
            "#,
        )
        .unwrap();
        assert_eq!(m.name, "alps");
        assert_eq!(m.grid, GridSpec::Geodetic);
        assert_eq!(m.sources[0].paths, vec![PathBuf::from("/scenes/alps/N43E007.hgt")]);
        assert_eq!(m.effects, vec!["lighting".to_string()]);
        assert_eq!(m.layers["color"], "ortho");
    }

    #[test]
    fn projected_grids_parse() {
        let m = parse("[scene]\nname = \"storm\"\ngrid = { crs = \"EPSG:32612\" }\n").unwrap();
        assert_eq!(m.grid, GridSpec::Projected { crs: "EPSG:32612".into(), extent: None });
    }

    #[test]
    fn arrays_and_tables_become_nested_option_values() -> Result<(), Box<dyn std::error::Error>> {
        let m = parse(
            r#"
            [scene]
            name = "forest"
            [[source]]
            id = "forest"
            kind = "scatter"
            inputs = ["landcover", "dem"]
            seed = 7
            [[source.rule]]
            class = 311
            models = { conifer = 0.7, broadleaf = 0.3 }
            scale = [0.8, 1.2]
            [[source.rule]]
            class = 312
            models = { shrub = 1 }
            scale = 1.5
            "#,
        )?;
        let spec = &m.sources[0];
        assert_eq!(spec.number("seed")?, Some(7.0));
        let rules = spec.list("rule")?.ok_or("no rules")?;
        assert_eq!(rules.len(), 2);
        let OptionValue::Table(first) = &rules[0] else { panic!("{:?}", rules[0]) };
        assert_eq!(first["class"], OptionValue::Number(311.0));
        assert_eq!(first["scale"], OptionValue::List(vec![OptionValue::Number(0.8), OptionValue::Number(1.2)]));
        let OptionValue::Table(models) = &first["models"] else { panic!("{first:?}") };
        assert_eq!(models.keys().collect::<Vec<_>>(), ["broadleaf", "conifer"]);
        assert_eq!(models["conifer"], OptionValue::Number(0.7));
        assert!(spec.table("rule").unwrap_err().to_string().contains("expected a table, found a list"));
        // Scalars still read as before.
        assert!(spec.text("seed").is_err());
        Ok(())
    }

    #[test]
    fn a_datetime_is_refused_where_it_stands() {
        let top = parse("[scene]\nname='a'\n[[source]]\nid='s'\nkind='gdal'\nwhen=1979-05-27\n");
        assert!(top.unwrap_err().to_string().contains("source 's', field 'when': unsupported value 1979-05-27"));
        let nested = parse(
            "[scene]\nname='a'\n[[source]]\nid='s'\nkind='scatter'\n[[source.rule]]\nclass=1\n\
             [[source.rule]]\nplanted=[1, 1979-05-27]\n",
        );
        let msg = nested.unwrap_err().to_string();
        assert!(msg.contains("source 's', field 'rule[1].planted[1]': unsupported value 1979-05-27"), "{msg}");
    }

    #[test]
    fn errors_name_the_source_and_the_field() {
        let cases = [
            ("[scene]\nname='a'\n[[source]]\nid='dem'\n", "source 'dem', field 'kind'"),
            ("[scene]\nname='a'\n[quality]\nresampling='bicubic'\n", "field 'quality.resampling'"),
            ("[scene]\nname='a'\n[effects]\nsparkles={}\n", "field 'effects.sparkles'"),
            ("[scene]\nname='a'\n[layers]\nheight='nope'\n", "field 'layers.height'"),
            ("[scene]\nname='a'\ngrid='mercator'\n", "field 'scene.grid'"),
            (
                "[scene]\nname='a'\n[[source]]\nid='x'\nkind='gdal'\n[[source]]\nid='x'\nkind='gdal'\n",
                "source 'x', field 'id'",
            ),
            ("[scene]\nname='a'\n[effects]\nlighting={}\n", "needs a 'height' layer"),
            // Names relief knows but cannot honour yet are refused, not ignored.
            (
                "[scene]\nname='a'\n[effects]\nvegetation={}\n",
                "field 'effects.vegetation': not drawn yet (drawn: lighting, atmosphere, fog, shadows, water, detail)",
            ),
            (
                "[scene]\nname='a'\n[effects]\nsparkle={}\n",
                "field 'effects.sparkle': unknown effect (drawn: lighting, atmosphere, fog, shadows, water, detail)",
            ),
            ("[scene]\nname='a'\n[effects]\nfog={}\n", "field 'effects.fog': needs a 'height' layer"),
            ("[scene]\nname='a'\n[sun]\nhour = 15\n", "unknown field `hour`"),
            (
                "[scene]\nname='a'\n[[source]]\nid='t'\nkind='gdal'\npath='t.tif'\n[layers]\nvegetation='t'\n",
                "field 'layers.vegetation': not drawn yet (drawn: height, color, buildings, instances, water)",
            ),
            ("[scene]\nname = \n", "invalid manifest"),
        ];
        for (text, expected) in cases {
            let msg = parse(text).unwrap_err().to_string();
            assert!(msg.contains(expected), "{msg:?} should contain {expected:?}");
            assert!(msg.ends_with("/scenes/alps/scene.toml"), "{msg}");
        }
    }
}
