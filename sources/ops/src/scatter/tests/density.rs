//! Each class gets its rule's density: on a local grid, across the
//! antimeridian and near a pole.

use relief_source::{Extent, Instance};

use super::super::lattice::{JitteredLattice, meridian_arc_m, parallel_radius_m, wrap_lon};
use super::placement::min_spacing_m;
use super::{Input, Scene, block, flat, geodetic, num, open, projected, rule, spec, uniform};

/// Instances per km² of `model` inside `window` of `area_km2`.
fn density(instances: &[Instance], model: &str, window: &Extent, area_km2: f64) -> f64 {
    let n = instances.iter().filter(|i| i.model == model && window.contains(i.position[0], i.position[1])).count();
    n as f64 / area_km2
}

fn within(actual: f64, expected: f64, tolerance: f64) -> bool {
    (actual - expected).abs() <= expected * tolerance
}

#[test]
fn each_class_gets_its_rule_density_and_the_density_raster_thins_it() {
    // Three bands one tile (1024 m) wide and two tall: class 1 at 21000
    // per km², class 2 at 5000, class 3 at 21000 under a density raster of 0.5.
    let x0 = 20.0 * 1024.0;
    let band = move |x: f64| ((x - x0) / 1024.0).floor();
    let classes = Input::Raster(Box::new(move |x, _| (band(x) + 1.0) as f32));
    let canopy = Input::Raster(Box::new(move |x, _| if band(x) >= 2.0 { 0.5 } else { 1.0 }));
    let s = Scene::new(projected(), vec![classes, flat(), canopy]);
    let rules =
        vec![rule(1, "conifer", 21_000.0, &[]), rule(2, "broadleaf", 5000.0, &[]), rule(3, "shrub", 21_000.0, &[])];
    let source = open(&spec(&["landcover", "dem", "canopy"], rules, &[]), &projected());
    let instances = s.instances(&source, &block(6, 20, 20, 3, 2));
    // Windows inside each band, two samples (32 m) clear of class edges.
    let (y_min, y_max) = (65_536.0 - 22.0 * 1024.0 + 32.0, 65_536.0 - 20.0 * 1024.0 - 32.0);
    for (b, model, expected) in [(0.0, "conifer", 21_000.0), (1.0, "broadleaf", 5000.0), (2.0, "shrub", 10_500.0)] {
        let window = Extent::new(x0 + b * 1024.0 + 32.0, y_min, x0 + (b + 1.0) * 1024.0 - 32.0, y_max);
        let area_km2 = window.width() * window.height() / 1e6;
        let d = density(&instances, model, &window, area_km2);
        assert!(within(d, expected, 0.05), "{model}: {d} per km², expected {expected}");
    }
    // No class strays: each instance's nearest class sample (16 m apart)
    // is its rule's class.
    for i in &instances {
        let sample_x = (i.position[0] / 16.0).round() * 16.0;
        assert_eq!(i.model, ["conifer", "broadleaf", "shrub"][band(sample_x) as usize], "{i:?}");
    }
}

/// The area of a longitude/latitude window on the ellipsoid, km².
fn area_km2(lon_deg: f64, lat0: f64, lat1: f64) -> f64 {
    let steps = 1000;
    let mut area = 0.0;
    for k in 0..steps {
        let (a, b) =
            (lat0 + (lat1 - lat0) * k as f64 / steps as f64, lat0 + (lat1 - lat0) * (k + 1) as f64 / steps as f64);
        area += parallel_radius_m(f64::midpoint(a, b)) * (meridian_arc_m(b) - meridian_arc_m(a));
    }
    area * lon_deg.to_radians() / 1e6
}

#[test]
fn the_antimeridian_has_no_seam_no_gap_and_no_duplicate() {
    let s = Scene::new(geodetic(), vec![uniform(5.0), flat()]);
    let rules = vec![rule(5, "conifer", 5000.0, &[("spacing", num(6.0))])];
    let source = open(&spec(&["landcover", "dem"], rules, &[]), &geodetic());
    // Level 14 (the default): 32768 columns, rows 8190 and 8191 just north
    // of the equator; two columns each side of lon 180.
    let mut keys = block(14, 32_766, 8190, 2, 2);
    keys.extend(block(14, 0, 8190, 2, 2));
    let instances = s.instances(&source, &keys);
    let (lat0, lat1) = (0.001, 0.021);
    for (west, east) in [(179.98, 180.0), (-180.0, -179.98)] {
        let window = Extent::new(west, lat0, east, lat1);
        let d = density(&instances, "conifer", &window, area_km2(east - west, lat0, lat1));
        assert!(within(d, 5000.0, 0.05), "{west}..{east}: {d} per km²");
    }
    // A thin strip on the line itself: no gap.
    let strip = |w: f64, e: f64| Extent::new(w, lat0, e, lat1);
    let near: usize = [strip(179.999, 180.0), strip(-180.0, -179.999)]
        .iter()
        .map(|e| instances.iter().filter(|i| e.contains(i.position[0], i.position[1])).count())
        .sum();
    let expected = 5000.0 * area_km2(0.002, lat0, lat1);
    assert!(within(near as f64, expected, 0.15), "{near} near the line, expected {expected}");
    // Spacing holds across the line.
    let close: Vec<[f64; 3]> =
        instances.iter().filter(|i| wrap_lon(i.position[0] - 180.0).abs() < 0.001).map(|i| i.position).collect();
    let d = min_spacing_m(&close, true, 6.0);
    assert!(d >= 6.0 - 1e-3, "{d} m between two instances across the antimeridian");
}

#[test]
fn near_a_pole_positions_are_finite_and_the_density_holds() {
    let s = Scene::new(geodetic(), vec![uniform(5.0), flat()]);
    let rules = vec![rule(5, "conifer", 1000.0, &[("spacing", num(10.0))])];
    // Level 10: tiles of 0.176 degrees; row 0 reaches the pole.
    let source = open(&spec(&["landcover", "dem"], rules, &[("level", num(10.0))]), &geodetic());
    let instances = s.instances(&source, &block(10, 1024, 0, 40, 1));
    assert!(instances.iter().all(|i| i.position.iter().all(|v| v.is_finite()) && i.position[1] <= 90.0));
    let (lat0, lat1) = (89.89, 89.91);
    let window = Extent::new(0.5, lat0, 6.5, lat1);
    let d = density(&instances, "conifer", &window, area_km2(6.0, lat0, lat1));
    assert!(within(d, 1000.0, 0.05), "{d} per km² at lat 89.9");
    // The tiles that hold the pole build, with finite positions.
    let polar = s.instances(&source, &block(10, 0, 0, 3, 1));
    assert!(polar.iter().all(|i| i.position.iter().all(|v| v.is_finite()) && i.position[1] <= 90.0));
}

#[test]
fn the_polar_cap_gets_its_density_too() {
    // Within 0.01 degree (1.1 km) of the north pole, all the way round.
    let lattice = JitteredLattice { cell_m: JitteredLattice::cell_size_m(1000.0).unwrap(), spacing_m: 10.0, key: 42 };
    let mut candidates = Vec::new();
    lattice
        .for_each(&geodetic(), &Extent::new(-180.0, 89.99, 180.0, 90.0), |c| {
            candidates.push(c);
            Ok::<(), ()>(())
        })
        .unwrap();
    assert!(candidates.iter().all(|c| c.x.is_finite() && (-180.0..180.0).contains(&c.x) && c.y <= 90.0));
    let inside = candidates.iter().filter(|c| c.y >= 89.99).count();
    let expected = 1000.0 * area_km2(360.0, 89.99, 90.0);
    assert!(within(inside as f64, expected, 0.05), "{inside} in the cap, expected {expected}");
    let positions: Vec<[f64; 3]> = candidates.iter().map(|c| [c.x, c.y, 0.0]).collect();
    assert!(min_spacing_m(&positions, true, 10.0) >= 10.0 - 1e-3);
}
