//! Shadows' accuracy against time: for each shadow-map size and cascade
//! count, the share of ground pixels whose shadow disagrees with a CPU
//! ray-cast on the analytic peaks (the renderer's own test scene and
//! reference), with the frame time and the shadows pass's time, at
//! 1280 x 720 on this machine's device: with the maps drawn (a moving
//! sun) and kept (a still camera under a still sun). The shadows pass
//! draws the maps; receiving them is timed in the lit passes, so a frame
//! with its maps kept costs over one without shadows what receiving does.
//!
//! `cargo bench -p relief-daemon --bench shadows`

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]
#![allow(clippy::unwrap_used, reason = "a bench")]

#[path = "../../renderer/tests/common/mod.rs"]
mod analytic;
mod common;

use analytic::raycast::{PEAKS_TOP_M, peaks, reference, score};
use analytic::{pose, utm_scene_of};
use common::median;
use relief_renderer::{ClipmapConfig, Frame, RenderSettings, Shadows, SunAngles};

const SUN: SunAngles = SunAngles { azimuth_deg: 250.0, elevation_deg: 12.0 };
/// The lighting's terms for a sun well above the horizon.
const LIGHT: (f64, f64) = (0.35, 0.75);
const FRAMES: usize = 5;

/// One setting's frames: median times with the maps kept (a still camera)
/// and drawn (a moving sun), and the last frame drawn.
struct Timed {
    still_ms: f64,
    moving_ms: f64,
    moving_pass_ms: f64,
    last: Frame,
}

fn main() -> anyhow::Result<()> {
    let gpu = analytic::gpu();
    let (mut renderer, source) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = pose(302_300.0, 5_095_300.0, 3600.0, 340.0, -40.0);
    let lit_settings = RenderSettings { sun: SUN, ..RenderSettings::new(1280, 720, true) };
    // A still camera keeps its maps (and so does one moving a little: the
    // boxes are fixed in the world); a sun that moved draws them. Both
    // timed, the second with the sun turning 0.05 degree to and fro (the
    // same view); the error is from the last frame, drawn under `SUN`.
    let turned = SunAngles { azimuth_deg: SUN.azimuth_deg + 0.05, ..SUN };
    let timed = |renderer: &mut relief_renderer::Renderer, settings: &RenderSettings| -> anyhow::Result<Timed> {
        let pass_ms = |f: &Frame| f.passes.iter().filter(|p| p.0 == "shadows").map(|p| p.1).sum::<f64>();
        let frame_ms = |f: &Frame| f.passes.iter().map(|p| p.1).sum::<f64>();
        renderer.render(&source, &at, settings)?;
        let still: Vec<Frame> =
            (0..FRAMES).map(|_| renderer.render(&source, &at, settings)).collect::<Result<_, _>>()?;
        // An even count, so that the first is turned and the last is not.
        let moving: Vec<Frame> = (0..2 * FRAMES.div_ceil(2))
            .map(|k| {
                let sun = if k % 2 == 0 { turned } else { SUN };
                renderer.render(&source, &at, &RenderSettings { sun, ..*settings })
            })
            .collect::<Result<_, _>>()?;
        Ok(Timed {
            still_ms: median(still.iter().map(frame_ms).collect()),
            moving_ms: median(moving.iter().map(frame_ms).collect()),
            moving_pass_ms: median(moving.iter().map(pass_ms).collect()),
            last: moving.into_iter().last().unwrap(),
        })
    };
    let Timed { still_ms: lit_ms, last: lit, .. } = timed(&mut renderer, &lit_settings)?;
    let judged = reference(&lit, peaks, PEAKS_TOP_M, SUN, LIGHT);
    println!("### Shadows: map size and cascades against a CPU ray-cast, 1280 x 720, median of {FRAMES}");
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!(
        "scene: two analytic peaks (1,700 and 1,400 m) in a 20 km UTM grid, the sun 12 degrees up; {} ground pixels judged, {} in shadow by the ray-cast; frame without shadows {lit_ms:.1} ms",
        judged.len(),
        judged.iter().filter(|j| j.in_shadow).count()
    );
    println!(
        "| cascades | map size | misclassified | shadows pass ms, maps drawn (sun turning 0.05 degree to and fro) | frame ms, maps drawn | / without shadows | frame ms, maps kept (still camera) | / without shadows |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for cascades in 1..=Shadows::MAX_CASCADES {
        for map_size in [512, 1024, 2048, 4096] {
            let shadows = Shadows { cascades, map_size, ..Shadows::DEFAULT };
            let t = timed(&mut renderer, &RenderSettings { shadows: Some(shadows), ..lit_settings })?;
            let s = score(&judged, &lit, &t.last);
            let default = if shadows == Shadows::DEFAULT { " (default)" } else { "" };
            println!(
                "| {cascades} | {map_size}{default} | {:.2}% | {:.1} | {:.1} | {:.2}x | {:.1} | {:.2}x |",
                100.0 * s.misclassified(),
                t.moving_pass_ms,
                t.moving_ms,
                t.moving_ms / lit_ms,
                t.still_ms,
                t.still_ms / lit_ms
            );
        }
    }
    Ok(())
}
