use super::*;

/// The 3D area of a triangulation, and its triangles' summed normal.
fn measure(t: &Triangulated) -> (f64, V3) {
    let mut area = 0.0;
    let mut normal = [0.0; 3];
    for tri in &t.triangles {
        let [a, b, c] = tri.map(|i| t.points[i as usize]);
        let n = cross(sub(b, a), sub(c, a));
        area += norm(n) / 2.0;
        normal = [normal[0] + n[0], normal[1] + n[1], normal[2] + n[2]];
    }
    (area, normal)
}

fn closed(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut ring = points.to_vec();
    ring.push(points[0]);
    ring
}

#[test]
fn a_level_square_gives_two_triangles_facing_its_winding() {
    let ring = closed(&[[0.0, 0.0, 5.0], [4.0, 0.0, 5.0], [4.0, 4.0, 5.0], [0.0, 4.0, 5.0]]);
    let t = triangulate(std::slice::from_ref(&ring), false).unwrap();
    assert_eq!(t.triangles.len(), 2);
    let (area, n) = measure(&t);
    assert!((area - 16.0).abs() < 1e-12);
    assert!(n[2] > 0.0, "counter-clockwise from above faces up");
    let mut reversed = ring;
    reversed.reverse();
    let (_, n) = measure(&triangulate(&[reversed], false).unwrap());
    assert!(n[2] < 0.0, "clockwise faces down");
}

#[test]
fn a_wall_with_a_window_keeps_its_area_on_its_plane() {
    // A wall 10 m long, 6 m high, along a diagonal, with a 2 x 2 m window.
    let (dx, dy) = (std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2);
    let at = |s: f64, z: f64| [100.0 + s * dx, 200.0 + s * dy, 300.0 + z];
    let wall = closed(&[at(0.0, 0.0), at(10.0, 0.0), at(10.0, 6.0), at(0.0, 6.0)]);
    let window = closed(&[at(4.0, 2.0), at(4.0, 4.0), at(6.0, 4.0), at(6.0, 2.0)]);
    let t = triangulate(&[wall, window], false).unwrap();
    let (area, n) = measure(&t);
    assert!((area - (60.0 - 4.0)).abs() < 1e-9, "{area}");
    // Every triangle on the wall's plane, facing one way.
    let plane = [dy, -dx, 0.0];
    for tri in &t.triangles {
        let [a, b, c] = tri.map(|i| t.points[i as usize]);
        for p in [a, b, c] {
            assert!(dot(sub(p, at(0.0, 0.0)), plane).abs() < 1e-9);
        }
        assert!(dot(cross(sub(b, a), sub(c, a)), n) > 0.0);
    }
}

#[test]
fn a_wall_in_degrees_keeps_its_shape_in_metres() {
    // 10 m along the parallel at 60 N, 3 m high: in degrees the wall is
    // 1.8e-4 wide and 3 high; triangulated in metres it stays a rectangle.
    let lon_per_m = 1.0 / (MEAN_RADIUS_M.to_radians() * 60f64.to_radians().cos());
    let wall = closed(&[
        [7.0, 60.0, 0.0],
        [7.0 + 10.0 * lon_per_m, 60.0, 0.0],
        [7.0 + 10.0 * lon_per_m, 60.0, 3.0],
        [7.0, 60.0, 3.0],
    ]);
    let t = triangulate(&[wall], true).unwrap();
    assert_eq!(t.triangles.len(), 2);
    // Its two triangles split the rectangle: each has half the area.
    let metres = |p: [f64; 3]| [(p[0] - 7.0) / lon_per_m, 0.0, p[2]];
    for tri in &t.triangles {
        let [a, b, c] = tri.map(|i| metres(t.points[i as usize]));
        assert!((norm(cross(sub(b, a), sub(c, a))) / 2.0 - 15.0).abs() < 1e-6);
    }
}

#[test]
fn a_patch_across_the_antimeridian_stays_whole() {
    let roof =
        closed(&[[179.9999, 0.0, 10.0], [-179.9999, 0.0, 10.0], [-179.9999, 0.0001, 10.0], [179.9999, 0.0001, 10.0]]);
    let t = triangulate(std::slice::from_ref(&roof), true).unwrap();
    assert_eq!(t.triangles.len(), 2);
    let feature = Feature { id: 1, geometry: Geometry::Polygons(vec![vec![roof]]), properties: BTreeMap::new() };
    let (x, _) = anchor(&feature, true).unwrap();
    assert!((x.abs() - 180.0).abs() < 1e-3, "{x}");
}

#[test]
fn degenerate_patches_say_why() {
    let two = closed(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
    assert_eq!(triangulate(&[two], false), Err("a patch with fewer than three distinct points"));
    let line = closed(&[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]);
    assert_eq!(triangulate(&[line], false), Err("a patch without area (its points are collinear)"));
    let nan = closed(&[[0.0, 0.0, 0.0], [f64::NAN, 1.0, 1.0], [2.0, 0.0, 2.0]]);
    assert_eq!(triangulate(&[nan], false), Err("a patch with a coordinate that is not a number"));
    assert_eq!(triangulate(&[], false), Err("an empty patch"));
    // A hole without area cuts nothing.
    let square = closed(&[[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [4.0, 4.0, 0.0], [0.0, 4.0, 0.0]]);
    let flat_hole = closed(&[[1.0, 1.0, 0.0], [2.0, 2.0, 0.0], [3.0, 3.0, 0.0]]);
    let (area, _) = measure(&triangulate(&[square, flat_hole], false).unwrap());
    assert!((area - 16.0).abs() < 1e-12);
}

#[test]
fn meshes_keep_heights_or_mark_them_relative_and_count_what_they_skip() {
    let roof = closed(&[[0.0, 0.0, 12.0], [4.0, 0.0, 12.0], [4.0, 4.0, 12.0], [0.0, 4.0, 12.0]]);
    let flat = closed(&[[0.0, 0.0, f64::NAN], [4.0, 0.0, f64::NAN], [4.0, 4.0, f64::NAN]]);
    let sliver = closed(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
    let features = [
        Feature { id: 7, geometry: Geometry::Polygons(vec![vec![roof], vec![sliver]]), properties: BTreeMap::new() },
        Feature { id: 8, geometry: Geometry::Polygons(vec![vec![flat]]), properties: BTreeMap::new() },
    ];
    let mut style = PatchStyle { z: ZPolicy::Absolute, color: DEFAULT_COLOR, color_by: None, min_level: 0 };
    let mesh_abs = mesh(features.iter(), false, &style);
    assert_eq!(mesh_abs.parts.len(), 1);
    assert!(!mesh_abs.parts[0].on_ground);
    assert!(mesh_abs.positions.iter().all(|p| p[2] == 12.0));
    let reasons: Vec<(u64, &str)> = mesh_abs.skipped.iter().map(|s| (s.feature_id, s.reason.as_str())).collect();
    assert_eq!(
        reasons,
        vec![
            (7, "a patch with fewer than three distinct points"),
            (8, "a patch without heights (z), drawn at absolute heights")
        ]
    );
    style.z = ZPolicy::Relative;
    let mesh_rel = mesh(features.iter(), false, &style);
    assert_eq!(mesh_rel.parts.len(), 2);
    assert!(mesh_rel.parts.iter().all(|p| p.on_ground));
    assert!(mesh_rel.positions.iter().all(|p| p[2].is_finite()));

    let counts = PatchCounts::of(features.iter(), false);
    assert_eq!((counts.patches, counts.triangles), (3, 3));
    assert_eq!(counts.skipped.get("a patch with fewer than three distinct points"), Some(&1));
    let (mut details, mut warnings) = (BTreeMap::new(), Vec::new());
    counts.report(&mut details, &mut warnings);
    assert_eq!(details.get("skipped_patches").map(String::as_str), Some("1"));
    assert!(warnings[0].starts_with("1 of 3 MultiPatch patches were degenerate"), "{warnings:?}");
}

#[test]
fn the_style_refuses_what_it_cannot_honour() {
    use crate::OptionValue;
    let spec = |k: &str, v: OptionValue| SourceSpec {
        id: "b".into(),
        kind: "shapefile".into(),
        options: [(k.to_owned(), v)].into(),
        ..SourceSpec::default()
    };
    let err = PatchStyle::from_spec(&spec("z", OptionValue::Text("floating".into()))).unwrap_err().to_string();
    assert!(err.contains("'floating' is not 'absolute' or 'relative'"), "{err}");
    let err = PatchStyle::refuse_on_features(&spec("z", OptionValue::Text("relative".into())), "polygons")
        .unwrap_err()
        .to_string();
    assert!(err.contains("option 'z'") && err.contains("MultiPatch"), "{err}");
    assert!(PatchStyle::from_spec(&spec("min_level", OptionValue::Number(2.5))).is_err());
    let style = PatchStyle::from_spec(&spec("z", OptionValue::Text("relative".into()))).unwrap();
    assert_eq!(style.z, ZPolicy::Relative);
}
