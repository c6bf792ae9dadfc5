//! What a scatter reports and how it follows changes: class counts, the
//! inputs' roles, dirt, model files.

use std::path::PathBuf;

use relief_source::{ClassCount, DirtySet, Extent, PayloadKind, Refresh, Source, TileKey};

use super::super::{Scatter, scatter_input_kinds};
use super::{Input, Scene, block, flat, num, open, projected, rule, spec, text};

#[test]
fn counts_per_class_match_the_tiles_and_list_classes_without_a_rule() {
    // Class 1 west, class 2 in the middle, class 7 (no rule) east.
    let classes = Input::Raster(Box::new(|x, _| {
        if x < 20_800.0 {
            1.0
        } else if x < 21_700.0 {
            2.0
        } else {
            7.0
        }
    }));
    let s = Scene::new(projected(), vec![classes, flat()]);
    let rules = vec![rule(1, "conifer", 2000.0, &[]), rule(2, "broadleaf", 800.0, &[]), rule(3, "shrub", 100.0, &[])];
    let source = open(&spec(&["landcover", "dem"], rules, &[]), &projected());
    let keys = block(6, 20, 20, 2, 2);
    let instances = s.instances(&source, &keys);
    let classes = source.info().classes;
    let count = |model: &str| instances.iter().filter(|i| i.model == model).count() as u64;
    let of = |class: i64| *classes.iter().find(|c| c.class == class).unwrap_or_else(|| panic!("{classes:?}"));
    assert_eq!(of(1).instances, count("conifer"));
    assert_eq!(of(2).instances, count("broadleaf"));
    assert!(of(1).has_rule && of(2).has_rule);
    // A rule whose class is not in the raster, and a class without a rule.
    assert_eq!(of(3), ClassCount { class: 3, has_rule: true, instances: 0, samples: 0 });
    assert!(!of(7).has_rule && of(7).instances == 0 && of(7).samples > 0);
    // Every sample the four tiles own, once.
    assert_eq!(classes.iter().map(|c| c.samples).sum::<u64>(), 4 * 64 * 64);
    // Built again, or as the coarser tile over them: the same counts.
    let _ = s.instances(&source, &keys);
    assert_eq!(source.info().classes, classes);
    s.tile(&source, TileKey::new(5, 10, 10));
    assert_eq!(source.info().classes, classes);
    // Finer tiles do not count (they see part of a tile of the level).
    s.tile(&source, TileKey::new(7, 50, 40));
    assert_eq!(source.info().classes, classes);
    let details = source.info().details;
    assert_eq!(details["level"], "6 (default: the first level whose tile is at most 2 km across)");
    assert!(details["counts"].contains("the 4 tiles"), "{}", details["counts"]);
    assert!(details["rules"].starts_with("1: conifer 100%; 2000/km², spacing 0 m, scale 1..1"), "{}", details["rules"]);
}

#[test]
fn extra_inputs_are_density_then_points_unless_named() {
    let kinds = |inputs: &[&str], options: &[(&str, relief_source::OptionValue)]| {
        scatter_input_kinds(&spec(inputs, vec![rule(1, "conifer", 1.0, &[])], options))
    };
    use PayloadKind::{Features, Height};
    assert_eq!(kinds(&["c", "g"], &[]), [Height, Height]);
    assert_eq!(kinds(&["c", "g", "d"], &[]), [Height, Height, Height]);
    assert_eq!(kinds(&["c", "g", "d", "p"], &[]), [Height, Height, Height, Features]);
    assert_eq!(kinds(&["c", "g", "p"], &[("points_input", text("p"))]), [Height, Height, Features]);
    assert_eq!(kinds(&["c", "g", "p", "d"], &[("points_input", text("p"))]), [Height, Height, Features, Height]);
    assert_eq!(kinds(&["c", "g", "p", "d"], &[("density_input", text("d"))]), [Height, Height, Features, Height]);
    let err = |inputs: &[&str], options: &[(&str, relief_source::OptionValue)]| {
        Scatter::open(&spec(inputs, vec![rule(1, "conifer", 1.0, &[])], options), &projected()).unwrap_err().to_string()
    };
    let e = err(&["c", "g", "p"], &[("points_input", text("g"))]);
    assert!(e.contains("'points_input'") && e.contains("'g' is not one of the inputs after"), "{e}");
    let e = err(&["c", "g", "p"], &[("points_input", text("p")), ("density_input", text("p"))]);
    assert!(e.contains("are one source"), "{e}");
    assert!(err(&["c"], &[]).contains("scatter takes inputs = [classes, ground]"));
    assert!(err(&["c", "g", "a", "b", "e"], &[]).contains("got 5"));
    assert!(err(&["c", "g"], &[("seed", num(1.5))]).contains("'seed'"));
    assert!(err(&["c", "g"], &[("level", num(25.0))]).contains("'level'"));
    assert!(err(&["c", "g"], &[("anchor_radius", num(-1.0))]).contains("'anchor_radius'"));
    assert!(err(&["c", "g"], &[("colour", num(1.0))]).contains("unknown option"));
    let none = Scatter::open(&spec(&["c", "g"], vec![], &[]), &projected()).unwrap_err().to_string();
    assert!(none.contains("at least one [[source.rule]]"), "{none}");
}

#[test]
fn dirt_on_an_input_reaches_only_the_tiles_round_it() {
    let s = Scene::new(projected(), vec![super::uniform(1.0), flat()]);
    let source = open(&spec(&["landcover", "dem"], vec![rule(1, "conifer", 10.0, &[])], &[]), &projected());
    let grid = projected();
    let key = TileKey::new(6, 20, 20);
    let e = grid.tile_extent(key);
    let middle =
        DirtySet::from_extents([Extent::new(e.min_x + 500.0, e.min_y + 500.0, e.min_x + 510.0, e.min_y + 510.0)]);
    // Before any tile, a projected grid's extent is unknown: everything.
    assert!(source.dirty_from_input(0, &middle).is_everything());
    s.tile(&source, key);
    let dirt = source.dirty_from_input(0, &middle);
    assert!(dirt.touches_tile(&grid, key));
    assert!(!dirt.touches_tile(&grid, TileKey::new(6, 21, 20)));
    assert!(!dirt.touches_tile(&grid, TileKey::new(8, 80, 80)), "a finer tile away from the dirt");
    // Dirt a sample from an edge reaches the tile across it.
    let edge = DirtySet::from_extents([Extent::new(e.max_x - 20.0, e.min_y + 500.0, e.max_x - 19.0, e.min_y + 501.0)]);
    assert!(source.dirty_from_input(1, &edge).touches_tile(&grid, TileKey::new(6, 21, 20)));
    assert!(source.dirty_from_input(1, &DirtySet::none()).is_none());
}

/// A scratch folder, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("relief-scatter-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn model_files_are_named_by_stem_watched_and_refreshed() {
    let dir = Scratch::new("models");
    let oak = dir.0.join("oak.glb");
    let glb = |name: &str| relief_models::stock_glb(name).unwrap();
    std::fs::write(&oak, glb("broadleaf")).unwrap();
    let mut declared = spec(&["c", "g"], vec![rule(1, "oak", 100.0, &[])], &[]);
    declared.paths = vec![oak.clone()];
    let source = open(&declared, &projected());
    assert_eq!(source.info().files, vec![oak.clone()]);
    assert!(source.info().details["models"].ends_with(&format!("files: oak ({})", oak.display())));
    assert!(matches!(source.refresh(&projected()).unwrap(), Refresh::Unchanged));
    std::fs::write(&oak, glb("conifer")).unwrap();
    let Refresh::Changed { source: next, dirty } = source.refresh(&projected()).unwrap() else { panic!("unchanged") };
    assert!(dirty.is_everything());
    assert!(matches!(next.refresh(&projected()).unwrap(), Refresh::Unchanged));
    std::fs::remove_file(&oak).unwrap();
    let gone = next.refresh(&projected()).unwrap_err().to_string();
    assert!(gone.contains("model of source 'forest'") && gone.ends_with(&oak.display().to_string()), "{gone}");
    // At open: a missing file, a model no rule may name, two files of one stem.
    let missing = Scatter::open(&declared, &projected()).unwrap_err().to_string();
    assert!(missing.contains("cannot read model of source 'forest'") && missing.contains("oak.glb"), "{missing}");
    // A corrupt model: refused at open and on refresh, naming the file.
    std::fs::write(&oak, b"glTF not really").unwrap();
    let corrupt = Scatter::open(&declared, &projected()).unwrap_err().to_string();
    assert!(
        corrupt.contains("model of source 'forest' is unusable") && corrupt.contains("not a glTF 2.0 file"),
        "{corrupt}"
    );
    assert!(corrupt.ends_with(&oak.display().to_string()), "{corrupt}");
    assert!(next.refresh(&projected()).unwrap_err().to_string().contains("not a glTF 2.0 file"));
    std::fs::write(&oak, glb("broadleaf")).unwrap();
    let mut pine = spec(&["c", "g"], vec![rule(1, "pine", 100.0, &[])], &[]);
    pine.paths = vec![oak.clone()];
    let unknown = Scatter::open(&pine, &projected()).unwrap_err().to_string();
    assert!(
        unknown.contains("rule[0].models.pine") && unknown.contains("known: broadleaf, conifer, house, oak, shrub")
    );
    std::fs::create_dir_all(dir.0.join("b")).unwrap();
    std::fs::write(dir.0.join("b/oak.gltf"), glb("shrub")).unwrap();
    declared.paths.push(dir.0.join("b/oak.gltf"));
    let twice = Scatter::open(&declared, &projected()).unwrap_err().to_string();
    assert!(twice.contains("are both model 'oak'"), "{twice}");
}
