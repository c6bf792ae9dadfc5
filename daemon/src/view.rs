//! Rendered views of the scene: the camera, the terrain the renderer reads
//! (answered from the tile store), and one shared GPU device behind a lock.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};

use relief_renderer::{
    ClipmapConfig, Detail, Detailed, Dirt, Frame, Gpu, InstanceBands, PassCounters, PassStats, RenderError,
    RenderSettings, Renderer, SceneLayers, Surface, TerrainSamples,
};
use relief_source::{Extent, Quality};
use tokio::sync::{Semaphore, watch};

pub use crate::camera::Camera;
use crate::camera::{default_camera, pose};
use crate::effects::EffectSettings;
use crate::graph::SceneSnapshot;
use crate::manifest::Manifest;
use crate::scene::Scene;
pub use crate::scene_tiles::{ModelCache, SceneBuildings, SceneInstances, SceneTerrain};
use crate::sun::{Sun, SunAngles};

/// The largest image side a request may ask for.
pub const MAX_IMAGE_SIDE: u32 = 4096;
/// Renders running or waiting for the device at once; more are refused.
pub const MAX_RENDERS_IN_FLIGHT: usize = 4;

#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Invalid(#[from] RenderError),
    #[error("{MAX_RENDERS_IN_FLIGHT} renders are already running or waiting; try again")]
    Busy,
    #[error("no renderer: {0}")]
    NoDevice(String),
    #[error("too many views: {0}; close one or share a camera")]
    TooManyViews(String),
    #[error("no open view has id '{0}' (views close after a minute unseen)")]
    UnknownView(String),
    #[error("view '{0}' has shown no frame yet")]
    NoFrame(String),
    #[error("no source has id '{0}'")]
    UnknownSource(String),
}

/// What the renderers' caches did since start: each refreshed only where
/// a source it reads changed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CacheWork {
    pub level_samples_written: u64,
    pub water_coverage_texels: u64,
    pub shadow_maps_drawn: u64,
    pub shadow_maps_redrawn_in_part: u64,
    pub shadow_maps_kept: u64,
    pub shadow_regions: u64,
    pub shadow_texels: u64,
    pub building_tiles_built: u64,
    pub instance_tiles_built: u64,
    pub detail_fits: u64,
}

impl CacheWork {
    fn add(&mut self, frame: &Frame) {
        let d = &frame.drawn;
        self.level_samples_written += frame.update.samples_written;
        self.water_coverage_texels += d.water_texels;
        self.shadow_maps_drawn += d.shadow_maps_drawn as u64;
        self.shadow_maps_redrawn_in_part += d.shadow_maps_redrawn_in_part as u64;
        self.shadow_maps_kept += d.shadow_maps_kept as u64;
        self.shadow_regions += d.shadow_regions as u64;
        self.shadow_texels += d.shadow_texels;
        self.building_tiles_built += d.building_tiles_built as u64;
        self.instance_tiles_built += d.instance_tiles_built as u64;
    }
}

/// A renderer, the generation it has seen and the manifest it drew with.
struct Seen {
    renderer: Renderer,
    generation: u64,
    manifest: Arc<Manifest>,
}

/// The detail's noise fitted to the height layer.
#[derive(Clone, Copy)]
struct DetailFit {
    /// The generation it was fitted at, and the one its noise last changed at.
    generation: u64,
    changed_at: u64,
    /// The grid area its fit read; None when it could not be fitted.
    area: Option<Extent>,
    detail: Option<Detail>,
}

/// Renderers by clipmap configuration, with the generation each has seen.
struct Renderers {
    gpu: Option<Arc<Gpu>>,
    /// By clipmap configuration and octaves of synthesized detail (0: none).
    by_config: HashMap<(ClipmapConfig, u32), Seen>,
    detail_fit: Option<DetailFit>,
    /// What the caches did since start (the detail's fits among it).
    work: CacheWork,
    /// Each pass's runs and time since start, over every renderer; built
    /// where some renderer now has it.
    passes: PassCounters,
}

impl Renderers {
    /// Fits the detail's noise to `snap` if it has not been, or if the
    /// height layer changed where the last fit read since.
    fn refit_detail(&mut self, scene: &Scene, snap: &SceneSnapshot, terrain: &SceneTerrain<'_>) {
        let height = snap.manifest.layers.get("height");
        if let Some(fit) = &mut self.detail_fit {
            if fit.generation == snap.generation {
                return;
            }
            let touched = scene.dirt_between(fit.generation, snap.generation).is_none_or(|regions| {
                regions
                    .iter()
                    .filter(|d| Some(&d.source_id) == height)
                    .any(|d| d.extents.iter().any(|e| fit.area.is_none_or(|a| a.overlaps(e))))
            });
            if !touched {
                fit.generation = snap.generation;
                return;
            }
        }
        let level = terrain.height_level();
        let at = level.and_then(|l| terrain.data_centre(l)).zip(level);
        let detail = at.and_then(|(at, level)| Detail::fit(terrain, at, level, Detail::DEFAULT_OCTAVES));
        // What the fit reads: 64 samples of the data's level round its
        // place, and 32 plus 5 of the level above round half of it.
        let area = at.map(|((x, y), level)| {
            let step = snap.grid.sample_step(level);
            let (cx, cy) = snap.grid.sample_point(level, x, y);
            let reach = 80.0 * step;
            Extent { min_x: cx - reach, min_y: cy - reach, max_x: cx + reach, max_y: cy + reach }
        });
        self.work.detail_fits += 1;
        let changed_at = match &self.detail_fit {
            Some(f) if f.detail == detail => f.changed_at,
            _ => snap.generation,
        };
        self.detail_fit = Some(DetailFit { generation: snap.generation, changed_at, area, detail });
    }

    /// What renderer `key` must refresh to draw `snap`: None when it has
    /// seen it; the whole grid when the dirt log lost generations it has
    /// not seen or the manifest was edited in what a frame draws (the
    /// sources an edit changed are dirt of their own); else the height and colour
    /// layers' extents (widened by the detail's reach below the data where
    /// it is drawn), the water layer's, and, when the detail's noise was
    /// fitted anew, every level below the data's.
    fn dirt_for(
        &self,
        scene: &Scene,
        snap: &SceneSnapshot,
        key: (ClipmapConfig, u32),
        detail: Option<Detail>,
    ) -> Option<Dirt> {
        let seen = self.by_config.get(&key)?;
        if seen.generation >= snap.generation && seen.manifest.draws_as(&snap.manifest) {
            return None;
        }
        let whole = Dirt::everything(snap.grid.extent());
        let regions = scene.dirt_between(seen.generation, snap.generation);
        let Some(regions) = regions.filter(|_| seen.manifest.draws_as(&snap.manifest)) else {
            return Some(whole);
        };
        let layer = |name: &str| snap.manifest.layers.get(name);
        let (height, color, water) = (layer("height"), layer("color"), layer("water"));
        // A synthesized sample reads the coarser ones round it: four-point
        // taps two samples out, halving at each finer level.
        let reach = detail.map_or(0.0, |d| 4.0 * snap.grid.sample_step(d.data_level));
        // The noise fitted anew changes every synthesized sample: the levels
        // below the data's are read again whole, the data's own keep theirs.
        let noise_changed = self.detail_fit.is_some_and(|f| f.changed_at > seen.generation);
        let mut dirt = Dirt { finer_than: detail.filter(|_| noise_changed).map(|d| d.data_level), ..Dirt::default() };
        for d in &regions {
            let id = Some(&d.source_id);
            if id == height || id == color {
                dirt.terrain.extend(d.extents.iter().map(|e| e.dilate(reach, reach)));
            }
            if id == water {
                dirt.water.extend_from_slice(&d.extents);
            }
        }
        Some(dirt)
    }

    /// Adds a frame's passes to the totals; built where a renderer has it.
    fn count_passes(&mut self, frame: &Frame) -> Vec<PassStats> {
        for &(name, ms) in &frame.passes {
            if relief_renderer::PASSES.contains(&name) {
                self.passes.add_run(name, ms);
            }
        }
        for &name in relief_renderer::PASSES {
            let built = self.by_config.values().any(|s| s.renderer.counters().is_built(name));
            self.passes.set_built(name, built);
        }
        self.passes.stats().to_vec()
    }
}

/// A rendered frame and what it shows.
pub struct Rendered {
    pub frame: Frame,
    pub generation: u64,
    pub camera: Camera,
    /// Every pass as of this frame (built, runs, milliseconds since start).
    pub passes: Vec<PassStats>,
    /// The sun it was lit by over its camera, and where that came from.
    pub sun: (SunAngles, Sun),
    /// The manifest it was drawn with.
    pub manifest: Arc<Manifest>,
    /// Shown again for a later generation that changed nothing it draws
    /// (a status change, a source no layer reads): not rendered again.
    pub carried_over: bool,
}

/// What the renderers did and hold, as of the last frame: read by the
/// scene state without waiting for the renderers' lock (held a whole
/// frame).
#[derive(Default)]
struct Report {
    work: CacheWork,
    held: Vec<(&'static str, u64)>,
    /// Effects the last frame computed, and what its pass cost (ms).
    effects_ran: BTreeMap<String, f64>,
    /// The renderer's passes as of the last frame.
    passes: Vec<relief_renderer::PassStats>,
}

pub struct Viewer {
    scene: Arc<Scene>,
    renderers: Mutex<Renderers>,
    report: Mutex<Report>,
    camera: watch::Sender<Camera>,
    permits: Semaphore,
    frames: std::sync::atomic::AtomicU64,
    models: ModelCache,
}

/// What a request may override of the manifest's quality: the clipmap,
/// the tile knobs, the instances' distance bands.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Overrides {
    pub clipmap: Option<ClipmapConfig>,
    pub quality: Option<Quality>,
    pub bands: Option<InstanceBands>,
    /// The sun of a request or a stream, over the scene's.
    pub sun: Option<Sun>,
    /// The effects' settings with this frame's quality knobs, over the
    /// scene's.
    pub effects: Option<EffectSettings>,
}

impl Viewer {
    /// A viewer over `scene`, its camera from the manifest or framing the
    /// height layer. Renderers refresh only what each new generation
    /// rebuilt (the scene's log of dirty extents).
    pub fn new(scene: &Arc<Scene>) -> Arc<Self> {
        let camera = watch::Sender::new(default_camera(&scene.snapshot()));
        Arc::new(Self {
            scene: Arc::clone(scene),
            report: Mutex::new(Report::default()),
            renderers: Mutex::new(Renderers {
                gpu: None,
                by_config: HashMap::new(),
                detail_fit: None,
                work: CacheWork::default(),
                passes: PassCounters::default(),
            }),
            camera,
            permits: Semaphore::new(MAX_RENDERS_IN_FLIGHT),
            frames: std::sync::atomic::AtomicU64::new(0),
            models: ModelCache::default(),
        })
    }

    /// The renderers, locked. A frame that panicked mid-way (a driver bug)
    /// leaves them in an unknown state: they are dropped and made anew,
    /// rather than every later frame failing.
    fn renderers(&self) -> std::sync::MutexGuard<'_, Renderers> {
        self.renderers.lock().unwrap_or_else(|poisoned| {
            self.renderers.clear_poison();
            let mut r = poisoned.into_inner();
            r.by_config.clear();
            tracing::error!("a frame failed part way; renderers are made anew");
            r
        })
    }

    pub fn camera(&self) -> Camera {
        *self.camera.borrow()
    }

    pub fn cameras(&self) -> watch::Receiver<Camera> {
        self.camera.subscribe()
    }

    /// Checks and sets the current camera.
    pub fn set_camera(&self, camera: Camera) -> Result<Camera, ViewError> {
        pose(&self.scene.snapshot(), &camera)?;
        self.camera.send_replace(camera);
        Ok(camera)
    }

    /// Renders from `camera` (the current one when None), as one of at
    /// most [`MAX_RENDERS_IN_FLIGHT`] single frames asked for at once.
    /// Blocking: call it from a blocking thread.
    pub fn render(
        &self,
        camera: Option<Camera>,
        width: u32,
        height: u32,
        overrides: Overrides,
    ) -> Result<Rendered, ViewError> {
        let _permit = self.permits.try_acquire().map_err(|_| ViewError::Busy)?;
        self.draw(camera, width, height, overrides)
    }

    /// Frames rendered since start.
    pub fn frames_rendered(&self) -> u64 {
        self.frames.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Renders a frame, waiting for the device: one frame at a time uses
    /// it. Blocking. The frame hub calls this for its streams, one at a
    /// time; single frames go through `render` and its limit.
    pub fn draw(
        &self,
        camera: Option<Camera>,
        width: u32,
        height: u32,
        overrides: Overrides,
    ) -> Result<Rendered, ViewError> {
        let Overrides { clipmap, quality, bands, sun, effects } = overrides;
        for (field, v) in [("width", width), ("height", height)] {
            if !(1..=MAX_IMAGE_SIDE).contains(&v) {
                return Err(RenderError::Request {
                    field,
                    message: format!("{v} is not from 1 to {MAX_IMAGE_SIDE} pixels"),
                }
                .into());
            }
        }
        let camera = camera.unwrap_or_else(|| self.camera());
        let snap = self.scene.snapshot();
        let pose = pose(&snap, &camera)?;
        let picture = crate::picture::Picture::of(&snap.manifest);
        let config = clipmap.unwrap_or(picture.clipmap);
        config.validate().map_err(|message| RenderError::Request { field: "quality.clipmap_grid_size", message })?;
        let terrain = SceneTerrain::new(&self.scene.store, &snap, quality.unwrap_or(snap.manifest.quality));
        let lighting = snap.manifest.effects.iter().any(|e| e == "lighting");
        let effects = effects.unwrap_or(picture.effect_settings);
        let mut guard = self.renderers();
        let r = &mut *guard;
        // Detail below the data: its noise fitted to the height layer over
        // the middle of the layer's data, again only when the height layer
        // changed there (a fit that fails, for nodata there, is kept too:
        // no detail, and the state says it did not run).
        let started = std::time::Instant::now();
        let detail = effects.detail_octaves.and_then(|octaves| {
            r.refit_detail(&self.scene, &snap, &terrain);
            r.detail_fit.and_then(|f| f.detail).map(|d| Detail { octaves, ..d })
        });
        let detail_surface = Surface::new(snap.grid.clone());
        let detailed = detail.map(|d| Detailed::new(&terrain, &detail_surface, d));
        let source: &dyn TerrainSamples = match &detailed {
            Some(d) => d,
            None => &terrain,
        };
        let fit_ms = started.elapsed().as_secs_f64() * 1e3;
        let key = (config, detail.map_or(0, |d| d.octaves));
        if r.gpu.is_none() {
            r.gpu = Some(Arc::new(Gpu::headless().map_err(|e| ViewError::NoDevice(e.to_string()))?));
        }
        let gpu = Arc::clone(r.gpu.as_ref().expect("opened above"));
        // A manifest edit may change the grid: start over then.
        r.by_config.retain(|_, seen| seen.renderer.surface().grid() == &snap.grid);
        if !r.by_config.contains_key(&key) {
            if r.by_config.len() >= 3 {
                r.by_config.clear();
            }
            let renderer = Renderer::new(gpu, Surface::new(snap.grid.clone()), config)?;
            let seen = Seen { renderer, generation: snap.generation, manifest: Arc::clone(&snap.manifest) };
            r.by_config.insert(key, seen);
        }
        let started = std::time::Instant::now();
        let dirt = r.dirt_for(&self.scene, &snap, key, detail);
        let seen = r.by_config.get_mut(&key).expect("inserted above");
        if let Some(dirt) = dirt {
            seen.renderer.invalidate(source, &dirt);
        }
        let refresh_ms = started.elapsed().as_secs_f64() * 1e3;
        (seen.generation, seen.manifest) = (snap.generation, Arc::clone(&snap.manifest));
        let renderer = &mut seen.renderer;
        let quality = quality.unwrap_or(snap.manifest.quality);
        let buildings = SceneBuildings::new(&self.scene.store, &snap, quality);
        let instances = SceneInstances::new(&self.scene.store, &snap, quality, &self.models);
        let layers = SceneLayers {
            // The water layer's source is read only for a scene with water.
            water: effects.water.map(|_| &terrain as &dyn relief_renderer::WaterSamples),
            buildings: buildings.as_ref().map(|b| b as &dyn relief_renderer::MeshTiles),
            instances: instances.as_ref().map(|i| i as &dyn relief_renderer::InstanceTiles),
        };
        let sun_spec = sun.unwrap_or(picture.sun);
        let sun = sun_spec
            .angles(camera.lon_deg, camera.lat_deg)
            .map_err(|message| RenderError::Request { field: "sun.time", message })?;
        let settings = RenderSettings {
            bands: bands.unwrap_or(picture.bands),
            sun,
            atmosphere: effects.atmosphere,
            fog: effects.fog,
            shadows: effects.shadows,
            water: effects.water,
            ..RenderSettings::new(width, height, lighting)
        };
        let mut frame = renderer.render_scene(source, layers, &pose, &settings)?;
        // Every millisecond of the frame in its timings: the detail's fit
        // and the caches refreshed over the generation's dirt come first.
        for (name, ms) in [("refresh caches", refresh_ms), ("fit detail", fit_ms)] {
            if ms >= 0.05 {
                frame.passes.insert(0, (name, ms));
            }
        }
        let mut ran = BTreeMap::new();
        // Lighting is shaded, and detail drawn, in the terrain pass.
        let terrain_ms = frame.passes.iter().find(|(p, _)| *p == "terrain").map_or(0.0, |(_, ms)| *ms);
        if lighting {
            ran.insert("lighting".to_owned(), terrain_ms);
        }
        if detail.is_some() {
            ran.insert("detail".to_owned(), terrain_ms);
        }
        for effect in ["shadows", "water", "atmosphere", "fog"] {
            if let Some((_, ms)) = frame.passes.iter().find(|(p, _)| *p == effect) {
                ran.insert(effect.to_owned(), *ms);
            }
        }
        for (pass, ms) in &frame.passes {
            metrics::histogram!("relief_render_pass_seconds", "pass" => *pass).record(ms / 1e3);
        }
        r.work.add(&frame);
        {
            let mut held: Vec<(&'static str, u64)> = Vec::new();
            for seen in r.by_config.values() {
                for (name, bytes) in seen.renderer.held_bytes() {
                    match held.iter_mut().find(|(n, _)| *n == name) {
                        Some((_, b)) => *b += bytes,
                        None => held.push((name, bytes)),
                    }
                }
            }
            let passes = r.count_passes(&frame);
            *self.report.lock().unwrap_or_else(std::sync::PoisonError::into_inner) =
                Report { work: r.work, held, effects_ran: ran, passes };
        }
        let passes = self.passes();
        self.frames.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(Rendered {
            frame,
            generation: snap.generation,
            camera,
            passes,
            sun: (sun, sun_spec),
            manifest: Arc::clone(&snap.manifest),
            carried_over: false,
        })
    }

    /// Whether a frame drawn at generation `since` with `manifest` (and
    /// `overrides`) would draw anything differently now: the manifest was
    /// edited in what frames draw (`Manifest::draws_as`), or a layer the
    /// frame draws (height, colour, buildings, instances; water where the
    /// frame has the effect) changed since. A generation that changed
    /// nothing drawn (a source turning to error, one no layer reads, its
    /// declaration edited) need not be rendered again.
    pub fn draws_differently(&self, since: u64, manifest: &Arc<Manifest>, overrides: &Overrides) -> bool {
        let snap = self.scene.snapshot();
        if !manifest.draws_as(&snap.manifest) {
            return true;
        }
        if since >= snap.generation {
            return false;
        }
        let water = overrides
            .effects
            .map_or_else(|| crate::picture::Picture::of(&snap.manifest).effect_settings.water, |e| e.water)
            .is_some();
        let drawn: Vec<&String> =
            snap.manifest.layers.iter().filter(|(name, _)| water || *name != "water").map(|(_, id)| id).collect();
        self.scene
            .dirt_between(since, snap.generation)
            .is_none_or(|regions| regions.iter().any(|d| drawn.contains(&&d.source_id)))
    }

    /// What the renderers hold, bytes, by part (each pass, the targets),
    /// summed over the renderers, as of the last frame.
    pub fn held_bytes(&self) -> Vec<(&'static str, u64)> {
        self.report.lock().unwrap_or_else(std::sync::PoisonError::into_inner).held.clone()
    }

    /// The effects the last frame computed (and their cost, ms), so the
    /// scene state shows that nothing else was.
    pub fn effects_ran(&self) -> BTreeMap<String, f64> {
        self.report.lock().unwrap_or_else(std::sync::PoisonError::into_inner).effects_ran.clone()
    }

    /// The renderer's passes as of the last frame; every pass unbuilt
    /// before the first.
    pub fn passes(&self) -> Vec<relief_renderer::PassStats> {
        let passes = self.report.lock().unwrap_or_else(std::sync::PoisonError::into_inner).passes.clone();
        if passes.is_empty() { PassCounters::default().stats().to_vec() } else { passes }
    }

    /// What the renderers' caches did since start.
    pub fn cache_work(&self) -> CacheWork {
        self.report.lock().unwrap_or_else(std::sync::PoisonError::into_inner).work
    }

    /// What the device is, once a frame has opened it.
    pub fn device(&self) -> Option<String> {
        self.renderers().gpu.as_ref().map(|g| g.description.clone())
    }
}
