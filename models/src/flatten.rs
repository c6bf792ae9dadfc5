//! Flattening a glTF scene into one [`Model`]: walk the node tree, apply
//! each node's transform to its mesh, and gather the triangles.

use gltf::mesh::Mode;
use gltf::{Accessor, Document, Mesh, Node, Primitive, Semantic};

use crate::accessor::{Buffers, read_floats, read_indices};
use crate::color::{clamp_unit, srgb_from_linear};
use crate::math::{add, cross, sub, unit};
use crate::{Bounds, MAX_TRIANGLES, MAX_VERTICES, Model, ModelError};

/// A column-major 4x4 matrix, as glTF stores them (`m[column][row]`).
type Mat4 = [[f32; 4]; 4];

const IDENTITY: Mat4 = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// One mesh placed in the scene by a node.
pub(crate) struct Instance<'a> {
    mesh: Mesh<'a>,
    world_from_mesh: Mat4,
}

/// The meshes the default scene (or scene 0) draws, each with its node's
/// world transform. A file without scenes draws the nodes no node has as a
/// child. The sizes and modes are checked before any buffer is read.
pub(crate) fn instances<'a>(path: &str, doc: &'a Document) -> Result<Vec<Instance<'a>>, ModelError> {
    let roots: Vec<Node<'a>> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for child in doc.nodes().flat_map(|n| n.children()) {
                is_child[child.index()] = true;
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    let mut seen = vec![false; doc.nodes().len()];
    let mut stack: Vec<(Node<'a>, Mat4)> = roots.into_iter().rev().map(|n| (n, IDENTITY)).collect();
    let mut instances = Vec::new();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(ModelError::invalid(
                path,
                format!("node {} is reached twice in the scene: glTF nodes must form a tree", node.index()),
            ));
        }
        let world = mul(&parent, &node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            instances.push(Instance { mesh, world_from_mesh: world });
        }
        let children: Vec<Node<'a>> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, world)));
    }
    check_sizes(path, &instances)?;
    Ok(instances)
}

/// Refuses points and lines, and models over the vertex or triangle limit
/// or with no triangle at all, from the accessors' counts alone.
fn check_sizes(path: &str, instances: &[Instance<'_>]) -> Result<(), ModelError> {
    let (mut vertices, mut triangles) = (0usize, 0usize);
    for instance in instances {
        for primitive in instance.mesh.primitives() {
            let mode = primitive.mode();
            if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                return Err(ModelError::NotTriangles {
                    path: path.to_owned(),
                    mesh: mesh_label(&instance.mesh),
                    primitive: primitive.index(),
                    mode: mode_name(mode),
                });
            }
            let count = positions(path, &instance.mesh, &primitive)?.count();
            let corners = primitive.indices().map_or(count, |i| i.count());
            vertices = vertices.saturating_add(count);
            triangles = triangles.saturating_add(match mode {
                Mode::Triangles => corners / 3,
                _ => corners.saturating_sub(2),
            });
        }
    }
    if vertices > MAX_VERTICES {
        return Err(ModelError::TooManyVertices { path: path.to_owned(), vertices });
    }
    if triangles > MAX_TRIANGLES {
        return Err(ModelError::TooManyTriangles { path: path.to_owned(), triangles });
    }
    if triangles == 0 {
        return Err(ModelError::NoTriangles { path: path.to_owned() });
    }
    Ok(())
}

/// The indices of the buffers the instances read, ascending: those that
/// hold positions, normals, vertex colours or indices (texture coordinates
/// and the like are never read, so their buffers need not exist).
pub(crate) fn used_buffers(instances: &[Instance<'_>]) -> Vec<usize> {
    let mut used = Vec::new();
    for primitive in instances.iter().flat_map(|i| i.mesh.primitives()) {
        let attributes = [Semantic::Positions, Semantic::Normals, Semantic::Colors(0)].map(|s| primitive.get(&s));
        for accessor in attributes.into_iter().chain([primitive.indices()]).flatten() {
            used.extend(accessor.view().map(|v| v.buffer().index()));
            if let Some(sparse) = accessor.sparse() {
                used.push(sparse.indices().view().buffer().index());
                used.push(sparse.values().view().buffer().index());
            }
        }
    }
    used.sort_unstable();
    used.dedup();
    used
}

/// The model the instances make, their primitives one after another.
pub(crate) fn build(path: &str, instances: &[Instance<'_>], buffers: &Buffers<'_>) -> Result<Model, ModelError> {
    let mut model = Model {
        positions: Vec::new(),
        normals: Vec::new(),
        colors: Vec::new(),
        indices: Vec::new(),
        bounds: Bounds::of(&[]),
    };
    for instance in instances {
        for primitive in instance.mesh.primitives() {
            let context = format!("{} primitive {}", mesh_label(&instance.mesh), primitive.index());
            append(&mut model, instance, &primitive, buffers)
                .map_err(|message| ModelError::invalid(path, format!("{context}: {message}")))?;
        }
    }
    model.bounds = Bounds::of(&model.positions);
    Ok(model)
}

/// Appends one primitive, transformed, to the model.
fn append(
    model: &mut Model,
    instance: &Instance<'_>,
    primitive: &Primitive<'_>,
    buffers: &Buffers<'_>,
) -> Result<(), String> {
    let m = &instance.world_from_mesh;
    let position_accessor = primitive.get(&Semantic::Positions).ok_or("it has no POSITION attribute")?;
    let count = position_accessor.count();
    let attribute = |name: &str, accessor: &Accessor<'_>, widths: &[usize]| -> Result<Vec<f32>, String> {
        let width = accessor.dimensions().multiplicity();
        if !widths.contains(&width) {
            let allowed: Vec<String> = widths.iter().map(ToString::to_string).collect();
            return Err(format!("its {name} has {width} components, not {}", allowed.join(" or ")));
        }
        if accessor.count() != count {
            return Err(format!("its {name} has {} elements for {count} vertices", accessor.count()));
        }
        read_floats(accessor, buffers).map_err(|e| format!("{name}: {e}"))
    };

    let mut positions: Vec<[f32; 3]> = Vec::with_capacity(count);
    for (i, p) in attribute("POSITION", &position_accessor, &[3])?.chunks_exact(3).enumerate() {
        let world = transform_point(m, [p[0], p[1], p[2]]);
        if !world.iter().all(|v| v.is_finite()) {
            return Err(format!("vertex {i} has a position that is not a finite number"));
        }
        positions.push(world);
    }

    let corners = match primitive.indices() {
        Some(accessor) => read_indices(&accessor, buffers).map_err(|e| format!("indices: {e}"))?,
        None => (0..count as u32).collect(),
    };
    if let Some(bad) = corners.iter().find(|&&i| i as usize >= count) {
        return Err(format!("it has index {bad} but only {count} vertices"));
    }
    let mut triangles = triangle_list(primitive.mode(), &corners);
    if determinant(m) < 0.0 {
        // A mirroring transform turns counter-clockwise into clockwise.
        for t in triangles.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
    }

    let face_normals = vertex_normals_from_faces(&positions, &triangles);
    let normals: Vec<[f32; 3]> = match primitive.get(&Semantic::Normals) {
        Some(accessor) => {
            let normal_m = normal_matrix(m);
            attribute("NORMAL", &accessor, &[3])?
                .chunks_exact(3)
                .zip(&face_normals)
                .map(|(n, fallback)| unit(mul3(&normal_m, [n[0], n[1], n[2]])).unwrap_or(*fallback))
                .collect()
        }
        None => face_normals,
    };

    let base = primitive.material().pbr_metallic_roughness().base_color_factor();
    let vertex_colors = match primitive.get(&Semantic::Colors(0)) {
        Some(accessor) => {
            let width = accessor.dimensions().multiplicity();
            let values = attribute("COLOR_0", &accessor, &[3, 4])?;
            values.chunks_exact(width).map(|c| [c[0], c[1], c[2], c.get(3).copied().unwrap_or(1.0)]).collect()
        }
        None => vec![[1.0; 4]; count],
    };
    let colors = vertex_colors.into_iter().map(|c| {
        let linear = [base[0] * c[0], base[1] * c[1], base[2] * c[2], base[3] * c[3]];
        [srgb_from_linear(linear[0]), srgb_from_linear(linear[1]), srgb_from_linear(linear[2]), clamp_unit(linear[3])]
    });

    let first = u32::try_from(model.positions.len()).map_err(|_| "the model has too many vertices")?;
    model.positions.extend(positions);
    model.normals.extend(normals);
    model.colors.extend(colors);
    model.indices.extend(triangles.into_iter().map(|i| i + first));
    Ok(())
}

/// Corners of a triangle list from the corners of any triangle mode.
fn triangle_list(mode: Mode, corners: &[u32]) -> Vec<u32> {
    match mode {
        Mode::TriangleStrip => (0..corners.len().saturating_sub(2))
            .flat_map(|i| {
                if i % 2 == 0 {
                    [corners[i], corners[i + 1], corners[i + 2]]
                } else {
                    [corners[i], corners[i + 2], corners[i + 1]]
                }
            })
            .collect(),
        Mode::TriangleFan => {
            (1..corners.len().saturating_sub(1)).flat_map(|i| [corners[i], corners[i + 1], corners[0]]).collect()
        }
        // A trailing incomplete triangle is dropped.
        _ => corners[..corners.len() / 3 * 3].to_vec(),
    }
}

/// Unit vertex normals: each vertex gets the sum of the normals of the
/// faces that use it, weighted by their areas; straight up where that sum
/// is zero.
fn vertex_normals_from_faces(positions: &[[f32; 3]], triangles: &[u32]) -> Vec<[f32; 3]> {
    let mut sums = vec![[0.0f32; 3]; positions.len()];
    for t in triangles.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        // The cross product's length is twice the face's area.
        let n = cross(sub(b, a), sub(c, a));
        for &i in t {
            let s = &mut sums[i as usize];
            *s = add(*s, n);
        }
    }
    sums.into_iter().map(|s| unit(s).unwrap_or([0.0, 1.0, 0.0])).collect()
}

fn mesh_label(mesh: &Mesh<'_>) -> String {
    match mesh.name() {
        Some(name) if !name.is_empty() => format!("mesh '{name}'"),
        _ => format!("mesh {}", mesh.index()),
    }
}

fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "Points",
        Mode::Lines => "Lines",
        Mode::LineLoop => "LineLoop",
        Mode::LineStrip => "LineStrip",
        Mode::Triangles => "Triangles",
        Mode::TriangleStrip => "TriangleStrip",
        Mode::TriangleFan => "TriangleFan",
    }
}

/// The POSITION accessor of a primitive.
fn positions<'a>(path: &str, mesh: &Mesh<'a>, primitive: &Primitive<'a>) -> Result<Accessor<'a>, ModelError> {
    primitive.get(&Semantic::Positions).ok_or_else(|| {
        ModelError::invalid(
            path,
            format!("{} primitive {} has no POSITION attribute", mesh_label(mesh), primitive.index()),
        )
    })
}

fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut out = [[0.0; 4]; 4];
    for (col, out_col) in out.iter_mut().enumerate() {
        for (row, value) in out_col.iter_mut().enumerate() {
            *value = (0..4).map(|k| a[k][row] * b[col][k]).sum();
        }
    }
    out
}

fn transform_point(m: &Mat4, p: [f32; 3]) -> [f32; 3] {
    let row = |r: usize| m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2] + m[3][r];
    [row(0), row(1), row(2)]
}

/// The determinant of the upper-left 3x3 block.
fn determinant(m: &Mat4) -> f32 {
    let [a, b, c] = [m[0], m[1], m[2]].map(|col| [col[0], col[1], col[2]]);
    a[0] * (b[1] * c[2] - c[1] * b[2]) - b[0] * (a[1] * c[2] - c[1] * a[2]) + c[0] * (a[1] * b[2] - b[1] * a[2])
}

/// The matrix that carries normals: the inverse transpose of the upper-left
/// 3x3 block, up to a positive scale (normals are made unit afterwards).
/// The cofactor matrix is the inverse transpose times the determinant, so
/// it is used with the determinant's sign; it stays usable when the block
/// is singular (a model flattened by a zero scale).
fn normal_matrix(m: &Mat4) -> [[f32; 3]; 3] {
    let [a, b, c] = [m[0], m[1], m[2]].map(|col| [col[0], col[1], col[2]]);
    let sign = if determinant(m) < 0.0 { -1.0 } else { 1.0 };
    // Column j of the cofactor matrix is the cross product of the other two columns.
    [cross(b, c), cross(c, a), cross(a, b)].map(|col| col.map(|v| v * sign))
}

/// A 3x3 matrix, given by its columns, times a vector.
fn mul3(columns: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    let [a, b, c] = columns;
    [0, 1, 2].map(|r| a[r] * v[0] + b[r] * v[1] + c[r] * v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scale(x: f32, y: f32, z: f32) -> Mat4 {
        [[x, 0.0, 0.0, 0.0], [0.0, y, 0.0, 0.0], [0.0, 0.0, z, 0.0], [0.0, 0.0, 0.0, 1.0]]
    }

    #[test]
    fn normals_follow_the_inverse_transpose() {
        // Stretching z by 2 tilts a 45-degree normal towards x.
        let n = unit(mul3(&normal_matrix(&scale(1.0, 1.0, 2.0)), [1.0, 0.0, 1.0])).unwrap();
        let expected = unit([2.0, 0.0, 1.0]).unwrap();
        assert!(n.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-6), "{n:?}");
        // A mirror keeps an up normal up (the cofactor alone would turn it down).
        assert_eq!(mul3(&normal_matrix(&scale(-1.0, 1.0, 1.0)), [0.0, 1.0, 0.0]), [0.0, 1.0, 0.0]);
        assert!(determinant(&scale(-1.0, 1.0, 1.0)) < 0.0);
        // A quarter turn about y carries +x to -z.
        let turn = [[0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        assert_eq!(mul3(&normal_matrix(&turn), [1.0, 0.0, 0.0]), [0.0, 0.0, -1.0]);
        assert_eq!(transform_point(&mul(&turn, &scale(2.0, 2.0, 2.0)), [1.0, 0.0, 0.0]), [0.0, 0.0, -2.0]);
    }

    #[test]
    fn strips_and_fans_keep_one_winding() {
        assert_eq!(triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3, 4]), [0, 1, 2, 1, 3, 2, 2, 3, 4]);
        assert_eq!(triangle_list(Mode::TriangleFan, &[0, 1, 2, 3]), [1, 2, 0, 2, 3, 0]);
        assert_eq!(triangle_list(Mode::Triangles, &[0, 1, 2, 3]), [0, 1, 2]);
        assert!(triangle_list(Mode::TriangleStrip, &[0, 1]).is_empty());
    }

    #[test]
    fn computed_normals_weigh_faces_by_area() {
        // A big flat triangle and a small upright one share vertex 0.
        let positions = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 0.0, -4.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let normals = vertex_normals_from_faces(&positions, &[0, 1, 2, 0, 4, 3]);
        assert_eq!(normals[1], [0.0, 1.0, 0.0]);
        assert!(normals[0][1] > 0.9 && normals[0][0] < 0.0, "{:?}", normals[0]);
        assert_eq!(vertex_normals_from_faces(&positions, &[])[0], [0.0, 1.0, 0.0]);
    }
}
