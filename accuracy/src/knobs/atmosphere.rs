//! `atmosphere_steps` and `atmosphere_downsample`: the demo range at
//! 1280 x 720 looking along it nearly level (sky and distance both show),
//! by day and at dawn, each setting's frame against the same frame with
//! the most steps and a ray for every pixel.

use std::sync::Arc;

use anyhow::Context as _;
use relief_daemon::view::SceneTerrain;
use relief_renderer::{Atmosphere, ClipmapConfig, Pose, RenderSettings, Renderer, SunAngles, Surface};

use super::interleave::interleaved;
use super::{Context, HD, demo_pose, frame_ms, rgb_difference};
use crate::sweep::{Row, Sweep};

/// Frames timed per setting (after one not timed), the settings in turn.
const ROUNDS: usize = 11;
const STEPS: [u32; 8] = [2, 4, 8, 12, 16, 24, 36, 64];
const DOWNSAMPLES: [u32; 6] = [1, 2, 3, 5, 6, 8];

/// The demo's camera looking 6 degrees down, along the range.
fn view() -> Pose {
    Pose { pitch_deg: -6.0, ..demo_pose() }
}

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let scene = cx.load(&cx.demo)?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let demo = relief_daemon::picture::Picture::of(&snap.manifest)
        .effect_settings
        .atmosphere
        .context("the demo declares no atmosphere")?;
    let renderer = || Renderer::new(Arc::clone(&cx.gpu), Surface::new(snap.grid.clone()), ClipmapConfig::default());
    let at = view();
    let mut sweeps = Vec::new();
    for (light, words, sun) in [
        ("day", "the sun 45 degrees up in the north-west", SunAngles::DEFAULT),
        (
            "dawn",
            "the sun 3 degrees up, 15 degrees right of ahead",
            SunAngles { azimuth_deg: 30.0, elevation_deg: 3.0 },
        ),
    ] {
        let with = |steps, downsample| RenderSettings {
            sun,
            atmosphere: Some(Atmosphere { steps, downsample, ..demo }),
            ..HD
        };
        let d = Atmosphere::DEFAULT_DOWNSAMPLE;
        // The reference is slow (a ray of 256 steps for every pixel): one
        // frame not timed, then one timed, on a renderer of its own.
        let mut own = renderer()?;
        let reference_settings = with(Atmosphere::MAX_STEPS, 1);
        own.render(&terrain, &at, &reference_settings)?;
        let reference = own.render(&terrain, &at, &reference_settings)?;
        drop(own);
        let reference_ms = frame_ms(&reference);
        let reference_pass_ms: f64 = reference.passes.iter().filter(|p| p.0 == "atmosphere").map(|p| p.1).sum();
        // The settings, and last the frame without the atmosphere.
        let mut settings: Vec<Option<(u32, u32)>> = STEPS.map(|s| Some((s, d))).to_vec();
        settings.extend(DOWNSAMPLES.map(|k| Some((Atmosphere::DEFAULT_STEPS, k))));
        settings.push(Some((Atmosphere::MAX_STEPS, d)));
        settings.push(None);
        let mut renderers = settings.iter().map(|_| Ok(renderer()?)).collect::<anyhow::Result<Vec<Renderer>>>()?;
        let timed = interleaved(settings.len(), ROUNDS, false, |k| {
            let s = settings[k].map_or(RenderSettings { sun, ..HD }, |(steps, k)| with(steps, k));
            Ok(renderers[k].render(&terrain, &at, &s)?)
        })?;
        drop(renderers);
        let lit_ms = timed[settings.len() - 1].frame_ms();
        let mut rows = Vec::new();
        for (setting, t) in settings.iter().zip(&timed) {
            let Some((steps, downsample)) = *setting else { continue };
            let (rms, max) = rgb_difference(&t.last, &reference);
            let is_default = (steps, downsample) == (Atmosphere::DEFAULT_STEPS, d);
            rows.push(
                Row::new(format!("{steps} steps, 1/{downsample}"), t.pass_ms("atmosphere"), rms)
                    .default_if(is_default)
                    .with("frame ms", format!("{:.1}", t.frame_ms()))
                    .with("max error", format!("{max:.0}")),
            );
        }
        let why_default = why(&rows);
        sweeps.push(Sweep {
            knob: format!("atmosphere_steps and atmosphere_downsample, {light}"),
            case: format!(
                "The demo range at 1280 x 720 from its camera (9 km up) looking 6 degrees down along the range, so \
                 sky, far ridges and near slopes all show; {words}. Settings read: steps along each view ray, then 1/k \
                 for one ray per k x k pixels (the scattering between interpolated). The frame without the atmosphere \
                 takes {lit_ms:.1} ms; the reference's atmosphere pass {reference_pass_ms:.0} ms (frame \
                 {reference_ms:.0} ms; one frame timed, after one not). Each setting's times are the fastest of \
                 {ROUNDS} still frames, the settings rendered in turn (the machine is shared: the fastest is the least \
                 disturbed)."
            ),
            reference: format!("the same frame with {} steps and a ray for every pixel", Atmosphere::MAX_STEPS),
            error: "RMS difference of every pixel's R, G and B (0-255)".into(),
            time: format!("atmosphere pass ms, fastest of {ROUNDS}"),
            rows,
            why_default,
        });
    }
    Ok(sweeps)
}

/// Why 16 steps at 1/4, from the rows `run` measured for one light.
fn why(rows: &[Row]) -> String {
    let get = |steps: u32, k: u32| {
        let name = format!("{steps} steps, 1/{k}");
        rows.iter().find(|r| r.setting == name).map_or((f64::NAN, f64::NAN), |r| (r.error, r.time))
    };
    let s = Atmosphere::DEFAULT_STEPS;
    let d = Atmosphere::DEFAULT_DOWNSAMPLE;
    let (e_default, t_default) = get(s, d);
    let (e_full, t_full) = get(s, 1);
    let ((e2, _), (e4, _), (e64, _)) = (get(2, d), get(4, d), get(64, d));
    let max = rows
        .iter()
        .find(|r| r.default)
        .and_then(|r| r.extra.iter().find(|(h, _)| h == "max error"))
        .map_or_else(String::new, |(_, v)| v.clone());
    let ((e_1_2, _), (e_1_3, t_1_3), (e_1_5, t_1_5), (e_1_6, _)) = (get(s, 2), get(s, 3), get(s, 5), get(s, 6));
    format!(
        "Past {s} steps the error hardly falls ({e_default:.2}, {e64:.2} at 64): what is left is the downsampling's, \
         at silhouettes against the sky (max error {max}). Under 8 it climbs fast ({e4:.2} at 4, {e2:.2} at 2), as \
         Clasen found (12-36 steps enough, fewer visibly wrong at dawn). A ray for every {d} x {d} pixels costs \
         {t_default:.1} ms of atmosphere against {t_full:.1} ms for one a pixel, {:.0} times less, for {e_default:.2} \
         RMS against {e_full:.2}. Odd factors beat their even neighbours (1/3: {e_1_3:.2} in {t_1_3:.1} ms, 1/5: \
         {e_1_5:.2}, against 1/2: {e_1_2:.2}, 1/4: {e_default:.2}, 1/6: {e_1_6:.2}). This sweep found why, in \
         part: a scattering texel marched its ray through its own centre, a pixel corner for an even factor, but \
         read the depth of the pixel beside that corner. Rays now go through the centre of the pixel whose depth \
         they read, which took 1/4 by day from 0.59 to 0.49 RMS (this session's runs); the even factors still \
         trail, and the composite's interpolation, which places each texel at its own centre, is the next \
         suspect. 1/4 was chosen for its cost; until that is settled these numbers say 1/5 ({e_1_5:.2} in \
         {t_1_5:.1} ms) or 1/3 would serve as well or better.",
        t_full / t_default
    )
}
