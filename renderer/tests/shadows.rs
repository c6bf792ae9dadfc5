//! Shadows against a CPU ray-cast on an analytic height field: the drawn
//! ground in shadow is where the ray-cast says, on the side away from the
//! sun; the pass exists only when asked for; hard suns give valid images.

#![allow(clippy::unwrap_used, reason = "a test")]

mod common;

use common::raycast::{PEAKS_TOP_M, peaks, reference, score};
use common::{pose, save, terrain_dirt, utm_scene_of};
use relief_renderer::{ClipmapConfig, Pose, RenderSettings, Shadows, SunAngles};
use relief_source::Extent;

const SUN: SunAngles = SunAngles { azimuth_deg: 250.0, elevation_deg: 12.0 };
const LIT: RenderSettings = RenderSettings { sun: SUN, ..RenderSettings::new(480, 270, true) };
/// The lighting's terms for a sun well above the horizon.
const LIGHT: (f64, f64) = (0.35, 0.75);

/// South-east of the peaks, looking north-west down over them.
fn over_the_peaks() -> Pose {
    pose(302_300.0, 5_095_300.0, 3600.0, 340.0, -40.0)
}

#[test]
fn shadows_fall_where_the_ray_cast_says_and_away_from_the_sun() {
    let (mut renderer, source) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = over_the_peaks();
    let lit = renderer.render(&source, &at, &LIT).unwrap();
    assert!(!renderer.counters().is_built("shadows"), "built for a frame without shadows");
    let settings = RenderSettings { shadows: Some(Shadows::DEFAULT), ..LIT };
    let shadowed = renderer.render(&source, &at, &settings).unwrap();
    save(&lit, "shadows-off.png");
    save(&shadowed, "shadows-on.png");
    let pass = renderer.counters().stats().iter().find(|s| s.name == "shadows").copied().unwrap();
    assert!(pass.built && pass.runs == 1 && pass.total_ms > 0.0, "{pass:?}");
    assert!(shadowed.passes.iter().any(|(name, _)| *name == "shadows"));

    let s = score(&reference(&lit, peaks, PEAKS_TOP_M, SUN, LIGHT), &lit, &shadowed);
    eprintln!("{s:?}, misclassified {:.4}", s.misclassified());
    assert!(s.compared > 40_000, "{s:?}");
    // The peaks cast long shadows: a good part of the ground is in them.
    assert!(s.reference_shadowed > s.compared / 50, "{s:?}");
    // Tolerance: 2% of the ground pixels (shadow edges a map texel wide,
    // and the drawn mesh's facets against the analytic surface).
    assert!(s.misclassified() < 0.02, "{s:?}");
    // Shadows lie on the side of the peaks away from the sun.
    assert!(s.towards_sun_m < -500.0, "{s:?}");

    // Undeclared again: the pass and its maps go.
    renderer.render(&source, &at, &LIT).unwrap();
    assert!(!renderer.counters().is_built("shadows"));
}

#[test]
fn maps_are_kept_while_cascades_and_casters_stay_and_drawn_when_either_changes() {
    let (mut renderer, source) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = over_the_peaks();
    renderer.render(&source, &at, &LIT).unwrap();
    let settings = RenderSettings { shadows: Some(Shadows::DEFAULT), ..LIT };
    let cascades = Shadows::DEFAULT.cascades as usize;
    let counts = |f: &relief_renderer::Frame| (f.drawn.shadow_maps_drawn, f.drawn.shadow_maps_kept);

    let first = renderer.render(&source, &at, &settings).unwrap();
    assert_eq!(counts(&first), (cascades, 0), "the first frame draws every map");
    let still = renderer.render(&source, &at, &settings).unwrap();
    assert_eq!(counts(&still), (0, cascades), "a still camera under a still sun keeps them");
    assert_eq!(still.rgba, first.rgba, "kept maps shade as the drawn ones did");

    // A camera moving a metre at a time mostly finds the same boxes (fixed
    // in the world) and keeps the maps, which still shade as the ray-cast
    // says; 2 km away, new boxes, drawn; back, drawn again, as first.
    let step = |k: f64| Pose { position: [at.position[0] + k, at.position[1], at.position[2]], ..at };
    let mut kept_steps = 0;
    for k in 1..=5 {
        let f = renderer.render(&source, &step(f64::from(k)), &settings).unwrap();
        assert_eq!(f.drawn.shadow_maps_drawn + f.drawn.shadow_maps_kept, cascades);
        kept_steps += usize::from(f.drawn.shadow_maps_drawn == 0);
    }
    assert!(kept_steps >= 3, "{kept_steps} of 5 one-metre steps kept the maps");
    let moved = step(5.0);
    let kept = renderer.render(&source, &moved, &settings).unwrap();
    assert_eq!(counts(&kept), (0, cascades), "the same view again");
    let lit_there = renderer.render(&source, &moved, &LIT).unwrap();
    let s = score(&reference(&lit_there, peaks, PEAKS_TOP_M, SUN, LIGHT), &lit_there, &kept);
    assert!(s.misclassified() < 0.02, "kept maps, 5 m on: {s:?}");
    let far = step(2_000.0);
    assert_eq!(counts(&renderer.render(&source, &far, &settings).unwrap()), (cascades, 0), "2 km away");
    let back = renderer.render(&source, &at, &settings).unwrap();
    assert_eq!(counts(&back), (cascades, 0), "back");
    assert_eq!(back.rgba, first.rgba);

    // The sun moves a tenth of a degree.
    let sun = SunAngles { azimuth_deg: SUN.azimuth_deg + 0.1, ..SUN };
    let turned = renderer.render(&source, &at, &RenderSettings { sun, ..settings }).unwrap();
    assert_eq!(counts(&turned), (cascades, 0), "the sun moved");

    // The terrain's samples are rebuilt under the view: the regions of the
    // maps over them drawn again, and (the same heights) to the same image.
    renderer.render(&source, &at, &settings).unwrap();
    renderer.invalidate(&source, &terrain_dirt(Extent::new(300_000.0, 5_090_000.0, 305_000.0, 5_100_000.0)));
    let rebuilt = renderer.render(&source, &at, &settings).unwrap();
    let d = rebuilt.drawn;
    assert_eq!(d.shadow_maps_drawn, 0, "{d:?}");
    assert!(d.shadow_maps_redrawn_in_part >= 1 && d.shadow_regions >= 1, "the terrain changed: {d:?}");
    assert_eq!(d.shadow_maps_redrawn_in_part + d.shadow_maps_kept, cascades);
    assert_eq!(rebuilt.rgba, first.rgba);
}

/// The peaks with a 600 m tower over 301..301.6 km E, 5,096..5,096.6 km N.
fn peaks_with_tower(x: f64, y: f64) -> f64 {
    let tower = (301_000.0..=301_600.0).contains(&x) && (5_096_000.0..=5_096_600.0).contains(&y);
    peaks(x, y) + if tower { 600.0 } else { 0.0 }
}

#[test]
fn an_edit_redraws_only_the_regions_of_the_maps_it_touches_to_the_image_drawn_from_scratch() {
    let (mut renderer, before) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = over_the_peaks();
    let settings = RenderSettings { shadows: Some(Shadows::DEFAULT), ..LIT };
    let cascades = Shadows::DEFAULT.cascades as usize;
    let without = renderer.render(&before, &at, &settings).unwrap();
    let after = common::Analytic { height: peaks_with_tower, surface: before.surface.clone(), ..before };
    renderer.invalidate(&after, &terrain_dirt(Extent::new(301_000.0, 5_096_000.0, 301_600.0, 5_096_600.0)));
    let edited = renderer.render(&after, &at, &settings).unwrap();
    let d = edited.drawn;
    assert_eq!(d.shadow_maps_drawn, 0, "{d:?}");
    assert!(d.shadow_regions >= 1, "{d:?}");
    let whole = (cascades * 1024 * 1024) as u64;
    assert!(d.shadow_texels * 10 < whole, "{} of {whole} texels redrawn for a 600 m tower", d.shadow_texels);
    // The same frame as a renderer that never saw the peaks without it.
    let (mut scratch, _) = utm_scene_of(ClipmapConfig::default(), peaks_with_tower);
    let fresh = scratch.render(&after, &at, &settings).unwrap();
    save(&edited, "shadows-edited.png");
    save(&fresh, "shadows-scratch.png");
    let off = edited.rgba.chunks(4).zip(fresh.rgba.chunks(4)).filter(|(a, b)| a != b).count();
    assert_eq!(off, 0, "{off} pixels differ from the frame drawn from scratch");
    // The tower shows: it differs from the frame before.
    assert!(edited.rgba != without.rgba, "the tower does not show");
}

#[test]
fn hard_suns_give_valid_images() {
    let (mut renderer, source) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = over_the_peaks();
    for (name, elevation_deg) in
        [("zenith", 90.0), ("0.1 degree below the horizon", -0.1), ("grazing", 0.5), ("night", -30.0)]
    {
        let sun = SunAngles { azimuth_deg: 250.0, elevation_deg };
        let settings = RenderSettings { sun, shadows: Some(Shadows::DEFAULT), ..LIT };
        let frame = renderer.render(&source, &at, &settings).unwrap();
        let lit = renderer.render(&source, &at, &RenderSettings { sun, ..LIT }).unwrap();
        assert!(frame.depth.iter().all(|d| d.is_finite()), "{name}");
        let drawn = frame.depth.iter().filter(|&&d| d > 0.0).count();
        assert!(drawn > frame.depth.len() / 2, "{name}: {drawn} pixels drawn");
        // Shadows only ever take light away.
        let brighter = frame.rgba.chunks(4).zip(lit.rgba.chunks(4)).filter(|(a, b)| a[0] > b[0].saturating_add(1));
        assert_eq!(brighter.count(), 0, "{name}");
        if elevation_deg <= 0.0 {
            assert_eq!(frame.rgba, lit.rgba, "{name}: a sun below the horizon casts no maps");
        }
    }
}

#[test]
fn shadows_without_lighting_and_bad_knobs_are_refused() {
    let (mut renderer, source) = utm_scene_of(ClipmapConfig::default(), peaks);
    let at = over_the_peaks();
    let unlit = RenderSettings { lighting: false, shadows: Some(Shadows::DEFAULT), ..LIT };
    let e = renderer.render(&source, &at, &unlit).unwrap_err().to_string();
    assert!(e.contains("lighting"), "{e}");
    for (shadows, field) in [
        (Shadows { cascades: 0, ..Shadows::DEFAULT }, "shadow_cascades"),
        (Shadows { cascades: 5, ..Shadows::DEFAULT }, "shadow_cascades"),
        (Shadows { map_size: 1000, ..Shadows::DEFAULT }, "shadow_map_size"),
        // A gibibyte of maps.
        (Shadows { cascades: 4, map_size: 8192, ..Shadows::DEFAULT }, "shadow_map_size"),
        (Shadows { distance_m: f64::NAN, ..Shadows::DEFAULT }, "distance_m"),
    ] {
        let e = renderer.render(&source, &at, &RenderSettings { shadows: Some(shadows), ..LIT }).unwrap_err();
        assert!(e.to_string().contains(field), "{e}");
    }
}
