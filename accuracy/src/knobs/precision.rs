//! `precision`: why the GPU gets eye-relative f32. The renderer keeps
//! positions in f64 on the CPU and gives the GPU each level's samples as f32
//! offsets from a per-level anchor, plus the anchor's offset from the eye
//! (worked out in f64, then made f32). Here the clipmap's vertices under a
//! camera at the demo's place are taken to the screen on the CPU each way,
//! against f64 all the way: no device is needed, and none is used.

use std::hint::black_box;
use std::time::Instant;

use glam::{DVec3, Mat4, Vec3, Vec4};
use relief_renderer::{Clipmap, ClipmapConfig, Pose, Surface, View};
use relief_source::{MAX_LEVEL, TileGrid, geodesy};

use super::{Context, demo_pose, median};
use crate::sweep::{Row, Sweep};

const WIDTH: f64 = 1280.0;
const HEIGHT: f64 = 720.0;
/// Camera heights above the ground, metres, with their column names.
const HEIGHTS: [(f64, &str); 4] = [(1.0, "1 m"), (10.0, "10 m"), (100.0, "100 m"), (9000.0, "9 km")];
/// Times each way is run to take the median of.
const RUNS: usize = 15;

/// The ways of taking a world point to the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Way {
    /// f64 throughout: the reference.
    F64,
    /// The renderer's: f32 offsets from an anchor, plus the anchor's
    /// offset from the eye (f64 on the CPU, then f32), an f32 matrix.
    EyeRelative,
    /// The buildings' way: the world position and the eye each split into
    /// an f32 high part and remainder, subtracted in two steps.
    DoubleSingle,
    /// Absolute f32 ECEF through an f32 view-projection holding the eye.
    Absolute,
}

impl Way {
    const ALL: [Way; 4] = [Way::F64, Way::EyeRelative, Way::DoubleSingle, Way::Absolute];

    fn label(self) -> &'static str {
        match self {
            Way::F64 => "f64 throughout (the reference)",
            Way::EyeRelative => "f32 eye-relative, per-level anchors (the renderer)",
            Way::DoubleSingle => "f32 double-single eye (as buildings)",
            Way::Absolute => "f32 absolute ECEF",
        }
    }
}

/// One clipmap level as the GPU would get it each way.
struct Level {
    /// World positions (f64): the reference's input.
    world: Vec<DVec3>,
    /// Offsets from the anchor, f32 (as `ClipLevel` stores them).
    relative: Vec<Vec3>,
    anchor: DVec3,
    /// High and low f32 parts of the world positions.
    high: Vec<Vec3>,
    low: Vec<Vec3>,
    /// The world positions rounded to f32.
    absolute: Vec<Vec3>,
}

/// The camera `height_m` above the demo's ground at its place, looking as
/// the demo does.
fn camera(height_m: f64) -> Pose {
    let base = demo_pose();
    let [lon, lat, _] = base.position;
    Pose { position: [lon, lat, relief_examples::demo_terrain(lon, lat) + height_m], ..base }
}

/// The clipmap's levels for `pose` (n 127, 8 levels) down to the finest the
/// camera's height asks for, as fine data or detail octaves would give:
/// each an n x n window of samples on the demo's formula, centred under
/// the camera, its anchor 2n samples east and 2n north of the window's
/// middle (a little past the farthest the renderer lets a level's window
/// move from its anchor before filling it again).
fn levels(surface: &Surface, pose: &Pose) -> Vec<Level> {
    let config = ClipmapConfig::default();
    let clipmap = Clipmap::new(config);
    let [x, y, h] = pose.position;
    let pixel_angle = pose.vertical_fov_deg.to_radians() / HEIGHT;
    let ground = relief_examples::demo_terrain(x, y);
    let (finest, coarsest) = clipmap.level_range(surface, h - ground, MAX_LEVEL - 1, pixel_angle);
    let n = config.n as i64;
    (coarsest..=finest)
        .map(|level| {
            let origin = clipmap.placement(surface, level, x, y, None);
            let (ax, ay) = surface.sample_point(level, origin.0 + n / 2 + 2 * n, origin.1 + n / 2 + 2 * n);
            let anchor = surface.world(ax, ay, 0.0);
            let world: Vec<DVec3> = (origin.1..origin.1 + n)
                .flat_map(|gy| (origin.0..origin.0 + n).map(move |gx| (gx, gy)))
                .map(|(gx, gy)| {
                    let (lon, lat) = surface.sample_point(level, gx, gy);
                    DVec3::from(geodesy::ecef_from_geodetic(lon, lat, relief_examples::demo_terrain(lon, lat)))
                })
                .collect();
            let relative = world.iter().map(|p| (*p - anchor).as_vec3()).collect();
            let high: Vec<Vec3> = world.iter().map(|p| p.as_vec3()).collect();
            let low = world.iter().zip(&high).map(|(p, h)| (*p - h.as_dvec3()).as_vec3()).collect();
            let absolute = high.clone();
            Level { world, relative, anchor, high, low, absolute }
        })
        .collect()
}

/// Clip coordinates to the pixel (x, y), pixel centres at .5.
fn pixel(clip: Vec4) -> (f64, f64) {
    let (x, y) = (f64::from(clip.x / clip.w), f64::from(clip.y / clip.w));
    (f64::midpoint(x, 1.0) * WIDTH, (1.0 - y) / 2.0 * HEIGHT)
}

/// Every vertex of `level` to the screen `way`: pixel (x, y), and whether
/// it is in front of the eye.
fn project(level: &Level, view: &View, way: Way, out: &mut Vec<(f64, f64, bool)>) {
    out.clear();
    let aspect = WIDTH / HEIGHT;
    let view_proj = view.view_projection(aspect);
    match way {
        Way::F64 => {
            let tan = (view.vertical_fov_deg.to_radians() / 2.0).tan();
            for p in &level.world {
                let d = *p - view.eye;
                let z = d.dot(view.forward);
                let (sx, sy) = (d.dot(view.right) / z / (tan * aspect), d.dot(view.up) / z / tan);
                out.push((f64::midpoint(sx, 1.0) * WIDTH, (1.0 - sy) / 2.0 * HEIGHT, z > 0.0));
            }
        }
        Way::EyeRelative => {
            let offset = (level.anchor - view.eye).as_vec3();
            for p in &level.relative {
                let clip = view_proj * (*p + offset).extend(1.0);
                let (x, y) = pixel(clip);
                out.push((x, y, clip.w > 0.0));
            }
        }
        Way::DoubleSingle => {
            let eye_high = view.eye.as_vec3();
            let eye_low = (view.eye - eye_high.as_dvec3()).as_vec3();
            for (h, l) in level.high.iter().zip(&level.low) {
                let clip = view_proj * ((*h - eye_high) + (*l - eye_low)).extend(1.0);
                let (x, y) = pixel(clip);
                out.push((x, y, clip.w > 0.0));
            }
        }
        Way::Absolute => {
            let m = view_proj * Mat4::from_translation(-view.eye.as_vec3());
            for p in &level.absolute {
                let clip = m * p.extend(1.0);
                let (x, y) = pixel(clip);
                out.push((x, y, clip.w > 0.0));
            }
        }
    }
}

/// The largest screen error `way` makes against f64 over the vertices the
/// reference puts on the screen, pixels, and how many those are.
fn max_error(levels: &[Level], view: &View, way: Way) -> (f64, usize) {
    let (mut reference, mut got) = (Vec::new(), Vec::new());
    let (mut max, mut count) = (0.0f64, 0usize);
    for level in levels {
        project(level, view, Way::F64, &mut reference);
        project(level, view, way, &mut got);
        for (r, g) in reference.iter().zip(&got) {
            let on_screen = r.2 && (0.0..WIDTH).contains(&r.0) && (0.0..HEIGHT).contains(&r.1);
            if !on_screen {
                continue;
            }
            count += 1;
            // Behind the eye where the reference is in front: as wrong as
            // a vertex can be.
            let e = if g.2 { (g.0 - r.0).hypot(g.1 - r.1) } else { f64::INFINITY };
            max = max.max(e);
        }
    }
    (max, count)
}

/// CPU ms to take one level's n x n vertices to the screen `way`, median of `RUNS`.
fn time_per_level(levels: &[Level], view: &View, way: Way) -> f64 {
    let mut out = Vec::with_capacity(levels[0].world.len());
    let times = (0..RUNS)
        .map(|_| {
            let started = Instant::now();
            for level in levels {
                project(black_box(level), black_box(view), way, &mut out);
                black_box(&out);
            }
            started.elapsed().as_secs_f64() * 1e3 / levels.len() as f64
        })
        .collect();
    median(times)
}

pub fn run(_: &Context) -> anyhow::Result<Vec<Sweep>> {
    let surface = Surface::new(TileGrid::geodetic(256).map_err(anyhow::Error::msg)?);
    let cases: Vec<(Pose, Vec<Level>)> = HEIGHTS
        .iter()
        .map(|&(h, _)| {
            let pose = camera(h);
            let levels = levels(&surface, &pose);
            (pose, levels)
        })
        .collect();
    let mut rows = Vec::new();
    let mut seen = Vec::new();
    let mut errors: Vec<(Way, Vec<f64>)> = Vec::new();
    for way in Way::ALL {
        let mut worst = 0.0f64;
        let mut columns = Vec::new();
        let mut by_height = Vec::new();
        for ((pose, levels), (_, name)) in cases.iter().zip(HEIGHTS) {
            let view = surface.view(pose);
            let (max, count) = max_error(levels, &view, way);
            if way == Way::F64 {
                seen.push(format!(
                    "{name}: {count} vertices on screen, spacing {:.3} to {:.0} m",
                    spacing(levels, levels.len() - 1),
                    spacing(levels, 0)
                ));
            }
            worst = worst.max(max);
            by_height.push(max);
            columns.push((format!("max error at {name} px"), crate::report::number(max)));
        }
        let (pose, levels) = &cases[cases.len() - 1];
        let time = time_per_level(levels, &surface.view(pose), way);
        let mut row = Row::new(way.label(), time, worst).default_if(way == Way::EyeRelative);
        for (header, value) in columns {
            row = row.with(header, value);
        }
        rows.push(row);
        errors.push((way, by_height));
    }
    let at = |way: Way| errors.iter().find(|(w, _)| *w == way).map_or(&[][..], |(_, e)| e.as_slice());
    let (relative, double, absolute) = (at(Way::EyeRelative), at(Way::DoubleSingle), at(Way::Absolute));
    let worst = |e: &[f64]| e.iter().copied().fold(0.0, f64::max);
    let n = crate::report::number;
    let why_default = format!(
        "Absolute f32 ECEF is {} px off at 1 m, {} px at 10 m and {} px at 100 m: this far from the Earth's centre f32 \
         holds a position only to half a metre, so nearby ground jitters and tears; only from 9 km ({} px) is it under \
         a pixel. The renderer's way keeps every vertex within {} px at all four heights, with each level's anchor \
         farther off than it ever gets. The double-single way is more exact still ({} px) but needs every position as \
         two f32 vectors, twice the levels' position textures and reads, for a gain no one can see; the renderer keeps \
         it for buildings, meshes in world positions with no level to anchor to. The CPU times are all of a size (a \
         few multiply-adds a vertex either way) and say nothing of the choice, which is accuracy alone.",
        n(absolute.first().copied().unwrap_or(f64::NAN)),
        n(absolute.get(1).copied().unwrap_or(f64::NAN)),
        n(absolute.get(2).copied().unwrap_or(f64::NAN)),
        n(absolute.get(3).copied().unwrap_or(f64::NAN)),
        n(worst(relative)),
        n(worst(double)),
    );
    let n = ClipmapConfig::default().n;
    Ok(vec![Sweep {
        knob: "precision (eye-relative f32 on the GPU)".into(),
        case: format!(
            "Not a manifest knob: the renderer's design. A camera 1 m, 10 m, 100 m and 9 km above the demo's ground at \
             its place (6.45 E, 44.95 N, heading 15, 25 degrees down, 50 degree field of view, 1280 x 720); under it \
             the default clipmap's 8 levels of {n} x {n} samples on the demo's formula, the finest as fine as the \
             camera's height asks for (as fine data or detail octaves give; {}). Each level's anchor is 2n samples \
             east and 2n north of its window's middle, a little past the farthest the renderer lets it drift (2n \
             samples from the window's corner) before filling the level again. Every vertex is taken to the screen on \
             the CPU each way, in IEEE f32 as the GPU would (a shader compiler may reorder f32 sums; none here). The \
             time is the CPU's, to take one level's {n} x {n} vertices to the screen, median of {RUNS}: it shows the \
             arithmetic each way does, not what a frame costs. On the GPU the three f32 ways cost the same (one f32 \
             matrix by vector per vertex; the double-single way subtracts twice and carries twice the vertex data); \
             f64 is not in WGSL at all.",
            seen.join("; ")
        ),
        reference:
            "f64 throughout: the world position (ECEF from relief_source::geodesy) less the eye, projected in f64"
                .into(),
        error: "largest screen error of a vertex on screen, over the four heights, pixels".into(),
        time: format!("CPU ms per level of {n} x {n} vertices, median of {RUNS}"),
        rows,
        why_default,
    }])
}

/// The sample spacing of `levels[k]` at its middle, metres (along a meridian).
fn spacing(levels: &[Level], k: usize) -> f64 {
    let w = &levels[k].world;
    let n = ClipmapConfig::default().n;
    (w[n / 2 * n + n / 2] - w[(n / 2 + 1) * n + n / 2]).length()
}
