//! `color_detail` (colour samples per mesh sample along a side, 1, 2 or
//! 4): the demo range unlit at 1280 x 720 from its camera, each terrain
//! pixel's colour against the tint the demo's orthophoto was made from,
//! at the ground point the pixel's depth gives.

use std::sync::Arc;

use glam::DVec3;
use relief_daemon::view::SceneTerrain;
use relief_renderer::{ClipmapConfig, Frame, Pose, RenderSettings, Renderer, Surface};
use relief_source::geodesy;

use super::interleave::interleaved;
use super::{Context, demo_pose};
use crate::sweep::{Row, Sweep};

/// Frames timed per setting (after one not timed), the settings in turn.
const ROUNDS: usize = 15;
/// Unlit: the colours as the layers give them, so the tint is the answer.
const UNLIT: RenderSettings = RenderSettings::new(1280, 720, false);
/// The orthophoto `write_demo_scene` writes: its north-west corner and pixel, degrees.
const ORTHO_ORIGIN: (f64, f64) = (6.0, 45.6);
const ORTHO_PIXEL_DEG: f64 = 0.002;

/// The ground point (lon, lat) of every 2nd pixel of every 2nd row that
/// shows the DEM away from its edges and its void, with the pixel's index.
fn ground_pixels(frame: &Frame) -> Vec<(usize, f64, f64)> {
    let [w0, s0, e0, n0] = relief_examples::DEMO_EXTENT;
    let mut out = Vec::new();
    for py in (0..frame.height).step_by(2) {
        for px in (0..frame.width).step_by(2) {
            let i = (py * frame.width + px) as usize;
            let depth = frame.depth[i];
            if depth <= 0.0 {
                continue;
            }
            let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), frame.width, frame.height, depth);
            let p: DVec3 = frame.view.eye + dir * distance;
            let (lon, lat, _) = geodesy::geodetic_from_ecef(p.to_array());
            if !(w0 + 0.01..e0 - 0.01).contains(&lon)
                || !(s0 + 0.01..n0 - 0.01).contains(&lat)
                || relief_examples::in_demo_void(lon, lat)
            {
                continue;
            }
            out.push((i, lon, lat));
        }
    }
    out
}

/// The tint at (lon, lat): the colour the orthophoto samples.
fn tint(lon: f64, lat: f64) -> [f64; 3] {
    relief_examples::demo_color(relief_examples::demo_terrain(lon, lat)).map(f64::from)
}

/// The orthophoto itself read bilinearly between its pixel centres at
/// (lon, lat): the best any colour detail can draw from it.
fn ortho_bilinear(lon: f64, lat: f64) -> [f64; 3] {
    let u = (lon - ORTHO_ORIGIN.0) / ORTHO_PIXEL_DEG - 0.5;
    let v = (ORTHO_ORIGIN.1 - lat) / ORTHO_PIXEL_DEG - 0.5;
    let (i, j) = (u.floor(), v.floor());
    let (fu, fv) = (u - i, v - j);
    let at = |i: f64, j: f64| {
        let (x, y) = (ORTHO_ORIGIN.0 + (i + 0.5) * ORTHO_PIXEL_DEG, ORTHO_ORIGIN.1 - (j + 0.5) * ORTHO_PIXEL_DEG);
        tint(x, y)
    };
    let (a, b, c, d) = (at(i, j), at(i + 1.0, j), at(i, j + 1.0), at(i + 1.0, j + 1.0));
    [0, 1, 2].map(|k| (a[k] * (1.0 - fu) + b[k] * fu) * (1.0 - fv) + (c[k] * (1.0 - fu) + d[k] * fu) * fv)
}

/// RMS and max of (drawn - tint) over `pixels`' R, G and B (0-255).
fn color_error(frame: &Frame, pixels: &[(usize, f64, f64)]) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    for &(i, lon, lat) in pixels {
        let want = tint(lon, lat);
        for (k, w) in want.iter().enumerate() {
            let d = f64::from(frame.rgba[i * 4 + k]) - w;
            sum += d * d;
            max = max.max(d.abs());
            n += 1;
        }
    }
    ((sum / n.max(1) as f64).sqrt(), max)
}

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let scene = cx.load(&cx.demo)?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let configs: Vec<ClipmapConfig> = [127usize, 63]
        .into_iter()
        .flat_map(|n| [1usize, 2, 4].map(|color_detail| ClipmapConfig { color_detail, ..ClipmapConfig::new(n, 8) }))
        .collect();
    let mut renderers = configs
        .iter()
        .map(|&config| Ok(Renderer::new(Arc::clone(&cx.gpu), Surface::new(snap.grid.clone()), config)?))
        .collect::<anyhow::Result<Vec<Renderer>>>()?;
    // Each renderer in turn flies 25 m north (a frame that fetches and
    // uploads the strips of samples that came into view, colour detail's
    // other cost), then draws a still frame there: setting 2k is config
    // k flying, 2k + 1 the same still. The error is measured after, back
    // at the demo's camera.
    let at = demo_pose();
    let mut steps = vec![0u32; configs.len()];
    let frames = interleaved(2 * configs.len(), ROUNDS, false, |k| {
        let c = k / 2;
        if k % 2 == 0 {
            steps[c] += 1;
        }
        let [lon, lat, h] = at.position;
        let moved = Pose { position: [lon, lat + f64::from(steps[c]) * 25.0 / 111_320.0, h], ..at };
        Ok(renderers[c].render(&terrain, &moved, &UNLIT)?)
    })?;
    let (flying, timed): (Vec<_>, Vec<_>) = frames.into_iter().enumerate().partition(|(k, _)| k % 2 == 0);
    let mut rows = Vec::new();
    let mut floor = None;
    for (((config, (_, timed)), (_, flying)), renderer) in configs.iter().zip(&timed).zip(&flying).zip(&mut renderers) {
        // The error at the demo's own camera: back there, then a still frame.
        renderer.render(&terrain, &at, &UNLIT)?;
        let frame = renderer.render(&terrain, &at, &UNLIT)?;
        let pixels = ground_pixels(&frame);
        let (rms, max) = color_error(&frame, &pixels);
        if floor.is_none() {
            let (mut sum, mut count) = (0.0, 0usize);
            for &(_, lon, lat) in &pixels {
                let (want, got) = (tint(lon, lat), ortho_bilinear(lon, lat));
                sum += (0..3).map(|k| (got[k] - want[k]).powi(2)).sum::<f64>();
                count += 3;
            }
            floor = Some(((sum / count.max(1) as f64).sqrt(), pixels.len()));
        }
        let side = config.color_detail * config.n;
        rows.push(
            Row::new(format!("{} (n {})", config.color_detail, config.n), timed.frame_ms(), rms)
                .default_if(*config == ClipmapConfig::default())
                .with("max error", format!("{max:.0}"))
                .with("colour texels a level", format!("{side} x {side}"))
                .with("terrain pass ms", format!("{:.1}", timed.pass_ms("terrain")))
                .with("flying frame ms", format!("{:.1}", flying.frame_ms()))
                .with("colour MiB", format!("{:.1}", (side * side * 4 * config.levels) as f64 / 1_048_576.0)),
        );
    }
    let (floor, judged) = floor.unwrap_or((f64::NAN, 0));
    let why_default = why(&rows, floor);
    Ok(vec![Sweep {
        knob: "color_detail".into(),
        case: format!(
            "The demo range unlit (the layers' colours as they are) at 1280 x 720 from its camera, 9 km up and 25 \
             degrees down, with 8 levels of n 127 (the default) and of n 63, whose levels reach half as far so more of \
             the view is drawn by coarse ones. {judged} ground pixels judged (every 2nd of every 2nd row on the DEM, \
             away from its edges and void). The orthophoto is 0.002 degree pixels of the tint; read bilinearly between \
             its pixel centres at the same ground points it is itself {floor:.2} RMS from the tint, a floor no colour \
             detail can go under. Each renderer in turn flies 25 m north (the flying frame fetches and uploads the \
             samples that come into view) and then draws a still frame there; each time is the fastest of {ROUNDS} \
             (the machine is shared: the fastest is the least disturbed). The colour's memory is the levels' colour \
             textures."
        ),
        reference:
            "the tint the demo's orthophoto is made of, demo_color(demo_terrain(lon, lat)), at the ground point \
                    each pixel's depth gives (f64)"
                .into(),
        error: "RMS difference of R, G and B over the terrain pixels (0-255)".into(),
        time: format!("still frame ms, fastest of {ROUNDS}"),
        rows,
        why_default,
    }])
}

/// Why 2, from the rows `run` measured.
fn why(rows: &[Row], floor: f64) -> String {
    let get = |c: usize, n: usize| {
        let name = format!("{c} (n {n})");
        rows.iter().find(|r| r.setting == name).map_or((f64::NAN, f64::NAN), |r| (r.error, r.time))
    };
    let ((e1, t1), (e2, t2), (e4, t4)) = (get(1, 127), get(2, 127), get(4, 127));
    let ((f1, _), (f2, _), (f4, _)) = (get(1, 63), get(2, 63), get(4, 63));
    format!(
        "Colour read from the tile level below the mesh's (2) takes the error from {e1:.2} to {e2:.2} at n 127 \
         ({f1:.2} to {f2:.2} at n 63, where coarser levels draw more of the view); 4 gains only {:.2} more at n 127 \
         ({e4:.2}, against the orthophoto's own floor of {floor:.2}), because near the camera the levels are already \
         finer than the orthophoto's 0.002 degree pixels, for four times the colour memory and four times the colour \
         samples fetched and uploaded as the camera moves. At n 63 it still pays ({f4:.2}), where the levels are \
         coarse enough that colour a level finer is still new information. The frame times ({t1:.1}, {t2:.1} and \
         {t4:.1} ms at n 127) differ by no more than this shared machine's noise: on lavapipe the cost that shows is \
         memory, not drawing.",
        e2 - e4
    )
}
