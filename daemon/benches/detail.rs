//! The detail effect's octaves against time. A fractal surface
//! (`relief_examples::fractal`: sines in octaves, each half the last's
//! wavelength and height) is the data down to one tile level and the truth
//! below it. The noise fitted to the data is set against what the truth
//! itself adds at each finer octave (the RMS of what the four-point
//! prediction from the octave above misses), and each count of octaves is
//! timed in a low view at 1280 x 720.
//!
//! `cargo bench -p relief-daemon --bench detail`

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]
#![allow(clippy::unwrap_used, reason = "a bench")]

#[path = "../../renderer/tests/common/mod.rs"]
mod analytic;
mod common;

use analytic::{Analytic, pose, utm_scene_of};
use common::median;
use relief_examples::fractal;
use relief_renderer::{ClipmapConfig, Detail, Detailed, Frame, RenderSettings, Renderer, TerrainSamples};

/// The data's finest level: 20 km / 256 / 2^5, 2.4 m samples.
const DATA_LEVEL: u8 = 5;
/// Corner samples of the scene's middle at the data's level, and a block round it.
const MIDDLE: (i64, i64) = (4096, 4096);

/// The RMS of what the four-point prediction from `level - 1` misses of the
/// truth at `level`, over 64 x 64 samples.
fn true_residual(truth: &Analytic, level: u8) -> f64 {
    let scale = 1i64 << (level - DATA_LEVEL);
    let (x0, y0) = (MIDDLE.0 * scale - 32, MIDDLE.1 * scale - 32);
    let (xs, ys) = (x0..x0 + 64, y0..y0 + 64);
    let fine = truth.heights(level, xs.clone(), ys.clone()).unwrap();
    let above = Analytic { max_level: level - 1, surface: truth.surface.clone(), ..*truth };
    let none = Detail { octaves: 1, sigma_m: 0.0, ratio: 0.5, data_level: level - 1 };
    let predicted = Detailed::new(&above, &truth.surface, none).heights(level, xs, ys).unwrap();
    let sum: f64 = fine.iter().zip(&predicted).map(|(a, b)| f64::from(a - b).powi(2)).sum();
    (sum / fine.len() as f64).sqrt()
}

fn main() -> anyhow::Result<()> {
    let gpu = analytic::gpu();
    let (_, base) = utm_scene_of(ClipmapConfig::default(), fractal);
    let data = Analytic { max_level: DATA_LEVEL, surface: base.surface.clone(), ..base };
    let truth = Analytic { max_level: DATA_LEVEL + 6, surface: base.surface.clone(), ..base };
    let fit = Detail::fit(&data, MIDDLE, DATA_LEVEL, Detail::MAX_OCTAVES).unwrap();
    println!("### Detail: octaves synthesized below the data against the truth's own finer octaves");
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!(
        "data: a fractal surface down to {:.2} m samples; noise fitted: {:.3} m RMS in the first octave, ratio {:.3}",
        data.surface.step(DATA_LEVEL),
        fit.sigma_at(DATA_LEVEL + 1),
        fit.ratio
    );
    println!("| octave | sample spacing m | truth adds (RMS m) | noise adds (RMS m) | log2 noise / truth |");
    println!("|---|---|---|---|---|");
    let mut errors = Vec::new();
    for k in 1..=Detail::MAX_OCTAVES {
        let level = DATA_LEVEL + k as u8;
        let (truth_rms, noise) = (true_residual(&truth, level), fit.sigma_at(level));
        let error = (noise / truth_rms).log2();
        errors.push(error.abs());
        println!("| {k} | {:.3} | {truth_rms:.4} | {noise:.4} | {error:+.2} |", data.surface.step(level));
    }

    let at = pose(300_400.0, 5_100_300.0, fractal(300_400.0, 5_100_300.0) + 25.0, 30.0, -12.0);
    let settings = RenderSettings::new(1280, 720, true);
    println!("\n| octaves | mean abs log2 error of the octaves drawn | frame ms (median of 5) | terrain pass ms |");
    println!("|---|---|---|---|");
    for octaves in 0..=4u32 {
        let (mut renderer, _): (Renderer, Analytic) = utm_scene_of(ClipmapConfig::default(), fractal);
        let detailed = Detailed::new(&data, &data.surface, Detail { octaves, ..fit });
        let source: &dyn TerrainSamples = if octaves == 0 { &data } else { &detailed };
        renderer.render(source, &at, &settings)?;
        let frames: Vec<Frame> = (0..5).map(|_| renderer.render(source, &at, &settings)).collect::<Result<_, _>>()?;
        let total = median(frames.iter().map(|f| f.passes.iter().map(|p| p.1).sum()).collect());
        let terrain = median(frames.iter().map(|f| f.passes[0].1).collect());
        let error = if octaves == 0 {
            "none drawn".to_owned()
        } else {
            format!("{:.2}", errors[..octaves as usize].iter().sum::<f64>() / f64::from(octaves))
        };
        let default = if octaves == Detail::DEFAULT_OCTAVES { " (default)" } else { "" };
        println!("| {octaves}{default} | {error} | {total:.1} | {terrain:.1} |");
    }
    Ok(())
}
