//! Drawing a frame: the passes the scene calls for, one after another into
//! one target (each submitted and timed on its own), then the image and
//! depth read back. The renderer builds a pass only when a frame first
//! needs it, and counts what each cost.

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;
use relief_source::Extent;

use crate::camera::{Pose, View};
use crate::clipmap::{Clipmap, ClipmapConfig, TerrainSamples, UpdateStats};
use crate::dirt::Dirt;
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::passes::atmosphere::{Atmosphere, AtmospherePass, AtmosphereView};
use crate::passes::buildings::{BuildingsCasting, BuildingsPass, DrawnTerrain, MeshTiles};
use crate::passes::casting::ShadowCaster;
use crate::passes::counters::{self as passes, PassCounters};
use crate::passes::fog::{Fog, FogPass};
use crate::passes::instances::{InstanceBands, InstanceTiles, InstancesCasting, InstancesPass, InstancesView};
use crate::passes::overlay::Eye;
use crate::passes::shadows::{ShadowView, Shadows, ShadowsPass};
use crate::passes::terrain::{TerrainCasting, TerrainPass};
use crate::passes::water::{Water, WaterPass, WaterSamples, WaterView};
use crate::surface::Surface;
use crate::target::Target;
use crate::uniforms::{self, FrameUniform, split};

/// What a frame is drawn with besides the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// The scene's `lighting` effect: sun and ambient. Off, colours are
    /// drawn as they are.
    pub lighting: bool,
    /// The instances layer's distance bands.
    pub bands: InstanceBands,
    /// Leave out the terrain's level blocks wholly outside the view (the
    /// default). Exact: the image is the same either way; off, for
    /// benchmarks and the test that shows it.
    pub cull: bool,
    /// Where the sun stands over the camera.
    pub sun: SunAngles,
    /// The `atmosphere` effect, when the scene declares it.
    pub atmosphere: Option<Atmosphere>,
    /// The `fog` effect, when the scene declares it.
    pub fog: Option<Fog>,
    /// The `shadows` effect, when the scene declares it (with `lighting`,
    /// whose sunlight it takes away).
    pub shadows: Option<Shadows>,
    /// The `water` effect, when the scene declares it (its layer in
    /// `SceneLayers::water`).
    pub water: Option<Water>,
}

impl RenderSettings {
    /// A frame of `width` x `height`, lit or not, at default quality, the
    /// sun from the north-west 45 degrees up.
    pub const fn new(width: u32, height: u32, lighting: bool) -> Self {
        Self {
            width,
            height,
            lighting,
            bands: InstanceBands::DEFAULT,
            cull: true,
            sun: SunAngles::DEFAULT,
            atmosphere: None,
            fog: None,
            shadows: None,
            water: None,
        }
    }
}

/// The sun in the local sky: azimuth clockwise from north and elevation
/// above the horizon, degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunAngles {
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
}

impl SunAngles {
    /// From the north-west, 45 degrees up: the cartographer's light.
    pub const DEFAULT: Self = Self { azimuth_deg: 315.0, elevation_deg: 45.0 };

    /// How much daylight there is, 0 (night) to 1: a smooth step through
    /// civil twilight, from 6 degrees below the horizon to 6 above.
    pub fn daylight(self) -> f64 {
        let t = ((self.elevation_deg + 6.0) / 12.0).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }
}

/// The layers a frame draws besides the terrain: each pass is built only
/// for a scene that has its layer.
#[derive(Clone, Copy, Default)]
pub struct SceneLayers<'a> {
    pub buildings: Option<&'a dyn MeshTiles>,
    pub instances: Option<&'a dyn InstanceTiles>,
    /// The water layer, read only for a scene with the `water` effect.
    pub water: Option<&'a dyn WaterSamples>,
}

/// What a frame drew.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Drawn {
    /// The terrain levels' blocks (16 x 16 cells) with cells to draw;
    /// those drawn (inside the view and short of the planet's horizon);
    /// and those left out though inside the view's frustum, beyond the
    /// horizon.
    pub terrain_blocks: usize,
    pub terrain_blocks_drawn: usize,
    pub terrain_blocks_beyond_horizon: usize,
    pub buildings: usize,
    /// Instances within reach and in the view before the distance bands
    /// thin them; those drawn as models, and as billboards (one fading
    /// from one to the other counts in both).
    pub instances_in_view: usize,
    pub models: usize,
    pub billboards: usize,
    /// Shadow maps drawn whole this frame, redrawn in part (only the
    /// regions over what changed in the casters), and kept from the last
    /// one (the same cascades over the same casters); the regions redrawn
    /// and the map texels drawn in all.
    pub shadow_maps_drawn: usize,
    pub shadow_maps_redrawn_in_part: usize,
    pub shadow_maps_kept: usize,
    pub shadow_regions: usize,
    pub shadow_texels: u64,
    /// Texels of the water's coverage read again this frame.
    pub water_texels: u64,
    /// Building mesh tiles and instance tiles brought to the device.
    pub building_tiles_built: usize,
    pub instance_tiles_built: usize,
}

/// A rendered frame.
#[derive(Debug, Clone)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// RGBA8, row-major from the top left.
    pub rgba: Vec<u8>,
    /// Reversed-Z depth per pixel: `NEAR_M / distance along the view axis`, 0 for sky.
    pub depth: Vec<f32>,
    /// Wall time of each pass that ran, in order, then of the read-back;
    /// milliseconds.
    pub passes: Vec<(&'static str, f64)>,
    pub update: UpdateStats,
    pub view: View,
    /// What the buildings and instances passes drew (0 without them).
    pub drawn: Drawn,
}

pub struct Renderer {
    gpu: Arc<Gpu>,
    surface: Surface,
    frame_buffer: wgpu::Buffer,
    terrain: TerrainPass,
    /// Built the first time a frame has buildings to draw.
    buildings: Option<BuildingsPass>,
    /// Built the first time a frame has instances to draw.
    instances: Option<InstancesPass>,
    /// Built the first time a frame has an atmosphere.
    atmosphere: Option<AtmospherePass>,
    /// Built the first time a frame has fog.
    fog: Option<FogPass>,
    /// Built the first time a frame casts shadows.
    shadows: Option<ShadowsPass>,
    /// Built the first time a frame has water.
    water: Option<WaterPass>,
    counters: PassCounters,
    /// The last frame's target, drawn into again while the size stays.
    target: Option<Target>,
}

impl Renderer {
    pub fn new(gpu: Arc<Gpu>, surface: Surface, config: ClipmapConfig) -> Result<Self, RenderError> {
        let frame_buffer = uniforms::frame_buffer(&gpu.device);
        let terrain = TerrainPass::new(&gpu.device, &frame_buffer, config)?;
        let mut counters = PassCounters::default();
        counters.set_built(passes::TERRAIN, true);
        Ok(Self {
            gpu,
            surface,
            frame_buffer,
            terrain,
            buildings: None,
            instances: None,
            atmosphere: None,
            fog: None,
            shadows: None,
            water: None,
            counters,
            target: None,
        })
    }

    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    pub fn clipmap(&self) -> &Clipmap {
        self.terrain.clipmap()
    }

    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// What the renderer holds, bytes, by part: each pass built (its
    /// textures, buffers and the samples it keeps on the CPU), and the
    /// frame's target. On a GPU the textures and buffers are the device's
    /// memory; on lavapipe, the process's.
    pub fn held_bytes(&self) -> Vec<(&'static str, u64)> {
        let mut out = vec![(passes::TERRAIN, self.terrain.held_bytes())];
        out.extend(self.buildings.as_ref().map(|p| (passes::BUILDINGS, p.held_bytes())));
        out.extend(self.instances.as_ref().map(|p| (passes::INSTANCES, p.held_bytes())));
        out.extend(self.shadows.as_ref().map(|p| (passes::SHADOWS, p.held_bytes())));
        out.extend(self.water.as_ref().map(|p| (passes::WATER, p.held_bytes())));
        out.extend(self.atmosphere.as_ref().map(|p| (passes::ATMOSPHERE, p.held_bytes())));
        out.extend(self.target.as_ref().map(|t| ("target", t.held_bytes())));
        out
    }

    /// Each pass: built or not, runs, milliseconds in total.
    pub fn counters(&self) -> &PassCounters {
        &self.counters
    }

    /// The scene rebuilt tiles where `dirt` says: each cache refreshes
    /// only where a layer it reads changed (the terrain's samples and the
    /// shadow maps under them, the water's coverage).
    pub fn invalidate(&mut self, source: &dyn TerrainSamples, dirt: &Dirt) {
        if let Some(level) = dirt.finer_than {
            self.terrain.invalidate_finer_than(level);
        }
        for area in &dirt.terrain {
            self.terrain.invalidate(&self.gpu, &self.surface, source, area);
        }
        if let Some(water) = &mut self.water {
            for area in &dirt.water {
                water.invalidate(area);
            }
        }
    }

    /// Renders the view from `pose`: the terrain alone.
    pub fn render(
        &mut self,
        source: &dyn TerrainSamples,
        pose: &Pose,
        settings: &RenderSettings,
    ) -> Result<Frame, RenderError> {
        self.render_scene(source, SceneLayers::default(), pose, settings)
    }

    /// Renders the view from `pose`: the terrain, then the buildings and
    /// the instances the scene has (`layers`). A pass the scene does not
    /// call for is never built, and one built for a layer the scene no
    /// longer has goes with it.
    pub fn render_scene(
        &mut self,
        source: &dyn TerrainSamples,
        layers: SceneLayers<'_>,
        pose: &Pose,
        settings: &RenderSettings,
    ) -> Result<Frame, RenderError> {
        self.check(pose, settings)?;
        let view = self.surface.view(pose);
        let target = match self.target.take() {
            Some(target) if target.fits(settings.width, settings.height) => target,
            _ => Target::new(&self.gpu.device, settings.width, settings.height),
        };
        let mut passes = Vec::new();

        // The terrain, buildings and instances are made ready first, the
        // shadow maps drawn from them next, and only then is the frame's
        // colour drawn: the lit passes receive the shadows as they draw.
        // A pass's time is what it took in each of those steps.
        let started = Instant::now();
        let pixel_angle = pose.vertical_fov_deg.to_radians() / f64::from(settings.height);
        let aspect = f64::from(settings.width) / f64::from(settings.height);
        let frustum = settings.cull.then(|| view.frustum(aspect));
        let draw = self.terrain.prepare(&self.gpu, &self.surface, source, pose, &view, pixel_angle, frustum.as_ref());
        let frame_uniform = self.write_frame_uniform(pose, &view, settings, Some(draw.base_sink));
        self.terrain.write_records(&self.gpu.queue, &draw, &frame_uniform);

        // Where the eye is over what this frame draws, and the sun: what
        // the later passes ask of the frame, worked out once.
        let ground_m =
            self.terrain.drawn_height(&self.surface, &draw.update.active, pose, pose.position[0], pose.position[1]);
        let up = self.surface.enu(pose.position[0], pose.position[1])[2];
        let sun = self.sun(pose, settings.sun);
        let ground_radius_m = self.surface.is_planet().then(|| view.eye.length() - pose.position[2]);
        let above_ground_m = (pose.position[2] - ground_m.unwrap_or(0.0)).abs();
        let terrain_ms = started.elapsed().as_secs_f64() * 1e3;

        let (terrain_blocks, terrain_blocks_drawn, terrain_blocks_beyond_horizon) = draw.blocks();
        let mut drawn =
            Drawn { terrain_blocks, terrain_blocks_drawn, terrain_blocks_beyond_horizon, ..Drawn::default() };
        if layers.buildings.is_none() && self.buildings.take().is_some() {
            self.counters.set_built(passes::BUILDINGS, false);
        }
        let (mut buildings_shown, mut instances_shown) = (None, None);
        let (mut buildings_ms, mut instances_ms) = (0.0, 0.0);
        if let Some(meshes) = layers.buildings {
            let started = Instant::now();
            let device = &self.gpu.device;
            let buildings = self.buildings.get_or_insert_with(|| BuildingsPass::new(device));
            self.counters.set_built(passes::BUILDINGS, true);
            let (terrain, surface) = (&self.terrain, &self.surface);
            let ground = |x: f64, y: f64| terrain.drawn_height(surface, &draw.update.active, pose, x, y);
            let on = DrawnTerrain {
                surface,
                clipmap: terrain.clipmap(),
                active: &draw.update.active,
                ground: &ground,
                camera: (pose.position[0], pose.position[1]),
            };
            let built = buildings.tiles_built;
            let shown = buildings.prepare(device, &self.frame_buffer, &on, meshes);
            drawn.building_tiles_built = (buildings.tiles_built - built) as usize;
            drawn.buildings = shown.drawn;
            buildings_shown = Some(shown);
            buildings_ms = started.elapsed().as_secs_f64() * 1e3;
        }

        if layers.instances.is_none() && self.instances.take().is_some() {
            self.counters.set_built(passes::INSTANCES, false);
        }
        if let Some(tiles) = layers.instances {
            let started = Instant::now();
            let device = &self.gpu.device;
            let frame_buffer = &self.frame_buffer;
            let instances = self.instances.get_or_insert_with(|| InstancesPass::new(device, frame_buffer));
            self.counters.set_built(passes::INSTANCES, true);
            let at = InstancesView {
                surface: &self.surface,
                view: &view,
                aspect,
                camera: pose.position,
                ground_m,
                bands: &settings.bands,
            };
            let built = instances.tiles_built;
            let shown = instances.prepare(&self.gpu, &at, tiles)?;
            drawn.instance_tiles_built = (instances.tiles_built - built) as usize;
            (drawn.instances_in_view, drawn.models, drawn.billboards) =
                (shown.in_view, shown.models_drawn, shown.billboards_drawn);
            instances_shown = Some(shown);
            instances_ms = started.elapsed().as_secs_f64() * 1e3;
        }

        if settings.shadows.is_none() && self.shadows.take().is_some() {
            self.counters.set_built(passes::SHADOWS, false);
            self.terrain.drop_casters();
            self.buildings.iter_mut().for_each(BuildingsPass::drop_casters);
            self.instances.iter_mut().for_each(InstancesPass::drop_casters);
        }
        if let Some(shadows) = &settings.shadows {
            let started = Instant::now();
            let at = ShadowView {
                view: &view,
                aspect,
                sun,
                sin_elevation: sun.dot(up),
                above_ground_m,
                frame: frame_uniform,
            };
            if self.shadows.as_ref().is_some_and(|p| p.cascades != shadows.cascades) {
                self.shadows = None;
            }
            let pass = self.shadows.get_or_insert_with(|| ShadowsPass::new(&self.gpu.device, shadows.cascades));
            self.counters.set_built(passes::SHADOWS, true);
            let mut terrain = TerrainCasting {
                pass: &mut self.terrain,
                surface: &self.surface,
                draw: &draw,
                view: (&view, pose, pixel_angle),
                chosen: None,
            };
            let mut casters: Vec<&mut dyn ShadowCaster> = vec![&mut terrain];
            let mut buildings = self
                .buildings
                .as_mut()
                .zip(buildings_shown.as_ref())
                .map(|(pass, draw)| BuildingsCasting::new(pass, draw, view.eye));
            if let Some(b) = &mut buildings {
                casters.push(b);
            }
            let mut instances = (self.instances.as_mut().zip(instances_shown.as_ref()))
                .map(|(pass, draw)| InstancesCasting { pass, draw });
            if let Some(i) = &mut instances {
                casters.push(i);
            }
            pass.run(&self.gpu, &self.frame_buffer, shadows, &at, &mut casters)?;
            drop(casters);
            // The levels' records are the camera's again.
            self.terrain.write_records(&self.gpu.queue, &draw, &frame_uniform);
            let work = pass.work;
            (drawn.shadow_maps_drawn, drawn.shadow_maps_kept) = (work.drawn, work.kept);
            (drawn.shadow_maps_redrawn_in_part, drawn.shadow_regions, drawn.shadow_texels) =
                (work.redrawn_in_part, work.regions, work.texels);
            passes.push((passes::SHADOWS, self.counters.ran(passes::SHADOWS, started)));
        }

        // The frame's colour: the lit passes, receiving the shadows where
        // the scene casts them.
        let device = &self.gpu.device;
        // The cascades' layout and count, for the passes reading the maps.
        let receiver = self.shadows.as_ref().map(|p| (p.lookup_layout(), p.cascades));
        let lookup = self.shadows.as_ref().and_then(ShadowsPass::lookup);
        // Each pass's time: what making it ready took, then drawing it.
        let mut ran = |name: &'static str, ready_ms: f64, started: Instant| {
            let ms = ready_ms + started.elapsed().as_secs_f64() * 1e3;
            self.counters.add_run(name, ms);
            passes.push((name, ms));
        };
        let started = Instant::now();
        self.terrain.receive_shadows(device, receiver);
        let terrain = &self.terrain;
        target.run(&self.gpu, passes::TERRAIN, true, |pass| terrain.record(pass, &draw, lookup))?;
        ran(passes::TERRAIN, terrain_ms, started);
        if let (Some(buildings), Some(shown)) = (&mut self.buildings, &buildings_shown) {
            let started = Instant::now();
            buildings.receive_shadows(device, receiver);
            target.run(&self.gpu, passes::BUILDINGS, false, |pass| buildings.record(pass, shown, lookup))?;
            ran(passes::BUILDINGS, buildings_ms, started);
        }
        if let (Some(instances), Some(shown)) = (&mut self.instances, &instances_shown) {
            let started = Instant::now();
            instances.receive_shadows(device, receiver);
            target.run(&self.gpu, passes::INSTANCES, false, |pass| instances.record(pass, shown, lookup))?;
            ran(passes::INSTANCES, instances_ms, started);
        }

        // The effects laid over the frame read one eye, worked out once
        // (and not at all for a scene without them).
        let water = settings.water.zip(layers.water);
        let overlaid = settings.atmosphere.is_some() || settings.fog.is_some() || water.is_some();
        let eye = overlaid.then(|| Eye::new(view.view_projection(aspect), up, pose.position[2]));
        if water.is_none() && self.water.take().is_some() {
            self.counters.set_built(passes::WATER, false);
        }
        if let Some((knobs, samples)) = water {
            let started = Instant::now();
            let at = WaterView {
                eye: eye.unwrap_or_default(),
                sun_light: (frame_uniform.sun, frame_uniform.light),
                view_proj: view.view_projection(aspect),
                eye_world: view.eye,
                under: (pose.position[0], pose.position[1]),
                eye_height_m: pose.position[2],
                above_ground_m,
                ground_radius_m,
                surface: &self.surface,
                samples,
            };
            let pass = self.water.get_or_insert_with(|| WaterPass::new(&self.gpu, &self.frame_buffer));
            self.counters.set_built(passes::WATER, true);
            pass.run(&self.gpu, &self.frame_buffer, &target, &knobs, &at)?;
            drawn.water_texels = pass.texels_read;
            passes.push((passes::WATER, self.counters.ran(passes::WATER, started)));
        }
        let shadowed = settings.shadows.map(|s| s.cascades);
        if (settings.atmosphere.is_none() || self.atmosphere.as_ref().is_some_and(|a| a.shadowed != shadowed))
            && self.atmosphere.take().is_some()
        {
            self.counters.set_built(passes::ATMOSPHERE, false);
        }
        if let Some(atmosphere) = &settings.atmosphere {
            let started = Instant::now();
            let pass = self
                .atmosphere
                .get_or_insert_with(|| AtmospherePass::new(&self.gpu.device, &self.frame_buffer, receiver));
            self.counters.set_built(passes::ATMOSPHERE, true);
            let at = AtmosphereView {
                eye: eye.unwrap_or_default(),
                ground_radius_m,
                sun,
                shadows: self.shadows.as_ref().and_then(ShadowsPass::lookup),
            };
            pass.run(&self.gpu, &self.frame_buffer, &target, atmosphere, &at)?;
            passes.push((passes::ATMOSPHERE, self.counters.ran(passes::ATMOSPHERE, started)));
        }
        if settings.fog.is_none() && self.fog.take().is_some() {
            self.counters.set_built(passes::FOG, false);
        }
        if let Some(fog) = &settings.fog {
            let started = Instant::now();
            let pass = self.fog.get_or_insert_with(|| FogPass::new(&self.gpu.device, &self.frame_buffer));
            self.counters.set_built(passes::FOG, true);
            let daylight = settings.sun.daylight();
            let bind_group = pass.prepare(
                &self.gpu,
                &self.frame_buffer,
                target.depth_view(),
                fog,
                eye.unwrap_or_default(),
                daylight,
            );
            target.run_overlay(&self.gpu, passes::FOG, |p| pass.record(p, &bind_group))?;
            passes.push((passes::FOG, self.counters.ran(passes::FOG, started)));
        }

        let started = Instant::now();
        let (rgba, depth) = target.read_back(&self.gpu)?;
        passes.push(("read back", started.elapsed().as_secs_f64() * 1e3));
        self.target = Some(target);
        let (width, height, update) = (settings.width, settings.height, draw.update);
        Ok(Frame { width, height, rgba, depth, passes, update, view, drawn })
    }

    /// The drawn terrain's height over grid point (x, y) in the last frame
    /// (what buildings are lifted onto); None off the levels.
    pub fn drawn_height(&self, pose: &Pose, active: &[u8], x: f64, y: f64) -> Option<f64> {
        self.terrain.drawn_height(&self.surface, active, pose, x, y)
    }

    /// The brute-force reference: every sample of `area` (grid units) at
    /// tile level `level` as one mesh, drawn without the clipmap. For
    /// benchmarks and accuracy comparisons; None when the data is not
    /// ready. Its passes: "mesh" (building it) and "draw and read back".
    pub fn render_full_mesh(
        &self,
        source: &dyn TerrainSamples,
        level: u8,
        area: &Extent,
        pose: &Pose,
        settings: &RenderSettings,
    ) -> Result<Option<Frame>, RenderError> {
        self.check(pose, settings)?;
        let started = Instant::now();
        let view = self.surface.view(pose);
        let Some(mesh) = TerrainPass::full_mesh(&self.gpu.device, &self.surface, source, level, area, &view) else {
            return Ok(None);
        };
        self.write_frame_uniform(pose, &view, settings, None);
        let mesh_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        let target = Target::new(&self.gpu.device, settings.width, settings.height);
        target.run(&self.gpu, "full mesh", true, |pass| self.terrain.record_mesh(pass, &mesh))?;
        let (rgba, depth) = target.read_back(&self.gpu)?;
        let passes = vec![("mesh", mesh_ms), ("draw and read back", started.elapsed().as_secs_f64() * 1e3)];
        let update = UpdateStats::default();
        let (width, height) = (settings.width, settings.height);
        Ok(Some(Frame { width, height, rgba, depth, passes, update, view, drawn: Drawn::default() }))
    }

    fn check(&self, pose: &Pose, settings: &RenderSettings) -> Result<(), RenderError> {
        pose.validate(self.surface.is_planet())?;
        let max = self.gpu.max_size();
        for (field, v) in [("width", settings.width), ("height", settings.height)] {
            if v == 0 || v > max {
                return Err(RenderError::Request { field, message: format!("{v} is not from 1 to {max} pixels") });
            }
        }
        settings.bands.validate().map_err(|(field, message)| RenderError::Request { field, message })?;
        let sun = settings.sun;
        if !(sun.azimuth_deg.is_finite() && sun.elevation_deg.is_finite() && sun.elevation_deg.abs() <= 90.0) {
            return Err(RenderError::Request {
                field: "sun",
                message: format!(
                    "azimuth {} and elevation {} are not a place in the sky",
                    sun.azimuth_deg, sun.elevation_deg
                ),
            });
        }
        if let Some(atmosphere) = &settings.atmosphere {
            atmosphere.validate().map_err(|(field, message)| RenderError::Request { field, message })?;
        }
        if let Some(fog) = &settings.fog {
            fog.validate().map_err(|(field, message)| RenderError::Request { field, message })?;
        }
        if let Some(water) = &settings.water {
            water.validate().map_err(|(field, message)| RenderError::Request { field, message })?;
        }
        if let Some(shadows) = &settings.shadows {
            shadows.validate().map_err(|(field, message)| RenderError::Request { field, message })?;
            if !settings.lighting {
                return Err(RenderError::Request {
                    field: "shadows",
                    message: "shadows take away the lighting's sunlight: they need lighting on".into(),
                });
            }
            let max = self.gpu.max_size();
            if shadows.map_size > max {
                return Err(RenderError::Request {
                    field: "shadow_map_size",
                    message: format!("{} is larger than this device's {max} texels", shadows.map_size),
                });
            }
            let carried = self.gpu.device.limits().max_inter_stage_shader_variables as usize;
            if settings.atmosphere.is_some() && carried < AtmospherePass::SHADOWED_INPUTS {
                return Err(RenderError::Request {
                    field: "shadows",
                    message: format!(
                        "shadowed air needs {} values between shader stages; this device carries {carried}: declare shadows or atmosphere, not both",
                        AtmospherePass::SHADOWED_INPUTS
                    ),
                });
            }
        }
        Ok(())
    }

    /// `base_sink`: Some(metres the base is sunk) when meshes are drawn
    /// from double-single world positions; None for a mesh already
    /// relative to the eye.
    fn write_frame_uniform(
        &self,
        pose: &Pose,
        view: &View,
        settings: &RenderSettings,
        base_sink: Option<f64>,
    ) -> FrameUniform {
        let (eye_high, eye_low) = if base_sink.is_some() { split(view.eye) } else { ([0.0; 3], [0.0; 3]) };
        let frame = FrameUniform {
            view_proj: view.view_projection(f64::from(settings.width) / f64::from(settings.height)).to_cols_array_2d(),
            sun: {
                let d = self.sun(pose, settings.sun).as_vec3();
                [d.x, d.y, d.z, 0.0]
            },
            light: {
                // Night is dark (a little ambient left), never NaN.
                let day = settings.sun.daylight() as f32;
                [0.05 + 0.30 * day, 0.75 * day, if settings.lighting { 1.0 } else { 0.0 }, 0.0]
            },
            centre: {
                let c = (-view.eye).as_vec3();
                [c.x, c.y, c.z, if self.surface.is_planet() { 1.0 } else { 0.0 }]
            },
            eye_high: [eye_high[0], eye_high[1], eye_high[2], 0.0],
            eye_low: [eye_low[0], eye_low[1], eye_low[2], base_sink.unwrap_or(0.0) as f32],
        };
        self.gpu.queue.write_buffer(&self.frame_buffer, 0, bytemuck::bytes_of(&frame));
        frame
    }

    /// The direction towards the sun, in world axes, from its angles in the
    /// camera's local sky.
    fn sun(&self, pose: &Pose, sun: SunAngles) -> DVec3 {
        let [e, n, u] = self.surface.enu(pose.position[0], pose.position[1]);
        let (az, el) = (sun.azimuth_deg.to_radians(), sun.elevation_deg.to_radians());
        (az.sin() * e + az.cos() * n) * el.cos() + u * el.sin()
    }
}
