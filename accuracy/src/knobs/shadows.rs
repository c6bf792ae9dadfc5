//! `shadow_map_size` and `shadow_cascades`: the renderer's own shadow test
//! scene (two analytic peaks in 20 km of UTM, the sun 12 degrees up) at
//! 1280 x 720, each ground pixel's shadow set against a CPU ray-cast on the
//! formula (the renderer's test reference, `raycast.rs`).

use relief_renderer::{ClipmapConfig, RenderSettings, Shadows, SunAngles};

use super::Context;
use super::analytic::{pose, utm_scene};
use super::interleave::interleaved;
use crate::sweep::{Row, Sweep};

#[allow(dead_code, reason = "the renderer's test reference, of which the sweep uses part")]
#[path = "../../../renderer/tests/common/raycast.rs"]
mod raycast;

use raycast::{PEAKS_TOP_M, peaks, reference, score};

const SUN: SunAngles = SunAngles { azimuth_deg: 250.0, elevation_deg: 12.0 };
/// The lighting's (ambient, diffuse) terms for a sun well above the horizon.
const LIGHT: (f64, f64) = (0.35, 0.75);
/// Frames timed per setting (after one not timed), the settings in turn.
const ROUNDS: usize = 9;
const SIZES: [u32; 4] = [512, 1024, 2048, 4096];

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let at = pose(302_300.0, 5_095_300.0, 3600.0, 340.0, -40.0);
    let lit_settings = RenderSettings { sun: SUN, ..RenderSettings::new(1280, 720, true) };
    // The frame without shadows first (the reference is judged on it), then each setting.
    let mut settings = vec![lit_settings];
    for cascades in 1..=Shadows::MAX_CASCADES {
        for map_size in SIZES {
            let shadows = Shadows { cascades, map_size, ..Shadows::DEFAULT };
            settings.push(RenderSettings { shadows: Some(shadows), ..lit_settings });
        }
    }
    let mut scenes = settings
        .iter()
        .map(|_| utm_scene(&cx.gpu, ClipmapConfig::default(), peaks))
        .collect::<anyhow::Result<Vec<_>>>()?;
    // A still camera under a still sun keeps its shadow maps (and so does
    // one moving a little): each setting's sun turns 0.05 degree to and fro
    // so that every timed frame draws them, the last (judged) under `SUN`
    // itself.
    let turned = SunAngles { azimuth_deg: SUN.azimuth_deg + 0.05, ..SUN };
    let mut rendered = vec![0usize; settings.len()];
    let timed = interleaved(settings.len(), ROUNDS, false, |k| {
        let (renderer, source) = &mut scenes[k];
        rendered[k] += 1;
        let sun = if rendered[k] % 2 == 1 { turned } else { SUN };
        Ok(renderer.render(&*source, &at, &RenderSettings { sun, ..settings[k] })?)
    })?;
    drop(scenes);
    let (lit, lit_ms) = (&timed[0].last, timed[0].frame_ms());
    let judged = reference(lit, peaks, PEAKS_TOP_M, SUN, LIGHT);
    let shadowed = judged.iter().filter(|j| j.in_shadow).count();
    let mut rows = Vec::new();
    for (s, t) in settings.iter().zip(&timed).skip(1) {
        let Some(shadows) = s.shadows else { continue };
        let score = score(&judged, lit, &t.last);
        let (cascades, map_size) = (shadows.cascades, shadows.map_size);
        let plural = if cascades == 1 { "" } else { "s" };
        let total = t.frame_ms();
        rows.push(
            Row::new(format!("{map_size} px, {cascades} cascade{plural}"), total, 100.0 * score.misclassified())
                .default_if(shadows == Shadows::DEFAULT)
                .with("shadows pass ms", format!("{:.1}", t.pass_ms("shadows")))
                .with("/ frame without shadows", format!("{:.2}x", total / lit_ms))
                .with("drawn in shadow", score.drawn_shadowed.to_string()),
        );
    }
    let why_default = why(&rows);
    Ok(vec![Sweep {
        knob: "shadow_map_size and shadow_cascades".into(),
        case: format!(
            "The renderer's shadow test scene: two analytic peaks (1,700 and 1,400 m over a 1,000 m plain) in 20 km of \
             UTM, the sun 12 degrees up from 250 degrees, seen at 1280 x 720 from 3,600 m, 40 degrees down. {} ground \
             pixels are judged (facing the sun enough that a shadow shows), {shadowed} of them in shadow by the \
             ray-cast. The frame without shadows takes {lit_ms:.1} ms. Each setting's time is the fastest of {ROUNDS} \
             frames under a sun turned 0.05 degree and back in turn, so that every frame draws its maps (a still \
             camera under a still sun keeps them), the fastest being the least disturbed on this shared machine, the settings rendered in turn.",
            judged.len()
        ),
        reference: "a CPU ray-cast (f64, 5 m steps) towards the sun from each drawn ground pixel's point on the \
                    formula"
            .into(),
        error: "ground pixels whose shadow disagrees with the ray-cast, %".into(),
        time: format!("frame ms with the maps drawn, fastest of {ROUNDS}"),
        rows,
        why_default,
    }])
}

/// Why two maps of 1,024, from the rows `run` measured.
fn why(rows: &[Row]) -> String {
    let get = |size: u32, cascades: u32| {
        let plural = if cascades == 1 { "" } else { "s" };
        let name = format!("{size} px, {cascades} cascade{plural}");
        rows.iter().find(|r| r.setting == name).map_or((f64::NAN, f64::NAN), |r| (r.error, r.time))
    };
    let (e, t) = get(1024, 2);
    let ((e_2048, t_2048), (e_4096, t_4096)) = (get(2048, 2), get(4096, 2));
    let ((e_one, _), (e_one_4096, _)) = (get(1024, 1), get(4096, 1));
    let ((e_three, _), (e_four, _)) = (get(1024, 3), get(1024, 4));
    // A setting with at least the maps and cascades of another that timed
    // faster than it: the machine's noise, not the knob.
    let mut settings = Vec::new();
    for cascades in 1..=Shadows::MAX_CASCADES {
        for size in SIZES {
            settings.push((size, cascades, get(size, cascades).1));
        }
    }
    let inverted = settings
        .iter()
        .flat_map(|a| settings.iter().map(move |b| (a, b)))
        .find(|(a, b)| a.0 >= b.0 && a.1 >= b.1 && (a.0, a.1) != (b.0, b.1) && a.2 < b.2);
    let noise = inverted.map_or_else(String::new, |(a, b)| {
        let plural = |c: u32| if c == 1 { "" } else { "s" };
        format!(
            " Times of neighbouring settings differ by less than this shared machine's noise ({} px with {} \
             cascade{} timed {:.1} ms, faster than {} px with {} cascade{} at {:.1} ms, which draws less), so the \
             front through the middle of the table is no firm ranking.",
            a.0,
            a.1,
            plural(a.1),
            a.2,
            b.0,
            b.1,
            plural(b.1),
            b.2
        )
    });
    format!(
        "Two maps of 1,024 misclassify {e:.2}% of the judged ground pixels in a {t:.1} ms frame. Doubling the maps to \
         2,048 takes that to {e_2048:.2}% for {:.1} ms more, 4,096 to {e_4096:.2}% for {:.1} ms more. One cascade of \
         1,024 misclassifies {e_one:.2}% and needs 4,096 to come near ({e_one_4096:.2}%): a single map spread over the \
         shadows' 20 km leaves the near ground few texels. Cascades past two gain less than a bigger map \
         ({e_three:.2}% with three of 1,024, {e_four:.2}% with four).{noise} Two of 1,024 sits where the error is \
         already {e:.2}% of the ground and the maps hold 2 million texels (8 MiB of 32-bit depth); each doubling of \
         the size costs four times the memory for a little over half the error.",
        t_2048 - t,
        t_4096 - t
    )
}
