//! The view calls: the scene camera, single frames, frame streams through
//! the hub, views of the viewers' own, gestures and picks. Transports
//! (gRPC, HTTP) are thin adapters over these.

use std::pin::Pin;
use std::sync::Arc;
use std::time::Instant;

use relief_proto::v1::{
    Camera, FrameDrawn, ImageFormat, NavigateRequest, OpenViewRequest, PassTiming, PickRequest, PickResponse,
    QualityOverrides, RenderRequest, RenderResponse, SetCameraRequest, StreamFramesRequest, Sun, SunPosition,
    UpdateViewRequest, ViewState, navigate_request,
};
use relief_renderer::ClipmapConfig;
use tokio_stream::{Stream, StreamExt, wrappers::ReceiverStream};
use tokio_util::sync::CancellationToken;
use tonic::Status;

use crate::codec::Codec;
use crate::effects::EffectSettings;
use crate::frames::{CameraSource, FrameFormat, FrameHub, HubFrame, OpenView, StreamSpec, ViewSettings};
use crate::navigate::{Gesture, navigate, pick};
use crate::scene::Scene;
use crate::service::auth::{Holder, Scope};
use crate::service::convert;
use crate::service::status::{from_view_error as status, invalid_field};
use crate::view::{MAX_IMAGE_SIDE, Overrides, Viewer};

/// Fastest StreamFrames rate a viewer may ask for.
const MAX_FPS: f64 = 60.0;
/// Slowest: a frame a minute at most between frames.
const MIN_FPS: f64 = 1.0 / 60.0;

/// A stream of frames as a transport sends it.
pub type Frames = Pin<Box<dyn Stream<Item = Result<RenderResponse, Status>> + Send>>;

pub struct ViewCalls {
    scene: Arc<Scene>,
    hub: Arc<FrameHub>,
    /// Ends frame streams when reliefd stops.
    shutdown: CancellationToken,
}

/// A frame request checked and in relief's own types.
#[derive(Clone, Copy)]
struct FrameRequest {
    camera: Option<crate::view::Camera>,
    width: u32,
    height: u32,
    format: FrameFormat,
    overrides: Overrides,
}

/// A request's image format: unspecified is PNG for one frame, and for a
/// stream JPEG while its view is interactive and PNG at rest.
fn frame_format(format: i32, stream: bool, jpeg_quality: u8) -> Result<FrameFormat, Status> {
    match ImageFormat::try_from(format) {
        Ok(ImageFormat::Unspecified) if stream => Ok(FrameFormat::Live(jpeg_quality)),
        Ok(ImageFormat::Unspecified | ImageFormat::Png) => Ok(FrameFormat::Png),
        Ok(ImageFormat::Jpeg) => Ok(FrameFormat::Jpeg(jpeg_quality)),
        Ok(ImageFormat::Rgba8) => Ok(FrameFormat::Rgba),
        Err(_) => Err(invalid_field("format", format!("{format} is not an image format"))),
    }
}

fn frame_request(
    scene: &Scene,
    camera: Option<&Camera>,
    (width, height): (u32, u32),
    (format, stream): (i32, bool),
    overrides: Option<&QualityOverrides>,
    sun: Option<&Sun>,
) -> Result<FrameRequest, Status> {
    let snap = scene.snapshot();
    let picture = crate::picture::Picture::of(&snap.manifest);
    let jpeg_quality = overrides
        .and_then(|o| o.frame_jpeg_quality)
        .map(|q| crate::picture::jpeg_quality(q).map_err(|e| invalid_field("quality.frame_jpeg_quality", e)))
        .transpose()?
        .unwrap_or(picture.frame_jpeg_quality);
    let format = frame_format(format, stream, jpeg_quality)?;
    if let Some(o) = overrides {
        // Knobs of effects not drawn yet: refused, never ignored.
        if o.precision.is_some() {
            return Err(invalid_field(
                "quality.precision",
                "no renderer precision to choose yet (f64 on the CPU, eye-relative f32 on the GPU)",
            ));
        }
    }
    let effects = overrides.map(|o| effect_overrides(&picture.effect_settings, o)).transpose()?;
    let clipmap = overrides.and_then(|o| {
        (o.clipmap_grid_size.is_some() || o.clipmap_levels.is_some() || o.color_detail.is_some()).then(|| {
            ClipmapConfig {
                n: o.clipmap_grid_size.map_or(picture.clipmap.n, |n| n as usize),
                levels: o.clipmap_levels.map_or(picture.clipmap.levels, |l| l as usize),
                color_detail: o.color_detail.map_or(picture.clipmap.color_detail, |d| d as usize),
            }
        })
    });
    if let Some(c) = clipmap {
        c.validate().map_err(|e| invalid_field("quality.clipmap_grid_size", e))?;
    }
    let quality = overrides.map(|o| convert::quality(snap.manifest.quality, Some(o))).transpose()?;
    let (width, height) = (if width == 0 { 1280 } else { width }, if height == 0 { 720 } else { height });
    for (field, v) in [("width", width), ("height", height)] {
        if v > MAX_IMAGE_SIDE {
            return Err(invalid_field(field, format!("{v} is not from 1 to {MAX_IMAGE_SIDE} pixels")));
        }
    }
    let camera = camera.map(|c| checked_camera(&snap, c)).transpose()?;
    let bands = overrides.map(|o| convert::bands(picture.bands, o)).transpose()?.flatten();
    let sun = sun
        .map(|s| {
            let time = (!s.time.is_empty()).then_some(s.time.as_str());
            if time.is_none() && s.azimuth_deg.is_none() && s.elevation_deg.is_none() {
                return Err(invalid_field("sun", "give a time or an azimuth and an elevation"));
            }
            let sun = crate::sun::Sun::parse(time, s.azimuth_deg, s.elevation_deg)
                .map_err(|(field, message)| invalid_field(&format!("sun.{field}"), message))?;
            if !snap.manifest.effects.iter().any(|e| crate::manifest::SUNLIT.contains(&e.as_str())) {
                return Err(invalid_field(
                    "sun",
                    format!(
                        "no effect of the scene follows the sun (it declares none of {})",
                        crate::manifest::SUNLIT.join(", ")
                    ),
                ));
            }
            Ok(sun)
        })
        .transpose()?;
    Ok(FrameRequest { camera, width, height, format, overrides: Overrides { clipmap, quality, bands, sun, effects } })
}

/// A request's camera in relief's types, checked against the scene (every
/// field in range, placeable in the grid's CRS).
fn checked_camera(snap: &crate::graph::SceneSnapshot, c: &Camera) -> Result<crate::view::Camera, Status> {
    let camera = convert::camera_from(c);
    crate::camera::pose(snap, &camera).map_err(|e| Status::invalid_argument(e.to_string()))?;
    Ok(camera)
}

/// A frame as relief.v1 answers it, encoded now if not yet (the encoding
/// is a pass timing: "encode png", "encode jpeg").
pub fn response(frame: &HubFrame, format: FrameFormat) -> Result<RenderResponse, Status> {
    let f = &frame.rendered.frame;
    let mut passes: Vec<PassTiming> =
        f.passes.iter().map(|(pass, ms)| PassTiming { pass: (*pass).into(), elapsed_ms: *ms }).collect();
    let (format, image) = match format.codec(frame.interactive) {
        Some(codec) => {
            let (image, ms) = frame.encoded(codec).map_err(Status::internal)?;
            let (format, name) = match codec {
                Codec::Png => (ImageFormat::Png, "encode png"),
                Codec::Jpeg(_) => (ImageFormat::Jpeg, "encode jpeg"),
            };
            passes.push(PassTiming { pass: name.into(), elapsed_ms: ms });
            (format, image)
        }
        None => (ImageFormat::Rgba8, frame.rgba.clone()),
    };
    Ok(RenderResponse {
        carried_over: frame.carried_over,
        generation: frame.generation,
        width: f.width,
        height: f.height,
        format: format as i32,
        image,
        passes,
        camera: Some(convert::camera_to(&frame.rendered.camera)),
        pass_counters: convert::pass_states(&frame.rendered.passes),
        drawn: Some(FrameDrawn {
            buildings: f.drawn.buildings as u32,
            models: f.drawn.models as u32,
            billboards: f.drawn.billboards as u32,
            terrain_blocks: f.drawn.terrain_blocks as u32,
            terrain_blocks_drawn: f.drawn.terrain_blocks_drawn as u32,
            terrain_blocks_beyond_horizon: f.drawn.terrain_blocks_beyond_horizon as u32,
            shadow_maps_drawn: f.drawn.shadow_maps_drawn as u32,
            shadow_maps_kept: f.drawn.shadow_maps_kept as u32,
            shadow_maps_redrawn_in_part: f.drawn.shadow_maps_redrawn_in_part as u32,
            shadow_regions: f.drawn.shadow_regions as u32,
            shadow_texels: f.drawn.shadow_texels,
            water_coverage_texels: f.drawn.water_texels,
            level_samples_written: f.update.samples_written,
            building_tiles_built: f.drawn.building_tiles_built as u32,
            instance_tiles_built: f.drawn.instance_tiles_built as u32,
        }),
        sun: {
            let (angles, spec) = &frame.rendered.sun;
            Some(SunPosition {
                azimuth_deg: angles.azimuth_deg,
                elevation_deg: angles.elevation_deg,
                source: spec.describe(),
            })
        },
    })
}

fn view_state(view: &OpenView, scene_camera: crate::view::Camera) -> ViewState {
    let s = view.settings();
    ViewState {
        view_id: view.id.clone(),
        camera: Some(convert::camera_to(if s.follow_scene_camera { &scene_camera } else { &s.camera })),
        follow_scene_camera: s.follow_scene_camera,
        interactive: s.interactive,
    }
}

impl ViewCalls {
    pub fn new(scene: Arc<Scene>, hub: Arc<FrameHub>, shutdown: CancellationToken) -> Self {
        Self { scene, hub, shutdown }
    }

    fn viewer(&self) -> &Arc<Viewer> {
        self.hub.viewer()
    }

    pub fn set_camera(&self, scope: Scope, r: &SetCameraRequest) -> Result<Camera, Status> {
        scope.require_control("move the scene camera")?;
        let camera = r.camera.as_ref().ok_or_else(|| invalid_field("camera", "missing"))?;
        let set = self.viewer().set_camera(convert::camera_from(camera)).map_err(|e| status(&e))?;
        Ok(convert::camera_to(&set))
    }

    pub fn camera(&self) -> Camera {
        convert::camera_to(&self.viewer().camera())
    }

    /// One frame, rendered for this call alone (at most four at once).
    pub async fn render(&self, r: &RenderRequest) -> Result<RenderResponse, Status> {
        let req = frame_request(
            &self.scene,
            r.camera.as_ref(),
            (r.width, r.height),
            (r.format, false),
            r.quality.as_ref(),
            r.sun.as_ref(),
        )?;
        let viewer = Arc::clone(self.viewer());
        tokio::task::spawn_blocking(move || {
            let rendered = viewer.render(req.camera, req.width, req.height, req.overrides).map_err(|e| status(&e))?;
            response(&HubFrame::new(rendered, false), req.format)
        })
        .await
        .map_err(|e| Status::internal(format!("the render task failed: {e}")))?
    }

    /// Frames of the scene camera, a fixed camera or an open view, shared
    /// through the hub with every stream that shows the same.
    pub fn stream_frames(&self, r: &StreamFramesRequest) -> Result<Frames, Status> {
        let req = frame_request(
            &self.scene,
            r.camera.as_ref(),
            (r.width, r.height),
            (r.format, true),
            r.quality.as_ref(),
            r.sun.as_ref(),
        )?;
        let fps = if r.max_fps == 0.0 { 10.0 } else { r.max_fps };
        if !(fps.is_finite() && (MIN_FPS..=MAX_FPS).contains(&fps)) {
            return Err(invalid_field("max_fps", format!("{fps} is not from 1/60 (a frame a minute) to {MAX_FPS}")));
        }
        let source = if !r.view_id.is_empty() {
            CameraSource::View(self.hub.views.get(&r.view_id).map_err(|e| status(&e))?)
        } else if let Some(camera) = req.camera {
            CameraSource::Fixed(camera)
        } else {
            CameraSource::Scene
        };
        let spec = StreamSpec {
            source,
            width: req.width,
            height: req.height,
            overrides: req.overrides,
            max_fps: fps,
            format: req.format,
            interactive_scale: crate::picture::Picture::of(&self.scene.snapshot().manifest).interactive_scale,
        };
        let frames = crate::frames::start(&self.hub, spec, self.shutdown.clone()).map_err(|e| status(&e))?;
        let format = req.format;
        Ok(Box::pin(ReceiverStream::new(frames).map(move |f| match f {
            Ok(frame) => response(&frame, format),
            Err(e) => Err(status(&e)),
        })))
    }

    /// A view of the caller's own: only a call with the same token (or a
    /// control token) may steer it.
    pub fn open_view(&self, holder: Holder, r: &OpenViewRequest) -> Result<ViewState, Status> {
        let scene_camera = self.viewer().camera();
        let camera = match &r.camera {
            Some(c) => checked_camera(&self.scene.snapshot(), c)?,
            None => scene_camera,
        };
        let settings = ViewSettings { camera, follow_scene_camera: r.follow_scene_camera, interactive: false };
        let view = self.hub.views.open(settings, holder).map_err(|e| status(&e))?;
        Ok(view_state(&view, scene_camera))
    }

    pub fn update_view(&self, scope: Scope, holder: Holder, r: &UpdateViewRequest) -> Result<ViewState, Status> {
        let view = self.hub.views.get(&r.view_id).map_err(|e| status(&e))?;
        may_steer(&view, scope, holder)?;
        let camera = r.camera.as_ref().map(|c| checked_camera(&self.scene.snapshot(), c)).transpose()?;
        let scene_camera = self.viewer().camera();
        view.update(|s| {
            if let Some(c) = camera {
                s.camera = c;
            }
            if let Some(f) = r.follow_scene_camera {
                // A view that stops following keeps the pose it shows, not
                // the one it had before it followed.
                if s.follow_scene_camera && !f && camera.is_none() {
                    s.camera = scene_camera;
                }
                s.follow_scene_camera = f;
            }
            if let Some(i) = r.interactive {
                s.interactive = i;
            }
        });
        Ok(view_state(&view, self.viewer().camera()))
    }

    /// Moves the view's camera, or the scene camera (with no view, or a
    /// view that follows it), by a gesture: on a view of the caller's own
    /// (read scope, the token that opened it), or on the scene's camera,
    /// which every viewer follows (control scope), whichever way the call
    /// names it.
    pub async fn navigate(&self, scope: Scope, holder: Holder, r: NavigateRequest) -> Result<Camera, Status> {
        let gesture = match r.gesture {
            Some(navigate_request::Gesture::Orbit(o)) => {
                Gesture::Orbit { heading_deg: o.heading_deg, pitch_deg: o.pitch_deg }
            }
            Some(navigate_request::Gesture::Pan(p)) => {
                Gesture::Pan { from: (p.from_x, p.from_y), to: (p.to_x, p.to_y) }
            }
            Some(navigate_request::Gesture::Zoom(z)) => Gesture::Zoom { factor: z.factor, at: (z.x, z.y) },
            Some(navigate_request::Gesture::Move(m)) => {
                Gesture::Move { forward: m.forward, right: m.right, up: m.up, turn_deg: m.turn_deg }
            }
            Some(navigate_request::Gesture::FlyToSource(id)) => Gesture::FlyTo(id),
            None => return Err(invalid_field("gesture", "missing: orbit, pan, zoom, move or fly_to_source")),
        };
        let view =
            (!r.view_id.is_empty()).then(|| self.hub.views.get(&r.view_id)).transpose().map_err(|e| status(&e))?;
        if let Some(v) = &view {
            may_steer(v, scope, holder)?;
        }
        let follows = view.as_ref().is_none_or(|v| v.settings().follow_scene_camera);
        if follows {
            scope.require_control(if view.is_some() {
                "move the scene camera, which this view follows,"
            } else {
                "move the scene camera"
            })?;
        }
        let camera = match &view {
            Some(v) if !follows => v.settings().camera,
            _ => self.viewer().camera(),
        };
        let frame = view.as_ref().and_then(|v| v.last_frame());
        let snap = self.scene.snapshot();
        let moved = tokio::task::spawn_blocking(move || navigate(&snap, &camera, frame.as_deref(), &gesture))
            .await
            .map_err(|e| Status::internal(format!("the navigation task failed: {e}")))?
            .map_err(|e| status(&e))?;
        match view {
            Some(v) if !follows => {
                v.update(|s| s.camera = moved);
            }
            _ => {
                self.viewer().set_camera(moved).map_err(|e| status(&e))?;
            }
        }
        Ok(convert::camera_to(&moved))
    }

    /// Back to the scene's default view (the manifest's `[camera]`, its
    /// gaps filled to frame the height layer): the view's camera, or the
    /// scene camera when the view follows it (control scope).
    pub async fn home(&self, scope: Scope, holder: Holder, view_id: &str) -> Result<Camera, Status> {
        let view = self.hub.views.get(view_id).map_err(|e| status(&e))?;
        may_steer(&view, scope, holder)?;
        let follows = view.settings().follow_scene_camera;
        if follows {
            scope.require_control("move the scene camera, which this view follows,")?;
        }
        let snap = self.scene.snapshot();
        let home = tokio::task::spawn_blocking(move || {
            let camera = crate::camera::default_camera(&snap);
            let kept = crate::camera::pose(&snap, &camera)
                .map(|p| crate::navigate::keep_in_scene(&snap, &p))
                .ok()
                .and_then(|p| crate::camera::camera_of(&snap, &p).ok());
            kept.unwrap_or(camera)
        })
        .await
        .map_err(|e| Status::internal(format!("the home task failed: {e}")))?;
        if follows {
            self.viewer().set_camera(home).map_err(|e| status(&e))?;
        } else {
            view.update(|s| s.camera = home);
        }
        Ok(convert::camera_to(&home))
    }

    /// The point under a pixel of the view's last frame.
    pub async fn pick(&self, r: &PickRequest) -> Result<PickResponse, Status> {
        let view = self.hub.views.get(&r.view_id).map_err(|e| status(&e))?;
        let frame = view.last_frame().ok_or_else(|| status(&crate::view::ViewError::NoFrame(r.view_id.clone())))?;
        let snap = self.scene.snapshot();
        let at = (r.x, r.y);
        let generation = frame.generation;
        let started = Instant::now();
        let picked = tokio::task::spawn_blocking(move || pick(&snap, &frame, at))
            .await
            .map_err(|e| Status::internal(format!("the pick task failed: {e}")))?
            .map_err(|e| status(&e))?;
        tracing::debug!(elapsed_ms = started.elapsed().as_secs_f64() * 1e3, "picked");
        Ok(picked.map_or(PickResponse { generation, ..PickResponse::default() }, |p| PickResponse {
            hit: true,
            lon_deg: p.lon_deg,
            lat_deg: p.lat_deg,
            surface_height_m: p.surface_height_m,
            ground_height_m: p.ground_height_m,
            distance_m: p.distance_m,
            generation: p.generation,
        }))
    }
}

/// `Ok` when the caller may steer `view`: it opened it (the same token),
/// or it holds a control token.
fn may_steer(view: &OpenView, scope: Scope, holder: Holder) -> Result<(), Status> {
    if view.owner == holder || scope == Scope::Control {
        return Ok(());
    }
    Err(Status::permission_denied(format!(
        "view '{}' was opened with another token: only that token (or a control token) may steer it",
        view.id
    )))
}

/// The scene's effect settings with a request's quality knobs over them,
/// each refused where the scene does not declare its effect.
fn effect_overrides(scene: &EffectSettings, o: &QualityOverrides) -> Result<EffectSettings, Status> {
    let mut effects = *scene;
    let knobs = [
        ("atmosphere_steps", o.atmosphere_steps),
        ("shadow_cascades", o.shadow_cascades),
        ("shadow_map_size", o.shadow_map_size),
        ("detail_octaves", o.detail_octaves),
    ];
    for (name, value) in knobs {
        if let Some(value) = value {
            effects
                .set_quality(name, value)
                .map_err(|(knob, message)| invalid_field(&format!("quality.{knob}"), message))?;
        }
    }
    Ok(effects)
}
