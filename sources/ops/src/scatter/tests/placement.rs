//! Where instances stand: only on their class, never on nodata, spaced,
//! anchored at the lowest ground of their footprint; points too.

use relief_source::geodesy::ecef_from_geodetic;
use relief_source::{SourceError, TileKey};

use super::{Input, Scene, block, flat, geodetic, list, num, open, point, projected, rule, spec, text, uniform};

/// Metres between two geodetic positions (lon, lat; the ground ignored),
/// as a straight line through ECEF: never more than the distance on the
/// ellipsoid, and equal to it to far below a millimetre at these ranges.
pub fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    let (p, q) = (ecef_from_geodetic(a[0], a[1], 0.0), ecef_from_geodetic(b[0], b[1], 0.0));
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// The smallest distance between two of `points` closer than `reach_m`
/// (infinity when none is), in metres: positions in metres on a projected
/// grid, in degrees on the geodetic one.
pub fn min_spacing_m(points: &[[f64; 3]], geodetic: bool, reach_m: f64) -> f64 {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a[1].total_cmp(&b[1]));
    // A degree of latitude is 110.5 km at least.
    let reach_y = if geodetic { reach_m / 110_000.0 } else { reach_m };
    let mut best = f64::INFINITY;
    for (n, a) in sorted.iter().enumerate() {
        for b in sorted[n + 1..].iter().take_while(|b| b[1] - a[1] <= reach_y) {
            let d = if geodetic { distance_m(*a, *b) } else { (a[0] - b[0]).hypot(a[1] - b[1]) };
            best = best.min(d);
        }
    }
    best
}

#[test]
fn spacing_is_kept_on_a_local_grid_and_on_the_planet() {
    let rules = vec![rule(1, "conifer", 21_000.0, &[("spacing", num(4.0))])];
    let s = Scene::new(projected(), vec![uniform(1.0), flat()]);
    let source = open(&spec(&["landcover", "dem"], rules.clone(), &[("level", num(8.0))]), &projected());
    let instances = s.instances(&source, &block(8, 80, 80, 2, 2));
    assert!(instances.len() > 4000, "{}", instances.len());
    let positions: Vec<[f64; 3]> = instances.iter().map(|i| i.position).collect();
    let d = min_spacing_m(&positions, false, 4.0);
    assert!(d >= 4.0, "{d}");
    // At 45 degrees north (level 16 tiles: about 300 m).
    let s = Scene::new(geodetic(), vec![uniform(1.0), flat()]);
    let source = open(&spec(&["landcover", "dem"], rules, &[("level", num(16.0))]), &geodetic());
    let key = s.grid.key_at(16, 7.0, 45.0).unwrap();
    let instances = s.instances(&source, &block(16, key.x, key.y, 2, 2));
    assert!(instances.len() > 4000, "{}", instances.len());
    let positions: Vec<[f64; 3]> = instances.iter().map(|i| i.position).collect();
    let d = min_spacing_m(&positions, true, 4.0);
    assert!(d >= 4.0 - 1e-3, "{d}");
}

#[test]
fn nothing_stands_on_nodata_or_off_its_class() {
    // Class 1 with a round hole of nodata; ground with a nodata strip.
    let classes =
        Input::Raster(Box::new(|x, y| if (x - 20_992.0).hypot(y - 44_544.0) < 200.0 { f32::NAN } else { 1.0 }));
    let ground = Input::Raster(Box::new(|x, _| if (20_700.0..20_800.0).contains(&x) { f32::NAN } else { 50.0 }));
    let s = Scene::new(projected(), vec![classes, ground]);
    let source = open(&spec(&["landcover", "dem"], vec![rule(1, "conifer", 10_000.0, &[])], &[]), &projected());
    let instances = s.instances(&source, &[TileKey::new(6, 20, 20)]);
    assert!(instances.len() > 5000);
    for i in &instances {
        let [x, y, z] = i.position;
        // The nearest class sample (16 m apart) is class 1, not the hole.
        let (sx, sy) = ((x / 16.0).round() * 16.0, (y / 16.0).round() * 16.0);
        assert!((sx - 20_992.0).hypot(sy - 44_544.0) >= 200.0, "{i:?} on the hole");
        // The footprint (0.5 m) stays where no bilinear sample is nodata:
        // off [20688, 20800), the strip and the sample west of it.
        assert!(!(20_687.5..20_800.5).contains(&x), "{i:?} on nodata ground");
        assert_eq!(z, 50.0);
    }
}

#[test]
fn an_instance_at_a_cliff_stands_on_the_lower_side() {
    // 0 m west of x = 20992, 1000 m from there: with 16 m samples the
    // bilinear ground ramps over [20976, 20992].
    let edge = 20_992.0;
    let ground = Input::Raster(Box::new(move |x, _| if x < edge { 0.0 } else { 1000.0 }));
    let s = Scene::new(projected(), vec![uniform(1.0), ground]);
    let rules = vec![rule(1, "conifer", 21_000.0, &[])];
    let source = open(&spec(&["landcover", "dem"], rules, &[("anchor_radius", num(20.0))]), &projected());
    let instances = s.instances(&source, &[TileKey::new(6, 20, 20)]);
    let bilinear = |x: f64| ((x - (edge - 16.0)) / 16.0).clamp(0.0, 1.0) * 1000.0;
    let mut on_the_edge = 0;
    for i in &instances {
        let [x, _, z] = i.position;
        let lowest = [x - 20.0, x, x + 20.0].map(bilinear).into_iter().fold(f64::INFINITY, f64::min);
        assert!((z - lowest).abs() < 1e-3, "{i:?}: expected {lowest}");
        if x >= edge && x - 20.0 <= edge - 16.0 {
            // Its centre is on the high side, its footprint reaches down.
            assert_eq!(z, 0.0, "{i:?}");
            on_the_edge += 1;
        }
    }
    assert!(on_the_edge > 50, "{on_the_edge}");
}

#[test]
fn a_class_raster_that_is_not_integer_fails_naming_the_input() {
    let classes = Input::Raster(Box::new(|x, _| if x > 21_000.0 { 12.5 } else { 12.0 }));
    let s = Scene::new(projected(), vec![classes, flat()]);
    let source = open(&spec(&["landcover", "dem"], vec![rule(12, "conifer", 1000.0, &[])], &[]), &projected());
    let err = s.try_tile(&source, TileKey::new(6, 20, 20)).unwrap_err();
    let SourceError::Input { input, message } = &err else { panic!("{err}") };
    assert_eq!(input, "landcover");
    assert!(message.starts_with("class raster 'landcover' holds 12.5 at ("), "{message}");
    assert!(message.contains("class codes are integers"), "{message}");
    assert!(message.contains("resampling = \"nearest\" on source 'landcover'"), "{message}");
}

#[test]
fn points_become_instances_without_a_density_raster() {
    let x = |k: f64| 20_500.0 + 100.0 * k;
    let y = 44_500.0;
    let classes = Input::Raster(Box::new(move |px, _| if px < x(3.5) { 1.0 } else { 9.0 }));
    let ground = Input::Raster(Box::new(move |px, _| if px > x(4.5) { f32::NAN } else { 10.0 }));
    let points = Input::Points(vec![
        point(1, x(0.0), y, &[]),
        point(2, x(1.0), y, &[("model", "house")]),
        point(3, x(2.0), y, &[("model", "pine")]),
        point(4, x(4.0), y, &[]),
        point(5, x(4.2), y, &[("model", "shrub")]),
        point(6, x(5.0), y, &[("model", "shrub")]),
    ]);
    let s = Scene::new(projected(), vec![classes, ground, points]);
    let rules = vec![rule(1, "broadleaf", 0.0, &[("scale", num(2.0)), ("rotation", list(&[10.0, 20.0]))])];
    let spec = spec(&["landcover", "dem", "trees"], rules, &[("points_input", text("trees"))]);
    let source = open(&spec, &projected());
    let tile = s.tile(&source, TileKey::new(6, 20, 20));
    let placed: Vec<(u64, &str, f64)> =
        tile.instances.iter().map(|i| (i.feature_id, i.model.as_str(), i.scale)).collect();
    assert_eq!(placed, [(1, "broadleaf", 2.0), (2, "house", 2.0), (5, "shrub", 1.0)]);
    assert!((10.0..=20.0).contains(&tile.instances[0].rotation_deg));
    assert_eq!(tile.instances[0].position, [x(0.0), y, 10.0]);
    let skipped: Vec<(u64, &str)> = tile.skipped.iter().map(|s| (s.feature_id, s.reason.as_str())).collect();
    assert_eq!(skipped.len(), 3, "{skipped:?}");
    assert!(skipped[0].1.starts_with("model 'pine' is not known (known: broadleaf, conifer, house, shrub)"));
    assert_eq!(skipped[1].1, "the point has no 'model' attribute and stands on class 9, which has no rule");
    assert_eq!(skipped[2].1, "the ground has no data under the point");
}
