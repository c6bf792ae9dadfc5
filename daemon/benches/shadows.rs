//! Shadows' accuracy against time: for each shadow-map size and cascade
//! count, the share of ground pixels whose shadow disagrees with a CPU
//! ray-cast on the analytic peaks (the renderer's own test scene and
//! reference), with the frame time and the shadows pass's time, at
//! 1280 x 720 on this machine's device.
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

fn main() -> anyhow::Result<()> {
    let gpu = analytic::gpu();
    let (mut renderer, source) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = pose(302_300.0, 5_095_300.0, 3600.0, 340.0, -40.0);
    let lit_settings = RenderSettings { sun: SUN, ..RenderSettings::new(1280, 720, true) };
    let timed = |renderer: &mut relief_renderer::Renderer,
                 settings: &RenderSettings|
     -> anyhow::Result<(f64, f64, Frame)> {
        renderer.render(&source, &at, settings)?;
        let frames: Vec<Frame> =
            (0..FRAMES).map(|_| renderer.render(&source, &at, settings)).collect::<Result<_, _>>()?;
        let total = median(frames.iter().map(|f| f.passes.iter().map(|p| p.1).sum()).collect());
        let pass =
            median(frames.iter().map(|f| f.passes.iter().filter(|p| p.0 == "shadows").map(|p| p.1).sum()).collect());
        Ok((total, pass, frames.into_iter().last().unwrap()))
    };
    let (lit_ms, _, lit) = timed(&mut renderer, &lit_settings)?;
    let judged = reference(&lit, peaks, PEAKS_TOP_M, SUN, LIGHT);
    println!("### Shadows: map size and cascades against a CPU ray-cast, 1280 x 720, median of {FRAMES}");
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!(
        "scene: two analytic peaks (1,700 and 1,400 m) in a 20 km UTM grid, the sun 12 degrees up; {} ground pixels judged, {} in shadow by the ray-cast; frame without shadows {lit_ms:.1} ms",
        judged.len(),
        judged.iter().filter(|j| j.in_shadow).count()
    );
    println!("| cascades | map size | misclassified | shadows pass ms | frame ms | / without shadows |");
    println!("|---|---|---|---|---|---|");
    for cascades in 1..=Shadows::MAX_CASCADES {
        for map_size in [512, 1024, 2048, 4096] {
            let shadows = Shadows { cascades, map_size, ..Shadows::DEFAULT };
            let (total, pass, frame) =
                timed(&mut renderer, &RenderSettings { shadows: Some(shadows), ..lit_settings })?;
            let s = score(&judged, &lit, &frame);
            let default = if shadows == Shadows::DEFAULT { " (default)" } else { "" };
            println!(
                "| {cascades} | {map_size}{default} | {:.2}% | {pass:.1} | {total:.1} | {:.2}x |",
                100.0 * s.misclassified(),
                total / lit_ms
            );
        }
    }
    Ok(())
}
