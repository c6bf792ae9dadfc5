//! The knobs, each a module that sweeps its settings against its
//! reference and returns one or more `Sweep`s, and what they share: the
//! device, a scratch folder, the demo scene (a synthetic range whose
//! heights are a formula, so every rendered pixel has a known answer).

mod analytic;
mod antialias;
mod atmosphere;
mod bands;
mod clipmap;
mod color_detail;
mod data;
mod detail;
mod frame_codec;
mod interleave;
mod precision;
mod reprojection;
mod resampling;
mod shadows;
mod terrain_mesh;
mod tile_size;

use std::path::PathBuf;
use std::sync::Arc;

use relief_daemon::scene::Scene;
use relief_renderer::{ClipmapConfig, Frame, Gpu, Pose, RenderSettings, Renderer, SceneLayers, Surface, WaterSamples};

use crate::sweep::Sweep;

/// A knob's sweep function.
pub type Run = fn(&Context) -> anyhow::Result<Vec<Sweep>>;

/// Every knob, in the report's order.
pub const ALL: &[(&str, Run)] = &[
    ("resampling", resampling::run),
    ("reprojection", reprojection::run),
    ("tile_size", tile_size::run),
    ("antialias", antialias::run),
    ("clipmap", clipmap::run),
    ("color_detail", color_detail::run),
    ("precision", precision::run),
    ("atmosphere", atmosphere::run),
    ("shadows", shadows::run),
    ("detail", detail::run),
    ("bands", bands::run),
    ("frame_codec", frame_codec::run),
    ("terrain_mesh", terrain_mesh::run),
];

/// What every knob's sweep may use.
pub struct Context {
    pub gpu: Arc<Gpu>,
    pub dir: tempfile::TempDir,
    /// The demo scene's manifest, written once.
    pub demo: PathBuf,
}

impl Context {
    pub fn new() -> anyhow::Result<Self> {
        let dir = tempfile::tempdir()?;
        let demo = relief_examples::write_demo_scene(&dir.path().join("demo"))?;
        // Tiles are timed as generated, never read back from a disk cache
        // an earlier knob or run left.
        let text = std::fs::read_to_string(&demo)?;
        anyhow::ensure!(!text.contains("[cache]"), "the demo manifest has a [cache] section already");
        std::fs::write(&demo, format!("{text}\n[cache]\ndisk_mb = 0\n"))?;
        Ok(Self { gpu: Arc::new(Gpu::headless()?), dir, demo })
    }

    /// A scene loaded in process (tile pool of 2), every source loaded.
    #[expect(clippy::unused_self, reason = "a knob loads its scenes through its context, as it renders through it")]
    pub fn load(&self, manifest: &std::path::Path) -> anyhow::Result<Scene> {
        match Scene::load_checked(manifest, false, 2, relief_daemon::picture::check) {
            Ok((scene, _)) => Ok(scene),
            Err(errors) => {
                let lines: Vec<String> = errors.iter().map(ToString::to_string).collect();
                anyhow::bail!("scene {} does not load: {}", manifest.display(), lines.join("; "))
            }
        }
    }
}

/// The demo's camera: 9 km up, 25 degrees down, over the range.
pub fn demo_pose() -> Pose {
    Pose {
        position: [6.45, 44.95 + 10.0 * 25.0 / 111_320.0, 9000.0],
        heading_deg: 15.0,
        pitch_deg: -25.0,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    }
}

pub const HD: RenderSettings = RenderSettings::new(1280, 720, true);

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The sum of a frame's pass times, ms.
pub fn frame_ms(frame: &Frame) -> f64 {
    frame.passes.iter().map(|(_, ms)| ms).sum()
}

/// `runs` still frames from `at` with `config`, after one that fills the
/// levels and builds the tiles and passes (not kept).
pub fn still_frames(
    gpu: &Arc<Gpu>,
    terrain: &relief_daemon::view::SceneTerrain<'_>,
    grid: &relief_source::TileGrid,
    config: ClipmapConfig,
    settings: &RenderSettings,
    at: &Pose,
    runs: usize,
) -> anyhow::Result<Vec<Frame>> {
    let mut renderer = Renderer::new(Arc::clone(gpu), Surface::new(grid.clone()), config)?;
    let layers = SceneLayers { water: settings.water.map(|_| terrain as &dyn WaterSamples), ..SceneLayers::default() };
    renderer.render_scene(terrain, layers, at, settings)?;
    (0..runs).map(|_| Ok(renderer.render_scene(terrain, layers, at, settings)?)).collect()
}

/// RMS and max difference of two frames' R, G and B (0-255), over every pixel.
pub fn rgb_difference(a: &Frame, b: &Frame) -> (f64, f64) {
    rgba_difference(&a.rgba, &b.rgba)
}

/// RMS and max difference of two RGBA8 images' R, G and B (0-255).
pub fn rgba_difference(a: &[u8], b: &[u8]) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    for (p, q) in a.chunks(4).zip(b.chunks(4)) {
        for k in 0..3 {
            let d = f64::from(p[k]) - f64::from(q[k]);
            sum += d * d;
            max = max.max(d.abs());
            n += 1;
        }
    }
    ((sum / n.max(1) as f64).sqrt(), max)
}
