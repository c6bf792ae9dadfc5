//! The same inputs and seed give the same instances whatever the order
//! tiles are asked in and whatever the level of the tile asked.

use relief_source::TileKey;

use super::{Input, Scene, block, list, num, open, point, projected, rule, sorted, spec, table};

/// Three classes in stripes, a hole of nodata classes, hilly ground, a
/// density gradient and a few points: every path of a tile.
fn scene() -> Scene {
    let classes = Input::Raster(Box::new(|x, y| {
        if (x - 21_000.0).hypot(y - 44_500.0) < 120.0 {
            f32::NAN
        } else {
            f32::from(((x / 300.0).floor() as i32).rem_euclid(3) as u8 + 1)
        }
    }));
    let ground = Input::Raster(Box::new(|x, y| (300.0 + 40.0 * (x / 170.0).sin() + 25.0 * (y / 230.0).cos()) as f32));
    let density = Input::Raster(Box::new(|x, _| ((x - 20_480.0) / 2048.0) as f32));
    let points = Input::Points(vec![
        point(1, 20_750.5, 44_800.25, &[]),
        point(2, 21_100.0, 44_100.0, &[("model", "house")]),
        point(3, 21_024.0, 44_544.0, &[("model", "shrub")]),
    ]);
    Scene::new(projected(), vec![classes, ground, density, points])
}

fn forest(seed: f64) -> super::super::Scatter {
    let rules = vec![
        rule(1, "conifer", 3000.0, &[("spacing", num(5.0)), ("scale", list(&[0.8, 1.2]))]),
        table(&[
            ("class", num(2.0)),
            ("models", table(&[("broadleaf", num(2.0)), ("shrub", num(1.0))])),
            ("density", num(1500.0)),
        ]),
    ];
    let spec =
        spec(&["landcover", "dem", "canopy", "trees"], rules, &[("seed", num(seed)), ("anchor_radius", num(3.0))]);
    open(&spec, &projected())
}

#[test]
fn tiles_asked_in_any_order_are_the_same() {
    let s = scene();
    let keys = block(6, 20, 20, 2, 2).into_iter().chain(block(7, 40, 40, 3, 3)).collect::<Vec<_>>();
    let first = forest(7.0);
    let forward: Vec<_> = keys.iter().map(|k| (k, s.tile(&first, *k))).collect();
    // A fresh source and a fresh store, asked in another order.
    let again = scene();
    let second = forest(7.0);
    let mut shuffled = keys.clone();
    shuffled.reverse();
    shuffled.rotate_left(5);
    for key in &shuffled {
        let tile = again.tile(&second, *key);
        let (_, expected) = forward.iter().find(|(k, _)| *k == key).unwrap();
        assert_eq!(&tile, expected, "tile {key}");
    }
    assert!(forward.iter().map(|(_, t)| t.instances.len()).sum::<usize>() > 1000);
    // Another seed, other instances.
    let other = forest(8.0);
    assert_ne!(s.tile(&other, keys[0]), forward[0].1);
}

#[test]
fn a_tile_holds_the_union_of_its_children_and_grandchildren() {
    let s = scene();
    let source = forest(7.0);
    // Level 6 is the scatter's level here; 5 and 3 are coarser, 7 and 8 finer.
    let parent = TileKey::new(6, 20, 21);
    let whole = sorted(s.tile(&source, parent).instances);
    assert!(whole.len() > 200, "{}", whole.len());
    let children = sorted(s.instances(&source, &block(7, 40, 42, 2, 2)));
    assert_eq!(children, whole);
    let grandchildren = sorted(s.instances(&source, &block(8, 80, 84, 4, 4)));
    assert_eq!(grandchildren, whole);
    // Coarser than the level: the union of the level's tiles.
    let coarse = sorted(s.tile(&source, TileKey::new(5, 10, 10)).instances);
    assert_eq!(coarse, sorted(s.instances(&source, &block(6, 20, 20, 2, 2))));
    // The points are there, once each; the third stands on a nodata class
    // and keeps its own model.
    let points: Vec<_> = coarse.iter().filter(|i| i.feature_id < 10).collect();
    assert_eq!(points.len(), 3, "{points:?}");
    assert_eq!(points[1].model, "house");
    assert_eq!(points[2].model, "shrub");
}

#[test]
fn tiles_coarser_than_three_levels_above_the_level_are_refused() {
    let s = scene();
    let source =
        open(&spec(&["landcover", "dem"], vec![rule(1, "conifer", 1.0, &[])], &[("level", num(9.0))]), &projected());
    assert!(s.try_tile(&source, TileKey::new(6, 2, 5)).is_ok());
    let err = s.try_tile(&source, TileKey::new(5, 1, 2)).unwrap_err().to_string();
    assert!(err.contains("tile 5/1/2 is coarser than level 6") && err.contains("too many instances"), "{err}");
}
