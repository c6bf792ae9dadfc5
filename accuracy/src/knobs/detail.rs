//! `detail_octaves`: a fractal surface (`relief_examples::fractal`: sines
//! in octaves, each half the last's wavelength and height) is the data
//! down to one tile level and the truth below it. The noise fitted to the
//! data is set against what the truth itself adds at each finer octave
//! (the RMS of what the four-point prediction from the octave above
//! misses), and each count of octaves is timed in a low view at 1280 x 720.

use anyhow::Context as _;
use std::time::Instant;

use relief_examples::fractal;
use relief_renderer::{ClipmapConfig, Detail, Detailed, Frame, RenderSettings, Renderer, TerrainSamples};

use super::Context;
use super::analytic::{Analytic, pose, utm_scene};
use super::interleave::interleaved;
use crate::sweep::{Row, Sweep};

/// The data's finest level: 20 km / 256 / 2^5, 2.4 m samples.
const DATA_LEVEL: u8 = 5;
/// A corner sample of the scene's middle at the data's level.
const MIDDLE: (i64, i64) = (4096, 4096);
/// Frames timed per setting (after one not timed), the settings in turn.
const ROUNDS: usize = 15;

/// The RMS of what the four-point prediction from `level - 1` misses of the
/// truth at `level`, over 64 x 64 samples round the middle.
fn true_residual(truth: &Analytic, level: u8) -> anyhow::Result<f64> {
    let scale = 1i64 << (level - DATA_LEVEL);
    let (x0, y0) = (MIDDLE.0 * scale - 32, MIDDLE.1 * scale - 32);
    let (xs, ys) = (x0..x0 + 64, y0..y0 + 64);
    let not_ready = || anyhow::anyhow!("the fractal does not answer at level {level}");
    let fine = truth.heights(level, xs.clone(), ys.clone()).ok_or_else(not_ready)?;
    let above = truth.to_level(level - 1);
    let none = Detail { octaves: 1, sigma_m: 0.0, ratio: 0.5, data_level: level - 1 };
    let predicted = Detailed::new(&above, &truth.surface, none).heights(level, xs, ys).ok_or_else(not_ready)?;
    let sum: f64 = fine.iter().zip(&predicted).map(|(a, b)| f64::from(a - b).powi(2)).sum();
    Ok((sum / fine.len() as f64).sqrt())
}

/// How far off a point must be for the far view, metres.
const FAR_M: f64 = 2000.0;

/// RMS of (drawn - fractal) over every 4th pixel whose ground lies more
/// than `FAR_M` from the eye and inside the scene, metres: what the levels'
/// reach decides.
fn far_error(frame: &Frame) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for py in (0..frame.height).step_by(4) {
        for px in (0..frame.width).step_by(4) {
            let depth = frame.depth[(py * frame.width + px) as usize];
            if depth <= 0.0 {
                continue;
            }
            let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), frame.width, frame.height, depth);
            let p = frame.view.eye + dir * distance;
            let inside = (290_100.0..309_900.0).contains(&p.x) && (5_090_100.0..5_109_900.0).contains(&p.y);
            if distance < FAR_M || !inside {
                continue;
            }
            sum += (p.z - fractal(p.x, p.y)).powi(2);
            n += 1;
        }
    }
    (sum / n.max(1) as f64).sqrt()
}

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let (_, base) = utm_scene(&cx.gpu, ClipmapConfig::default(), fractal)?;
    let data = base.to_level(DATA_LEVEL);
    let truth = base.to_level(DATA_LEVEL + Detail::MAX_OCTAVES as u8);
    let fit = Detail::fit(&data, MIDDLE, DATA_LEVEL, Detail::MAX_OCTAVES).context("the detail fit found no data")?;
    // What the truth adds at each octave below the data, and what the noise adds.
    let mut truth_rms = Vec::new();
    let mut noise_rms = Vec::new();
    for k in 1..=Detail::MAX_OCTAVES {
        let level = DATA_LEVEL + k as u8;
        truth_rms.push(true_residual(&truth, level)?);
        noise_rms.push(fit.sigma_at(level));
    }

    let at = pose(300_400.0, 5_100_300.0, fractal(300_400.0, 5_100_300.0) + 25.0, 30.0, -12.0);
    let settings = RenderSettings::new(1280, 720, true);
    let counts: Vec<u32> = (0..=Detail::MAX_OCTAVES).collect();
    let detailed: Vec<Detailed<'_>> =
        counts.iter().map(|&octaves| Detailed::new(&data, &data.surface, Detail { octaves, ..fit })).collect();
    let sources: Vec<&dyn TerrainSamples> =
        counts.iter().zip(&detailed).map(|(&o, d)| if o == 0 { &data as &dyn TerrainSamples } else { d }).collect();
    let mut renderers = counts
        .iter()
        .map(|_| Ok(utm_scene(&cx.gpu, ClipmapConfig::default(), fractal)?.0))
        .collect::<anyhow::Result<Vec<Renderer>>>()?;
    // The first frame fills every level, synthesizing the detail's: timed on its own.
    let first = renderers
        .iter_mut()
        .zip(&sources)
        .map(|(renderer, source)| {
            let started = Instant::now();
            renderer.render(*source, &at, &settings)?;
            Ok(started.elapsed().as_secs_f64() * 1e3)
        })
        .collect::<anyhow::Result<Vec<f64>>>()?;
    let timed = interleaved(counts.len(), ROUNDS, false, |k| Ok(renderers[k].render(sources[k], &at, &settings)?))?;
    let mut rows = Vec::new();
    for ((&octaves, timed), first_ms) in counts.iter().zip(&timed).zip(&first) {
        // The octaves this view draws: the finest level drawn, below the data's.
        let active = &timed.last.update.active;
        let finest = active.last().copied().unwrap_or(DATA_LEVEL);
        let levels = format!("{} to {finest}", active.first().copied().unwrap_or(finest));
        let drawn = usize::from(finest.saturating_sub(DATA_LEVEL)).min(octaves as usize);
        // Each octave's roughness as drawn (the noise's, or none) against the truth's.
        let spectrum: f64 = (0..truth_rms.len())
            .map(|j| (if j < drawn { noise_rms[j] } else { 0.0 } - truth_rms[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        let missing: f64 = truth_rms[drawn..].iter().map(|t| t * t).sum::<f64>().sqrt();
        let log2 = if drawn == 0 {
            "—".to_owned()
        } else {
            let mean = (0..drawn).map(|j| (noise_rms[j] / truth_rms[j]).log2().abs()).sum::<f64>() / drawn as f64;
            format!("{mean:.2}")
        };
        rows.push(
            Row::new(octaves.to_string(), timed.frame_ms(), spectrum)
                .default_if(octaves == Detail::DEFAULT_OCTAVES)
                .with("octaves drawn in this view", drawn.to_string())
                .with("finest spacing drawn m", format!("{:.2}", data.surface.step(finest)))
                .with("truth's roughness left out m", format!("{missing:.3}"))
                .with("mean abs log2 noise / truth", log2)
                .with("terrain pass ms", format!("{:.1}", timed.pass_ms("terrain")))
                .with("first frame ms (levels filled)", format!("{first_ms:.0}"))
                .with("tile levels drawn", levels)
                .with("far surface RMS m", format!("{:.2}", far_error(&timed.last)))
                .with("level blocks drawn", timed.last.drawn.terrain_blocks_drawn.to_string()),
        );
    }
    let why_default = why(&rows);
    let per_octave: Vec<String> =
        truth_rms.iter().zip(&noise_rms).enumerate().map(|(j, (t, n))| format!("{}: {t:.3} / {n:.3}", j + 1)).collect();
    Ok(vec![Sweep {
        knob: "detail_octaves".into(),
        case: format!(
            "A fractal surface (sines in 16 octaves, each half the last's wavelength and height) in 20 km of UTM is \
             the data down to {:.2} m samples (tile level {DATA_LEVEL}) and the truth below it. The noise fitted to \
             the data ({:.3} m RMS in the first octave, ratio {:.3} per octave) is drawn from 25 m above the ground \
             looking 12 degrees down at 1280 x 720; each octave halves the drawn spacing, and this view draws no finer \
             than its cells reach two pixels, so settings past what it draws cost and show the same. What the truth / \
             the noise add per octave, RMS m: {}. Each setting's time is the fastest of {ROUNDS} still frames (the \
             machine is shared: the fastest is the least disturbed), the settings rendered in turn; the first frame, \
             which fills the levels and synthesizes the detail, is timed apart, once. The far surface is the drawn \
             surface's RMS height error beyond 2 km (every 4th pixel, from the depth buffer) against the fractal.",
            data.surface.step(DATA_LEVEL),
            fit.sigma_at(DATA_LEVEL + 1),
            fit.ratio,
            per_octave.join(", ")
        ),
        reference: "the fractal's own octaves below the data: the RMS each adds to the four-point prediction from the \
                    octave above (64 x 64 samples at the scene's middle)"
            .into(),
        error: format!(
            "RMS over the {} octaves below the data of (roughness drawn - the truth's), m; an octave not drawn counts \
             as all of the truth's missing",
            Detail::MAX_OCTAVES
        ),
        time: format!("still frame ms, fastest of {ROUNDS}"),
        rows,
        why_default,
    }])
}

/// Why 2, from the rows `run` measured.
fn why(rows: &[Row]) -> String {
    let get = |octaves: u32| rows.iter().find(|r| r.setting == octaves.to_string());
    let (Some(none), Some(two), Some(four)) = (get(0), get(2), get(4)) else { return String::new() };
    let most = rows.last().unwrap_or(four);
    let extra =
        |r: &Row, header: &str| r.extra.iter().find(|(h, _)| h == header).map_or_else(String::new, |(_, v)| v.clone());
    let (levels, blocks, first) = ("tile levels drawn", "level blocks drawn", "first frame ms (levels filled)");
    let far = "far surface RMS m";
    let first_of = |r: &Row| extra(r, first).parse::<f64>().unwrap_or(f64::NAN);
    let slowest_first = rows.iter().map(first_of).fold(f64::NAN, f64::max);
    format!(
        "Two octaves take the drawn spacing from {} m to {} m and leave {} m of the truth's roughness out, against {} \
         m with none; their noise is on average within a factor of 2^{} of the truth's per octave. Past four, each \
         octave adds a centimetre RMS or less ({} m of error at {}, {} m at the most this view draws). In this view \
         the still frame {} ({:.1}, {:.1} and {:.1} ms with none, two and the most), and the first frame, which fills \
         the levels and synthesizes the detail, is at most {:.0}% slower than with none ({}, {} and {} ms). What they \
         cost is reach: each octave adds a finer level, and once there are 8 drops the coarsest ({} with none, {} with \
         two, {} with the most), so the level blocks drawn go {}, {}, {} and more of the far view is left to the \
         coarse base: the drawn surface beyond 2 km is {} m RMS from the fractal with none, {} m with two, {} m with \
         the most. Two, here the most that keeps the coarsest level, takes most of the roughness the data lacks and \
         leaves the far view as it was.",
        extra(none, "finest spacing drawn m"),
        extra(two, "finest spacing drawn m"),
        extra(two, "truth's roughness left out m"),
        extra(none, "truth's roughness left out m"),
        extra(two, "mean abs log2 noise / truth"),
        crate::report::number(four.error),
        four.setting,
        crate::report::number(most.error),
        if most.time <= none.time { "is no slower with the most octaves than with none" } else { "takes" },
        none.time,
        two.time,
        most.time,
        (100.0 * (slowest_first / first_of(none) - 1.0)).max(0.0),
        extra(none, first),
        extra(two, first),
        extra(most, first),
        extra(none, levels),
        extra(two, levels),
        extra(most, levels),
        extra(none, blocks),
        extra(two, blocks),
        extra(most, blocks),
        extra(none, far),
        extra(two, far),
        extra(most, far),
    )
}
