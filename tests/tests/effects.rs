//! Effects a scene declares, on lavapipe: each drawn where it must be when
//! declared, and when not declared, none of its work done (its pass never
//! built or run, the state without it).

#![allow(clippy::unwrap_used, reason = "a test")]

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::scenes;

const SIZE: (u32, u32) = (200, 120);
/// The fog of these tests: thick enough to see over the hill's 40 km.
const FOG: &str = "fog = { density = 0.0002, falloff_m = 3000, color = \"#c0c8d0\" }\n";
const FOG_RGB: [f64; 3] = [192.0, 200.0, 208.0];

/// From south of the hill, low, looking north over it to the horizon.
fn across_the_hill() -> pb::Camera {
    scenes::camera(10.25, 44.93, 2500.0, 0.0, -8.0)
}

async fn frame(effects: &str, camera: pb::Camera) -> (pb::RenderResponse, pb::SceneState) {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), effects).unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let frame = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    daemon.stop(&[]).unwrap();
    (frame, state)
}

fn pixel(f: &pb::RenderResponse, x: usize, y: usize) -> [f64; 3] {
    let i = (y * f.width as usize + x) * 4;
    [f64::from(f.image[i]), f64::from(f.image[i + 1]), f64::from(f.image[i + 2])]
}

fn pass<'a>(f: &'a pb::RenderResponse, name: &str) -> &'a pb::PassState {
    f.pass_counters.iter().find(|p| p.name == name).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fog_hazes_distant_terrain_and_costs_nothing_undeclared() {
    let (off, off_state) = frame("[effects]\nlighting = {}\n", across_the_hill()).await;
    let (on, on_state) = frame(&format!("[effects]\nlighting = {{}}\n{FOG}"), across_the_hill()).await;

    // Undeclared: the pass was never built nor run, the state has no fog.
    let idle = pass(&off, "fog");
    assert!(!idle.built && idle.runs == 0, "{idle:?}");
    assert!(off.passes.iter().all(|p| p.pass != "fog"));
    assert!(off_state.effects.iter().all(|e| e.name != "fog"), "{:?}", off_state.effects);
    // Declared: built, ran in this frame, in the state with its cost.
    let ran = pass(&on, "fog");
    assert!(ran.built && ran.runs >= 1 && ran.total_ms > 0.0, "{ran:?}");
    let effect = on_state.effects.iter().find(|e| e.name == "fog").unwrap();
    assert!(effect.ran && effect.last_cost_ms > 0.0, "{effect:?}");

    // How far each pixel went from its clear colour towards the fog's:
    // 0 clear, 1 all fog. Rows near the bottom see the hill's near slope,
    // rows higher up see farther terrain: the farther, the hazier.
    let haze = |x: usize, y: usize| {
        let (a, b) = (pixel(&off, x, y), pixel(&on, x, y));
        let (moved, room): (f64, f64) = (0..3)
            .map(|k| ((b[k] - a[k]).abs(), (FOG_RGB[k] - a[k]).abs()))
            .fold((0.0, 0.0), |s, v| (s.0 + v.0, s.1 + v.1));
        (room > 30.0).then_some(moved / room)
    };
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let band = |rows: std::ops::Range<usize>| {
        let v: Vec<f64> = rows.flat_map(|y| (0..w).filter_map(move |x| haze(x, y))).collect();
        assert!(!v.is_empty());
        v.iter().sum::<f64>() / v.len() as f64
    };
    let near = band(h - 15..h);
    let far = band(h / 2..h / 2 + 10);
    assert!(near < far, "near {near:.3}, far {far:.3}");
    assert!(far > 0.15 && far <= 1.0 && near >= 0.0, "near {near:.3}, far {far:.3}");
    let changed =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| pixel(&on, x, y) != pixel(&off, x, y));
    assert!(changed.count() > w * h / 2, "fog left most of the frame as it was");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_camera_inside_fog_sees_fog_not_nan() {
    // 30 m above the hill's foot in fog of 100 m visibility.
    let thick = "[effects]\nlighting = {}\nfog = { density = 0.04, falloff_m = 2000, color = \"#c0c8d0\" }\n";
    let (inside, _) = frame(thick, scenes::camera(10.25, 45.0, 60.0, 0.0, 0.0)).await;
    let (w, h) = (inside.width as usize, inside.height as usize);
    let fogged = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| pixel(&inside, x, y).iter().zip(FOG_RGB).all(|(p, f)| (p - f).abs() <= 3.0))
        .count();
    assert!(fogged > w * h * 9 / 10, "{fogged} of {} pixels are the fog", w * h);
}

/// Mean colour of the rows `rows` of a frame.
fn mean(f: &pb::RenderResponse, rows: std::ops::Range<usize>) -> [f64; 3] {
    let w = f.width as usize;
    let n = (rows.len() * w) as f64;
    let mut sum = [0.0; 3];
    for y in rows {
        for x in 0..w {
            let p = pixel(f, x, y);
            for k in 0..3 {
                sum[k] += p[k] / n;
            }
        }
    }
    sum
}

async fn frames_of(effects: &str, views: &[(pb::Camera, Option<pb::Sun>, Option<u32>)]) -> Vec<pb::RenderResponse> {
    let views: Vec<_> = views
        .iter()
        .map(|(camera, sun, steps)| {
            let quality = steps.map(|s| pb::QualityOverrides { atmosphere_steps: Some(s), ..Default::default() });
            (*camera, sun.clone(), quality)
        })
        .collect();
    frames_with(effects, &views).await.0
}

/// Frames of the hill scene with `effects`, each view with its camera, sun
/// and quality overrides; and the scene's state after them.
async fn frames_with(
    effects: &str,
    views: &[(pb::Camera, Option<pb::Sun>, Option<pb::QualityOverrides>)],
) -> (Vec<pb::RenderResponse>, pb::SceneState) {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), effects).unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut out = Vec::new();
    for (camera, sun, quality) in views {
        let request = pb::RenderRequest {
            camera: Some(*camera),
            width: SIZE.0,
            height: SIZE.1,
            format: pb::ImageFormat::Rgba8 as i32,
            quality: quality.clone(),
            sun: sun.clone(),
        };
        let mut views = relief_proto::v1::view_service_client::ViewServiceClient::new(channel.clone())
            .max_decoding_message_size(64 << 20);
        out.push(views.render(request).await.unwrap().into_inner());
    }
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    daemon.stop(&[]).unwrap();
    (out, state)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shadows_fall_away_from_the_sun_and_cost_nothing_undeclared() {
    // Straight down over the hill, the sun low in the west: its shadow
    // lies east of it (right in the image).
    let above = scenes::camera(10.25, 45.25, 25_000.0, 0.0, -90.0);
    let west = Some(sun(270.0, 4.0));
    let (off, off_state) = frames_with("[effects]\nlighting = {}\n", &[(above, west.clone(), None)]).await;
    let knobs = pb::QualityOverrides { shadow_cascades: Some(1), shadow_map_size: Some(512), ..Default::default() };
    let views = [
        (above, west.clone(), None),
        (above, west.clone(), Some(knobs)),
        (above, Some(sun(270.0, -0.1)), None),
        (above, west.clone(), None),
        (above, west.clone(), None),
    ];
    let (on, on_state) = frames_with("[effects]\nlighting = {}\nshadows = {}\n", &views).await;

    let idle = pass(&off[0], "shadows");
    assert!(!idle.built && idle.runs == 0, "{idle:?}");
    assert!(off[0].passes.iter().all(|p| p.pass != "shadows"));
    assert!(off_state.effects.iter().all(|e| e.name != "shadows"));
    let ran = pass(&on[0], "shadows");
    assert!(ran.built && ran.runs >= 1 && ran.total_ms > 0.0, "{ran:?}");
    let effect = on_state.effects.iter().find(|e| e.name == "shadows").unwrap();
    assert!(effect.ran && effect.last_cost_ms > 0.0, "{effect:?}");

    // Pixels the shadows darkened by more than 5%, by half of the image.
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let darkened = |f: &pb::RenderResponse, xs: std::ops::Range<usize>| {
        xs.flat_map(|x| (0..h).map(move |y| (x, y)))
            .filter(|&(x, y)| {
                let (a, b): (f64, f64) = (pixel(&off[0], x, y).iter().sum(), pixel(f, x, y).iter().sum());
                b < a * 0.95
            })
            .count()
    };
    let (west_half, east_half) = (darkened(&on[0], 0..w / 2), darkened(&on[0], w / 2..w));
    assert!(east_half > w * h / 50, "east {east_half}, west {west_half}");
    assert!(east_half > 10 * west_half.max(1), "east {east_half}, west {west_half}");
    // The knobs are honoured: one small map draws other shadows, yet east.
    assert_ne!(on[1].image, on[0].image, "one 512-texel cascade drew what three of 2048 did");
    assert!(darkened(&on[1], w / 2..w) > 10 * darkened(&on[1], 0..w / 2).max(1));
    // A sun just under the horizon: no maps, a valid image.
    let dusk = &on[2];
    assert_eq!(dusk.image.len(), w * h * 4);
    assert!(pass(dusk, "shadows").runs >= 3);
    // The same view again: its maps drawn, then kept (still camera, still
    // sun, same terrain), to the same image.
    let drawn = |f: &pb::RenderResponse| f.drawn.as_ref().map(|d| (d.shadow_maps_drawn, d.shadow_maps_kept));
    let cascades = drawn(&on[3]).unwrap().0;
    assert!(cascades > 0, "{:?}", on[3].drawn);
    assert_eq!(drawn(&on[4]), Some((0, cascades)), "a still view keeps its maps");
    assert_eq!(on[4].image, on[3].image);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_an_atmosphere_shadowed_air_scatters_no_sun() {
    // East of the hill, low, looking west towards a low sun behind it: the
    // sky just above the hill is seen through air in the hill's shadow.
    let east_foot = scenes::camera(10.40, 45.25, 700.0, 270.0, 2.0);
    let view = [(east_foot, Some(sun(270.0, 3.0)), None)];
    let (bare, _) = frames_with("[effects]\nlighting = {}\n", &view).await;
    let (plain, _) = frames_with("[effects]\nlighting = {}\natmosphere = {}\n", &view).await;
    let (shadowed, _) = frames_with("[effects]\nlighting = {}\natmosphere = {}\nshadows = {}\n", &view).await;
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    // Sky pixels: the clear colour where only the terrain is drawn. There
    // the shadows' own pass changes nothing: any difference is the air's.
    let clear = pixel(&bare[0], 0, 0);
    let sky: Vec<(usize, usize)> =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| pixel(&bare[0], x, y) == clear).collect();
    assert!(sky.len() > w * h / 8, "{} sky pixels", sky.len());
    let light = |f: &pb::RenderResponse| sky.iter().map(|&(x, y)| pixel(f, x, y).iter().sum::<f64>()).sum::<f64>();
    let (lit_air, shaded_air) = (light(&plain[0]), light(&shadowed[0]));
    assert!(shaded_air < lit_air * 0.99, "sky with shadows {shaded_air}, without {lit_air}");
    // Only ever darker.
    assert!(sky.iter().all(|&(x, y)| {
        let (a, b) = (pixel(&plain[0], x, y), pixel(&shadowed[0], x, y));
        (0..3).all(|k| b[k] <= a[k] + 1.0)
    }));
    assert!(pass(&shadowed[0], "atmosphere").built && pass(&shadowed[0], "shadows").built);
}

fn sun(azimuth_deg: f64, elevation_deg: f64) -> pb::Sun {
    pb::Sun { azimuth_deg: Some(azimuth_deg), elevation_deg: Some(elevation_deg), ..Default::default() }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_atmosphere_gives_a_blue_sky_by_day_haze_far_off_and_a_dark_night() {
    // Level, at 2,500 m: the upper half is sky, the lower the hill.
    let level = scenes::camera(10.25, 44.93, 2500.0, 0.0, 0.0);
    let views = [(level, None, None), (across_the_hill(), None, None)];
    let off = frames_of("[effects]\nlighting = {}\n", &views).await;
    let on_views = [
        (level, None, None),
        (across_the_hill(), None, None),
        (level, Some(sun(315.0, -30.0)), None),
        (level, Some(sun(315.0, -0.1)), None),
        (level, Some(sun(0.0, 90.0)), None),
        (level, None, Some(1)),
    ];
    let on = frames_of("[effects]\nlighting = {}\natmosphere = {}\n", &on_views).await;

    // Undeclared: never built nor run. Declared: built and ran.
    let idle = pass(&off[0], "atmosphere");
    assert!(!idle.built && idle.runs == 0, "{idle:?}");
    let ran = pass(&on[0], "atmosphere");
    assert!(ran.built && ran.runs >= 1 && ran.total_ms > 0.0, "{ran:?}");

    // The sky by day is blue and bright where it was the dark clear colour.
    let h = SIZE.1 as usize;
    let sky_off = mean(&off[0], 0..h / 4);
    let sky = mean(&on[0], 0..h / 4);
    assert!(sky[2] > sky[0] + 20.0 && sky[2] > 120.0, "day sky {sky:?}");
    assert!(sky[2] > sky_off[2] + 60.0, "day sky {sky:?} against the clear colour {sky_off:?}");
    // Farther terrain is hazier: towards the sky's colour more than near.
    let towards = |y0: usize, y1: usize| {
        let (a, b) = (mean(&off[1], y0..y1), mean(&on[1], y0..y1));
        (0..3).map(|k| (b[k] - a[k]).abs()).sum::<f64>()
    };
    let (near, far) = (towards(h - 15, h), towards(h / 2, h / 2 + 10));
    assert!(far > near, "haze near {near:.1}, far {far:.1}");

    // Night: a dark sky, though not black (a NaN draws black).
    let night = mean(&on[2], 0..h / 4);
    assert!(night.iter().all(|c| *c < 40.0), "night sky {night:?}");
    assert!(night.iter().sum::<f64>() > 3.0, "night sky black: {night:?}");
    // The sun a tenth of a degree under the horizon: twilight, between.
    let dusk = mean(&on[3], 0..h / 4);
    let (dusk_sum, day_sum, night_sum): (f64, f64, f64) = (dusk.iter().sum(), sky.iter().sum(), night.iter().sum());
    assert!(dusk_sum > night_sum && dusk_sum < day_sum, "dusk {dusk:?}, day {sky:?}, night {night:?}");
    // The sun at the zenith: a blue sky still.
    let zenith = mean(&on[4], 0..h / 4);
    assert!(zenith[2] > zenith[0] && zenith[2] > 100.0, "zenith sun sky {zenith:?}");
    // The steps are the knob: one step is not sixteen.
    assert_ne!(on[5].image, on[0].image, "atmosphere_steps = 1 drew what 16 did");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn from_space_the_planet_has_a_limb_and_a_pole_has_its_midnight_sun() {
    // 1,000 km up, looking north down at the planet's edge: the solid
    // horizon lies acos(R / (R + h)) = 30.18 degrees below level, so at the
    // middle row; the atmosphere's top (50 km) 0.78 degrees (2 rows) above.
    let dip = (6_378_137.0f64 / 7_378_137.0).acos().to_degrees();
    let views = [
        (scenes::camera(10.25, 10.0, 1.0e6, 0.0, -dip), Some(sun(0.0, 30.0)), None),
        // Near the north pole at midnight UT on the June solstice, level.
        (
            scenes::camera(10.0, 89.5, 2000.0, 180.0, 0.0),
            Some(pb::Sun { time: "2026-06-21T00:00:00Z".into(), ..Default::default() }),
            None,
        ),
    ];
    let on = frames_of("[effects]\nlighting = {}\natmosphere = {}\n", &views).await;
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    // Down the middle column: space, then the limb's glow in the rows just
    // above the solid horizon, then the lit planet.
    let column: Vec<f64> = (0..h).map(|y| pixel(&on[0], w / 2, y).iter().sum()).collect();
    let space = column[0];
    assert!(space < 60.0, "space {space}: {column:?}");
    assert!(column[..h / 2 - 8].iter().all(|v| *v < space + 10.0), "sky far above the limb: {column:?}");
    assert!(column[h / 2 - 4..h / 2].iter().any(|v| *v > space + 30.0), "no limb above the horizon: {column:?}");
    assert!(column[h / 2 + 3..].iter().all(|v| *v > space + 60.0), "the planet below: {column:?}");
    // Midnight sun: the sun is up at the pole, and the sky is day-blue.
    let sun = on[1].sun.as_ref().unwrap();
    assert!(sun.elevation_deg > 20.0, "{sun:?}");
    let sky = mean(&on[1], 0..h / 4);
    assert!(sky[2] > sky[0] && sky[2] > 100.0, "midnight sun sky {sky:?}");
}

#[test]
fn effects_relief_cannot_draw_are_refused_with_the_known_ones() {
    for (effects, message) in [
        (
            "[effects]\nvegetation = {}\n",
            "effects.vegetation': not drawn yet (drawn: lighting, atmosphere, fog, shadows, water, detail)",
        ),
        (
            "[effects]\nsmog = {}\n",
            "effects.smog': unknown effect (drawn: lighting, atmosphere, fog, shadows, water, detail)",
        ),
        ("[effects]\nshadows = {}\n", "effects.shadows': shadows take away the lighting's sunlight: declare lighting"),
        ("[effects]\nlighting = {}\nshadows = { cascades = 2 }\n", "effects.shadows.cascades"),
        ("[effects]\nlighting = {}\nshadows = { distance_m = 10 }\n", "effects.shadows.distance_m"),
        ("[quality]\nshadow_cascades = 2\n", "declares no shadows"),
        ("[effects]\nlighting = {}\nshadows = {}\n[quality]\nshadow_cascades = 5\n", "quality.shadow_cascades"),
        ("[effects]\nlighting = {}\nshadows = {}\n[quality]\nshadow_map_size = 1000\n", "quality.shadow_map_size"),
        ("[effects]\natmosphere = { steps = 8 }\n", "effects.atmosphere.steps"),
        ("[quality]\natmosphere_steps = 8\n", "declares no atmosphere"),
        ("[effects]\natmosphere = {}\n[quality]\natmosphere_steps = 0\n", "quality.atmosphere_steps"),
        ("[quality]\natmosphere_downsample = 2\n", "declares no atmosphere"),
        ("[effects]\natmosphere = {}\n[quality]\natmosphere_downsample = 9\n", "quality.atmosphere_downsample"),
        ("[effects]\nfog = { color = '#c0c8d080' }\n", "effects.fog.color"),
        ("[sun]\nazimuth_deg = 10\nelevation_deg = 20\n", "no declared effect follows the sun"),
        ("[effects]\nfog = { visibility_m = 100 }\n", "effects.fog.visibility_m"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let (code, text) = relief_tests::daemon::check(&scenes::hill(dir.path(), effects).unwrap()).unwrap();
        assert_ne!(code, 0, "{effects}: accepted");
        assert!(text.contains(message) && text.contains("scene.toml"), "{effects}: {text}");
    }
}
