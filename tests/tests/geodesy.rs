//! relief's WGS84 geodesy (`relief_source::geodesy`) against PROJ, through
//! GDAL's OSR (the one PROJ relief links): geodetic to ECEF (EPSG:4979 to
//! EPSG:4978), ECEF to geodetic, and east-north-up offsets (PROJ's
//! `+proj=topocentric`), each at 10,000 seeded random points from 11 km
//! below the ellipsoid to 40,000 km above it, the poles and the
//! antimeridian included. Stated tolerance: 1 mm, everywhere.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, CoordTransformOptions, SpatialRef};
use relief_source::geodesy::{self, WGS84_A};
use relief_tests::fixtures::Lcg;

/// The stated tolerance, metres.
const TOLERANCE_M: f64 = 1e-3;

const POINTS: usize = 10_000;

fn srs(definition: &str) -> SpatialRef {
    let mut s = SpatialRef::from_definition(definition).unwrap();
    s.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    s
}

/// A height from the deepest trench to beyond geostationary orbit, spread
/// over the ranges that matter: near the ground, low orbit, deep space.
fn height(rng: &mut Lcg) -> f64 {
    match (rng.next_f64() * 3.0) as u32 {
        0 => rng.range(-11_000.0, 9_000.0),
        1 => rng.range(9_000.0, 2_000_000.0),
        _ => rng.range(2_000_000.0, 40_000_000.0),
    }
}

/// (lon, lat, height): the hard ones first (exact poles, exact +-180, the
/// extreme heights), then random points, latitudes uniform on the sphere.
fn points() -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(POINTS);
    for h in [-11_000.0, 0.0, 1.0, 8_848.0, 35_786_000.0, 40_000_000.0] {
        for lon in [-180.0, -179.999_999_9, -90.0, 0.0, 45.0, 179.999_999_9, 180.0] {
            for lat in [-90.0, -89.999_999_9, -45.0, 0.0, 1e-12, 45.0, 89.999_999, 89.999_999_9, 90.0] {
                out.push([lon, lat, h]);
            }
        }
    }
    let mut rng = Lcg(0x0067_656f_6465_7379);
    while out.len() < POINTS {
        let lon = rng.range(-180.0, 180.0);
        let lat = rng.range(-1.0, 1.0).asin().to_degrees();
        out.push([lon, lat, height(&mut rng)]);
    }
    out
}

/// PROJ's geocentric coordinates of `points`.
fn proj_ecef(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let t = CoordTransform::new(&srs("EPSG:4979"), &srs("EPSG:4978")).unwrap();
    let mut xs: Vec<f64> = points.iter().map(|p| p[0]).collect();
    let mut ys: Vec<f64> = points.iter().map(|p| p[1]).collect();
    let mut zs: Vec<f64> = points.iter().map(|p| p[2]).collect();
    t.transform_coords(&mut xs, &mut ys, &mut zs).unwrap();
    (0..points.len()).map(|k| [xs[k], ys[k], zs[k]]).collect()
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// How far apart two geodetic positions are, in metres: along the
/// meridian, along the parallel (which shrinks to nothing at a pole, where
/// longitude means nothing) and in height, each at the point's own radius.
fn geodetic_gap(a: (f64, f64, f64), b: [f64; 3]) -> f64 {
    let r = WGS84_A + b[2].max(0.0);
    let dlat = (a.1 - b[1]).to_radians() * r;
    let dlon = ((a.0 - b[0] + 540.0).rem_euclid(360.0) - 180.0).to_radians() * r * b[1].to_radians().cos();
    (dlat * dlat + dlon * dlon + (a.2 - b[2]).powi(2)).sqrt()
}

/// The worst of `errors`, with the point it was at, after a line on stderr.
fn worst(what: &str, errors: impl Iterator<Item = (f64, [f64; 3])>) -> (f64, [f64; 3]) {
    let (mut max, mut at, mut count) = (0.0f64, [0.0; 3], 0);
    for (e, p) in errors {
        assert!(e.is_finite(), "{what}: not a number at {p:?}");
        count += 1;
        if e > max {
            (max, at) = (e, p);
        }
    }
    eprintln!("{what}: {count} points, largest difference {max:.3e} m at {at:?}");
    (max, at)
}

#[test]
fn ecef_from_geodetic_agrees_with_proj_within_a_millimetre() {
    let points = points();
    let proj = proj_ecef(&points);
    let (max, at) = worst(
        "ecef_from_geodetic",
        points.iter().zip(&proj).map(|(p, q)| (distance(geodesy::ecef_from_geodetic(p[0], p[1], p[2]), *q), *p)),
    );
    assert!(max <= TOLERANCE_M, "ECEF {max} m from PROJ's at {at:?}");
}

#[test]
fn geodetic_from_ecef_agrees_with_proj_within_a_millimetre() {
    let points = points();
    let ecef = proj_ecef(&points);
    // relief's inverse of PROJ's ECEF gives back the point PROJ started from.
    let (max, at) = worst(
        "geodetic_from_ecef of PROJ's ECEF, against the point it came from",
        points.iter().zip(&ecef).map(|(p, e)| (geodetic_gap(geodesy::geodetic_from_ecef(*e), *p), *p)),
    );
    assert!(max <= TOLERANCE_M, "{max} m from the point PROJ's ECEF came from, at {at:?}");
    // PROJ's own inverse of the same ECEF (its `cart` step: Bowring's
    // closed form, no iteration) drifts from its forward with height: 0.1 mm
    // at 100 km, 1 mm from about 300 km, 1 cm at 1,000 km, 0.4 m at 40,000 km. Where PROJ
    // gives back its own input within 1 mm relief agrees with it within
    // 1 mm; above that, relief agrees with PROJ within PROJ's own
    // round-trip error plus 1 mm, and is the one of the two that is right.
    let t = CoordTransform::new(&srs("EPSG:4978"), &srs("EPSG:4979")).unwrap();
    let mut xs: Vec<f64> = ecef.iter().map(|p| p[0]).collect();
    let mut ys: Vec<f64> = ecef.iter().map(|p| p[1]).collect();
    let mut zs: Vec<f64> = ecef.iter().map(|p| p[2]).collect();
    t.transform_coords(&mut xs, &mut ys, &mut zs).unwrap();
    let proj: Vec<[f64; 3]> = (0..points.len()).map(|k| [xs[k], ys[k], zs[k]]).collect();
    let own = |k: usize| geodetic_gap((proj[k][0], proj[k][1], proj[k][2]), points[k]);
    let lowest_drift = (0..points.len()).filter(|k| own(*k) > TOLERANCE_M).map(|k| points[k][2]).reduce(f64::min);
    eprintln!(
        "PROJ's inverse round-trips its forward within 1 mm below {} m; worst {:.1} mm",
        lowest_drift.map_or("every height".into(), |h| format!("{h:.0}")),
        (0..points.len()).map(own).fold(0.0, f64::max) * 1000.0
    );
    let (max, at) = worst(
        "geodetic_from_ecef against PROJ's inverse, less PROJ's own round-trip error",
        ecef.iter()
            .enumerate()
            .map(|(k, e)| ((geodetic_gap(geodesy::geodetic_from_ecef(*e), proj[k]) - own(k)).max(0.0), points[k])),
    );
    assert!(max <= TOLERANCE_M, "{max} m from PROJ's inverse beyond PROJ's own error, at {at:?}");
    // Up to 100 km (every DEM, every aircraft), plainly within 1 mm of PROJ.
    let (max, at) = worst(
        "geodetic_from_ecef against PROJ's inverse, up to 100 km",
        ecef.iter()
            .enumerate()
            .filter(|(k, _)| points[*k][2] <= 100_000.0)
            .map(|(k, e)| (geodetic_gap(geodesy::geodetic_from_ecef(*e), proj[k]), points[k])),
    );
    assert!(max <= TOLERANCE_M, "{max} m from PROJ's inverse, at {at:?}");
}

/// PROJ's east, north and up of `ecef` points from the topocentric frame at
/// `origin` (lon, lat, height).
fn proj_enu(origin: [f64; 3], ecef: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut options = CoordTransformOptions::new().unwrap();
    options
        .set_coordinate_operation(
            &format!(
                "+proj=topocentric +ellps=WGS84 +lon_0={:.17} +lat_0={:.17} +h_0={:.17}",
                origin[0], origin[1], origin[2]
            ),
            false,
        )
        .unwrap();
    let geocentric = srs("EPSG:4978");
    let t = CoordTransform::new_with_options(&geocentric, &geocentric, &options).unwrap();
    let mut xs: Vec<f64> = ecef.iter().map(|p| p[0]).collect();
    let mut ys: Vec<f64> = ecef.iter().map(|p| p[1]).collect();
    let mut zs: Vec<f64> = ecef.iter().map(|p| p[2]).collect();
    t.transform_coords(&mut xs, &mut ys, &mut zs).unwrap();
    (0..ecef.len()).map(|k| [xs[k], ys[k], zs[k]]).collect()
}

#[test]
fn enu_agrees_with_proj_topocentric_within_a_millimetre() {
    // 500 origins (the hard ones among them), 20 points each: half within
    // 10 km of the origin (a mesh, a camera's neighbourhood), half anywhere.
    let mut rng = Lcg(0x656e_7521);
    let all = points();
    let mut origins: Vec<[f64; 3]> = all.iter().step_by(all.len() / 500).copied().take(500).collect();
    origins[..8].copy_from_slice(&[
        [0.0, 90.0, 0.0],
        [135.0, 90.0, 100.0],
        [0.0, -90.0, 0.0],
        [-60.0, -90.0, 2_000.0],
        [180.0, 0.0, 0.0],
        [-180.0, -17.0, 500.0],
        [180.0, 89.999_999, 0.0],
        [10.0, 45.0, 40_000_000.0],
    ]);
    let mut pairs = Vec::with_capacity(POINTS);
    for origin in &origins {
        let mut near = Vec::new();
        for k in 0..20 {
            let p = if k < 10 {
                // Up to 10 km away, across the pole or the antimeridian.
                let d = 0.09;
                let lat = (origin[1] + rng.range(-d, d)).clamp(-90.0, 90.0);
                let lon = origin[0] + rng.range(-d, d) / lat.to_radians().cos().max(0.01);
                [(lon + 540.0).rem_euclid(360.0) - 180.0, lat, origin[2] + rng.range(-500.0, 5_000.0)]
            } else {
                all[(rng.next_f64() * all.len() as f64) as usize]
            };
            near.push(p);
        }
        let ecef = proj_ecef(&near);
        for (p, q) in near.iter().zip(proj_enu(*origin, &ecef)) {
            pairs.push((*origin, *p, q));
        }
    }
    assert_eq!(pairs.len(), POINTS);
    let (max, at) = worst(
        "enu_from_geodetic",
        pairs.iter().map(|(o, p, q)| (distance(geodesy::enu_from_geodetic(*o, *p), *q), *p)),
    );
    assert!(max <= TOLERANCE_M, "ENU {max} m from PROJ's topocentric, point {at:?}");
    // The frame itself: up at the origin is PROJ's up, a unit vector.
    for o in &origins[..8] {
        let up = proj_enu(*o, &proj_ecef(&[[o[0], o[1], o[2] + 1000.0]]))[0];
        assert!(distance(up, [0.0, 0.0, 1000.0]) < TOLERANCE_M, "up at {o:?}: {up:?}");
    }
}
