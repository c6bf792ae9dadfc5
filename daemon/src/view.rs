//! Rendered views of the scene: the camera, the terrain the renderer reads
//! (answered from the tile store), and one shared GPU device behind a lock.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::{Arc, Mutex};

use relief_renderer::{
    ClipmapConfig, Detail, Detailed, Frame, Gpu, InstanceBands, PassCounters, PassStats, RenderError, RenderSettings,
    Renderer, SceneLayers, Surface, TerrainSamples,
};
use relief_source::{Extent, Quality};
use tokio::sync::{Semaphore, watch};

pub use crate::camera::Camera;
use crate::camera::{default_camera, pose};
use crate::effects::EffectSettings;
use crate::scene::{EventKind, Scene};
pub use crate::scene_tiles::{ModelCache, SceneBuildings, SceneInstances, SceneTerrain};
use crate::sun::{Sun, SunAngles};

/// The largest image side a request may ask for.
pub const MAX_IMAGE_SIDE: u32 = 4096;
/// Renders running or waiting for the device at once; more are refused.
pub const MAX_RENDERS_IN_FLIGHT: usize = 4;
/// Generations of dirt remembered for renderers that fall behind.
const DIRT_LOG: usize = 64;

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

/// Renderers by clipmap configuration, with the generation each has seen.
struct Renderers {
    gpu: Option<Arc<Gpu>>,
    /// By clipmap configuration and octaves of synthesized detail (0: none).
    by_config: HashMap<(ClipmapConfig, u32), (Renderer, u64)>,
    /// The detail's noise fitted to the height layer, and the generation
    /// it was fitted at.
    detail_fit: Option<(u64, Option<Detail>)>,
    /// (generation, extents it dirtied), oldest first.
    dirt: VecDeque<(u64, Vec<Extent>)>,
    /// Each pass's runs and time since start, over every renderer; built
    /// where some renderer now has it.
    passes: PassCounters,
}

impl Renderers {
    /// Adds a frame's passes to the totals; built where a renderer has it.
    fn count_passes(&mut self, frame: &Frame) -> Vec<PassStats> {
        for &(name, ms) in &frame.passes {
            if relief_renderer::PASSES.contains(&name) {
                self.passes.add_run(name, ms);
            }
        }
        for &name in relief_renderer::PASSES {
            let built = self.by_config.values().any(|(r, _)| r.counters().is_built(name));
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
}

pub struct Viewer {
    scene: Arc<Scene>,
    renderers: Mutex<Renderers>,
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
    /// height layer. Keeps a log of dirty areas so renderers refresh only
    /// what a new generation rebuilt.
    pub fn new(scene: &Arc<Scene>) -> Arc<Self> {
        let camera = watch::Sender::new(default_camera(&scene.snapshot()));
        let viewer = Arc::new(Self {
            scene: Arc::clone(scene),
            renderers: Mutex::new(Renderers {
                gpu: None,
                by_config: HashMap::new(),
                detail_fit: None,
                dirt: VecDeque::new(),
                passes: PassCounters::default(),
            }),
            camera,
            permits: Semaphore::new(MAX_RENDERS_IN_FLIGHT),
            frames: std::sync::atomic::AtomicU64::new(0),
            models: ModelCache::default(),
        });
        let weak = Arc::downgrade(&viewer);
        let mut events = scene.events();
        tokio::spawn(async move {
            while let Ok(event) = events.recv().await {
                let Some(viewer) = weak.upgrade() else { break };
                if let EventKind::Generation { dirty, .. } = event.kind {
                    let extents = dirty.into_iter().flat_map(|d| d.extents).collect();
                    let mut r = viewer.renderers();
                    r.dirt.push_back((event.generation, extents));
                    while r.dirt.len() > DIRT_LOG {
                        r.dirt.pop_front();
                    }
                }
            }
        });
        viewer
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
        let config = clipmap.unwrap_or(snap.manifest.clipmap);
        config.validate().map_err(|message| RenderError::Request { field: "quality.clipmap_grid_size", message })?;
        let terrain = SceneTerrain::new(&self.scene.store, &snap, quality.unwrap_or(snap.manifest.quality));
        let lighting = snap.manifest.effects.iter().any(|e| e == "lighting");
        let effects = effects.unwrap_or(snap.manifest.effect_settings);
        let mut guard = self.renderers();
        let r = &mut *guard;
        // Detail below the data: its noise fitted to the height layer once
        // a generation, over the middle of the layer's data.
        // (A fit that fails, for nodata there, is kept too: no detail this
        // generation, and the state says it did not run.)
        let detail = effects.detail_octaves.and_then(|octaves| {
            if r.detail_fit.is_none_or(|(g, _)| g != snap.generation) {
                let level = terrain.height_level();
                let at = level.and_then(|l| terrain.data_centre(l)).zip(level);
                let fit = at.and_then(|(at, level)| Detail::fit(&terrain, at, level, octaves));
                r.detail_fit = Some((snap.generation, fit));
            }
            r.detail_fit.and_then(|(_, d)| d).map(|d| Detail { octaves, ..d })
        });
        let detail_surface = Surface::new(snap.grid.clone());
        let detailed = detail.map(|d| Detailed::new(&terrain, &detail_surface, d));
        let source: &dyn TerrainSamples = match &detailed {
            Some(d) => d,
            None => &terrain,
        };
        let key = (config, detail.map_or(0, |d| d.octaves));
        if r.gpu.is_none() {
            r.gpu = Some(Arc::new(Gpu::headless().map_err(|e| ViewError::NoDevice(e.to_string()))?));
        }
        let gpu = Arc::clone(r.gpu.as_ref().expect("opened above"));
        // A manifest edit may change the grid: start over then.
        r.by_config.retain(|_, (renderer, _)| renderer.surface().grid() == &snap.grid);
        if !r.by_config.contains_key(&key) {
            if r.by_config.len() >= 3 {
                r.by_config.clear();
            }
            let renderer = Renderer::new(gpu, Surface::new(snap.grid.clone()), config)?;
            r.by_config.insert(key, (renderer, snap.generation));
        }
        let oldest = r.dirt.front().map_or(u64::MAX, |(g, _)| *g);
        let (renderer, seen) = r.by_config.get_mut(&key).expect("inserted above");
        if *seen < snap.generation {
            // Detail refitted to a new generation changes every synthesized sample.
            if oldest > *seen + 1 || detail.is_some() {
                renderer.invalidate(source, &snap.grid.extent());
            }
            for (_, extents) in r.dirt.iter().filter(|(g, _)| *g > *seen && *g <= snap.generation) {
                for e in extents {
                    renderer.invalidate(source, e);
                }
            }
            *seen = snap.generation;
        }
        let quality = quality.unwrap_or(snap.manifest.quality);
        let buildings = SceneBuildings::new(&self.scene.store, &snap, quality);
        let instances = SceneInstances::new(&self.scene.store, &snap, quality, &self.models);
        let layers = SceneLayers {
            // The water layer's source is read only for a scene with water.
            water: effects.water.map(|_| &terrain as &dyn relief_renderer::WaterSamples),
            buildings: buildings.as_ref().map(|b| b as &dyn relief_renderer::MeshTiles),
            instances: instances.as_ref().map(|i| i as &dyn relief_renderer::InstanceTiles),
        };
        let sun_spec = sun.unwrap_or(snap.manifest.sun);
        let sun = sun_spec
            .angles(camera.lon_deg, camera.lat_deg)
            .map_err(|message| RenderError::Request { field: "sun.time", message })?;
        let settings = RenderSettings {
            bands: bands.unwrap_or(snap.manifest.bands),
            sun,
            atmosphere: effects.atmosphere,
            fog: effects.fog,
            shadows: effects.shadows,
            water: effects.water,
            ..RenderSettings::new(width, height, lighting)
        };
        let frame = renderer.render_scene(source, layers, &pose, &settings)?;
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
        self.scene.set_effects_ran(ran);
        for (pass, ms) in &frame.passes {
            metrics::histogram!("relief_render_pass_seconds", "pass" => *pass).record(ms / 1e3);
        }
        let passes = r.count_passes(&frame);
        self.scene.set_passes(passes.clone());
        self.frames.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(Rendered { frame, generation: snap.generation, camera, passes, sun: (sun, sun_spec) })
    }

    /// What the device is, once a frame has opened it.
    pub fn device(&self) -> Option<String> {
        self.renderers().gpu.as_ref().map(|g| g.description.clone())
    }
}
