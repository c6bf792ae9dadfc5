//! The stock models: shape, size, orientation, and the file round trip.

use std::collections::HashMap;

use relief_models::{Model, STOCK, load, stock, stock_glb, write_stock};

/// (name, expected height in metres, expected radius in metres, most triangles).
const EXPECTED: &[(&str, f32, f32, usize)] =
    &[("conifer", 12.0, 2.5, 150), ("broadleaf", 10.0, 3.5, 150), ("shrub", 1.5, 1.2, 150), ("house", 6.0, 7.0, 24)];

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn triangles(model: &Model) -> impl Iterator<Item = [[f32; 3]; 3]> + '_ {
    model.indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| model.positions[t[k] as usize]))
}

/// Groups the triangles into pieces that touch (share a corner position):
/// flat shading gives every facet its own vertices, so vertex indices do
/// not connect facets but positions do.
fn pieces(model: &Model) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..model.triangle_count()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut first_at: HashMap<[u32; 3], usize> = HashMap::new();
    for (t, corners) in triangles(model).enumerate() {
        for p in corners {
            let key = p.map(f32::to_bits);
            let other = *first_at.entry(key).or_insert(t);
            let (a, b) = (root(&mut parent, t), root(&mut parent, other));
            parent[a] = b;
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for t in 0..parent.len() {
        let r = root(&mut parent, t);
        groups.entry(r).or_default().push(t);
    }
    groups.into_values().collect()
}

#[test]
fn every_stock_model_loads_with_sane_size_and_few_triangles() {
    for &(name, height, radius, most) in EXPECTED {
        let model = stock(name).unwrap();
        let n = model.triangle_count();
        assert!(n > 0 && n <= most, "{name}: {n} triangles");
        assert!((model.height() - height).abs() <= 0.15 * height, "{name}: height {}", model.height());
        assert!((model.radius() - radius).abs() <= 0.2 * radius, "{name}: radius {}", model.radius());
        assert_eq!(model.bounds.min[1], -1.0, "{name} reaches 1 m underground");
        assert_eq!(model.positions.len(), model.normals.len());
        assert_eq!(model.positions.len(), model.colors.len());
        assert!(model.indices.iter().all(|&i| (i as usize) < model.positions.len()));
    }
    assert_eq!(STOCK.len(), EXPECTED.len());
    assert!(stock("baobab").is_none());
    assert!(stock_glb("baobab").is_none());
}

#[test]
fn stock_normals_are_unit_and_agree_with_the_winding() {
    for name in STOCK {
        let model = stock(name).unwrap();
        for n in &model.normals {
            assert!((dot(*n, *n).sqrt() - 1.0).abs() < 1e-5, "{name}: normal {n:?}");
        }
        for (t, [a, b, c]) in model.indices.chunks_exact(3).zip(triangles(&model)) {
            let face = cross(sub(b, a), sub(c, a));
            for &i in t {
                assert!(dot(face, model.normals[i as usize]) > 0.0, "{name}: a facet is wound against its normal");
            }
        }
    }
}

#[test]
fn stock_facets_face_away_from_the_middle_of_their_piece() {
    for name in STOCK {
        let model = stock(name).unwrap();
        let groups = pieces(&model);
        assert!(groups.len() >= 2 || *name == "shrub", "{name}: {} pieces", groups.len());
        for group in groups {
            let corners: Vec<[f32; 3]> = group
                .iter()
                .flat_map(|&t| model.indices[3 * t..3 * t + 3].iter().map(|&i| model.positions[i as usize]))
                .collect();
            let centroid = corners
                .iter()
                .fold([0.0; 3], |s, p| [s[0] + p[0], s[1] + p[1], s[2] + p[2]])
                .map(|v| v / corners.len() as f32);
            let outward = group
                .iter()
                .filter(|&&t| {
                    let [a, b, c] = [0, 1, 2].map(|k| model.positions[model.indices[3 * t + k] as usize]);
                    let middle = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
                    dot(cross(sub(b, a), sub(c, a)), sub(middle, centroid)) > 0.0
                })
                .count();
            assert!(outward * 10 >= group.len() * 9, "{name}: {outward} of {} facets face outward", group.len());
        }
    }
}

#[test]
fn stock_colours_are_opaque_and_srgb() {
    let house = stock("house").unwrap();
    let roof = house.colors[house.indices[house.indices.len() - 1] as usize];
    assert!((roof[0] - 0.55).abs() < 1e-3 && (roof[1] - 0.23).abs() < 1e-3, "roof {roof:?}");
    for name in STOCK {
        assert!(stock(name).unwrap().colors.iter().all(|c| c[3] == 1.0));
    }
}

#[test]
fn written_stock_files_load_back_equal() {
    let dir = tempfile::tempdir().unwrap();
    let paths = write_stock(&dir.path().join("models")).unwrap();
    assert_eq!(paths.len(), STOCK.len());
    for (path, name) in paths.iter().zip(STOCK) {
        assert_eq!(path.file_name().unwrap().to_str().unwrap(), format!("{name}.glb"));
        assert_eq!(std::fs::read(path).unwrap(), stock_glb(name).unwrap());
        assert_eq!(load(path).unwrap(), stock(name).unwrap());
    }
    // Writing again leaves identical files as they are and still lists them.
    assert_eq!(write_stock(&dir.path().join("models")).unwrap(), paths);
}

#[test]
fn stock_glb_is_deterministic_and_aligned() {
    for name in STOCK {
        let bytes = stock_glb(name).unwrap();
        assert_eq!(bytes, stock_glb(name).unwrap());
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(bytes.len() % 4, 0);
        assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, bytes.len());
        let json_length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(json_length % 4, 0);
        // The gltf crate reads it too, with its own validation.
        gltf::Gltf::from_slice(&bytes).unwrap();
    }
}
