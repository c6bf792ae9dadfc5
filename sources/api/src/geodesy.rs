//! WGS84 geodesy in f64: the CPU side of the precision contract. The GPU
//! only ever sees f32 offsets from a nearby f64 origin computed here.

/// WGS84 semi-major axis, metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS84 semi-minor axis, metres.
pub const WGS84_B: f64 = WGS84_A * (1.0 - WGS84_F);
/// First eccentricity squared.
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);
/// Mean Earth radius (IUGG), metres, for great-circle distances.
pub const MEAN_RADIUS_M: f64 = 6_371_008.8;

/// Earth-centred, Earth-fixed coordinates from longitude, latitude (degrees)
/// and height above the ellipsoid (metres).
pub fn ecef_from_geodetic(lon_deg: f64, lat_deg: f64, height_m: f64) -> [f64; 3] {
    let (lon, lat) = (lon_deg.to_radians(), lat_deg.to_radians());
    let (sin_lat, cos_lat) = lat.sin_cos();
    let n = WGS84_A / (1.0 - WGS84_E2 * sin_lat * sin_lat).sqrt();
    [
        (n + height_m) * cos_lat * lon.cos(),
        (n + height_m) * cos_lat * lon.sin(),
        (n * (1.0 - WGS84_E2) + height_m) * sin_lat,
    ]
}

/// Longitude, latitude (degrees) and ellipsoidal height (metres) from ECEF.
/// Bowring's start and Newton steps: sub-millimetre everywhere from the
/// centre of the planet to far beyond geostationary orbit, poles included.
pub fn geodetic_from_ecef(p: [f64; 3]) -> (f64, f64, f64) {
    let [x, y, z] = p;
    let lon = y.atan2(x);
    let r = x.hypot(y);
    if r < 1e-9 {
        // On the polar axis.
        let lat = if z >= 0.0 { 90.0 } else { -90.0 };
        return (lon.to_degrees(), lat, z.abs() - WGS84_B);
    }
    let ep2 = WGS84_E2 / (1.0 - WGS84_E2);
    let theta = (z * WGS84_A).atan2(r * WGS84_B);
    let (st, ct) = theta.sin_cos();
    let mut lat = (z + ep2 * WGS84_B * st * st * st).atan2(r - WGS84_E2 * WGS84_A * ct * ct * ct);
    let mut h = 0.0;
    for _ in 0..3 {
        let (sin_lat, cos_lat) = lat.sin_cos();
        let n = WGS84_A / (1.0 - WGS84_E2 * sin_lat * sin_lat).sqrt();
        h = if cos_lat.abs() > 1e-3 { r / cos_lat - n } else { z / sin_lat - n * (1.0 - WGS84_E2) };
        lat = (z / r / (1.0 - WGS84_E2 * n / (n + h))).atan();
    }
    (lon.to_degrees(), lat.to_degrees(), h)
}

/// The east, north and up unit vectors of the local tangent frame at a
/// geodetic position (ECEF components).
pub fn enu_axes(lon_deg: f64, lat_deg: f64) -> [[f64; 3]; 3] {
    let (sin_lon, cos_lon) = lon_deg.to_radians().sin_cos();
    let (sin_lat, cos_lat) = lat_deg.to_radians().sin_cos();
    [
        [-sin_lon, cos_lon, 0.0],
        [-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat],
        [cos_lat * cos_lon, cos_lat * sin_lon, sin_lat],
    ]
}

/// A geodetic position as metres east, north and up of `origin` (lon, lat,
/// height), exact through ECEF: for meshes and cameras near the origin.
pub fn enu_from_geodetic(origin: [f64; 3], point: [f64; 3]) -> [f64; 3] {
    let o = ecef_from_geodetic(origin[0], origin[1], origin[2]);
    let p = ecef_from_geodetic(point[0], point[1], point[2]);
    let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
    enu_axes(origin[0], origin[1]).map(|axis| axis[0] * d[0] + axis[1] * d[1] + axis[2] * d[2])
}

/// Great-circle distance on the mean sphere (haversine), metres. Stable for
/// tiny distances and across the antimeridian.
pub fn haversine_m(lon1_deg: f64, lat1_deg: f64, lon2_deg: f64, lat2_deg: f64) -> f64 {
    let (p1, p2) = (lat1_deg.to_radians(), lat2_deg.to_radians());
    let dp = p2 - p1;
    let dl = (lon2_deg - lon1_deg).to_radians();
    let a = (dp / 2.0).sin().powi(2) + p1.cos() * p2.cos() * (dl / 2.0).sin().powi(2);
    2.0 * MEAN_RADIUS_M * a.sqrt().min(1.0).asin()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn enu_axes_point_east_north_up() {
        // At (0, 0): east is +Y, north +Z, up +X in ECEF.
        let [e, n, u] = enu_axes(0.0, 0.0);
        assert_eq!(e, [-0.0, 1.0, 0.0]);
        assert!((n[2] - 1.0).abs() < 1e-15 && (u[0] - 1.0).abs() < 1e-15);
        // 100 m up is 100 m up; a point 0.001 deg north is ~110.6 m north.
        let up = enu_from_geodetic([10.0, 45.0, 0.0], [10.0, 45.0, 100.0]);
        assert!((up[2] - 100.0).abs() < 1e-6 && up[0].abs() < 1e-6 && up[1].abs() < 1e-6);
        let north = enu_from_geodetic([10.0, 45.0, 0.0], [10.0, 45.001, 0.0]);
        assert!((north[1] - 111.13).abs() < 0.05, "{north:?}");
    }

    #[test]
    fn known_points() {
        let [x, y, z] = ecef_from_geodetic(0.0, 0.0, 0.0);
        assert!((x - WGS84_A).abs() < 1e-9 && y.abs() < 1e-9 && z.abs() < 1e-9);
        let [x, y, z] = ecef_from_geodetic(0.0, 90.0, 0.0);
        assert!(x.abs() < 1e-6 && y.abs() < 1e-9 && (z - WGS84_B).abs() < 1e-6);
        // Reference from PROJ (cs2cs EPSG:4979 -> EPSG:4978): 7E 43N 1000 m.
        let [x, y, z] = ecef_from_geodetic(7.0, 43.0, 1000.0);
        assert!((x - 4_637_855.180_7).abs() < 1e-3, "{x}");
        assert!((y - 569_457.011_9).abs() < 1e-3, "{y}");
        assert!((z - 4_328_183.757_6).abs() < 1e-3, "{z}");
    }

    #[test]
    fn haversine_is_stable_across_the_antimeridian() {
        let d = haversine_m(179.9999, 0.0, -179.9999, 0.0);
        assert!((d - 0.0002f64.to_radians() * MEAN_RADIUS_M).abs() < 1e-6);
        assert!(haversine_m(10.0, 10.0, 10.0, 10.0) == 0.0);
    }

    proptest! {
        #[test]
        fn ecef_round_trip(lon in -180.0f64..180.0, lat in -90.0f64..=90.0, h in -11_000.0f64..40_000_000.0) {
            let (lon2, lat2, h2) = geodetic_from_ecef(ecef_from_geodetic(lon, lat, h));
            prop_assert!((h2 - h).abs() < 1e-3, "h {h} -> {h2}");
            prop_assert!((lat2 - lat).abs() < 1e-9, "lat {lat} -> {lat2}");
            if lat.abs() < 89.999_999 {
                let dl = (lon2 - lon + 540.0).rem_euclid(360.0) - 180.0;
                prop_assert!(dl.abs() < 1e-9, "lon {lon} -> {lon2}");
            }
        }
    }
}
