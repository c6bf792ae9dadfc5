//! A MultiPatch shape as its patches, the way OGR reads one: each triangle
//! of a strip or a fan a polygon of its own, an outer (or first) ring a new
//! polygon and each inner ring (or ring) after it a hole in it. The
//! source's `relief_source::patches` triangulates and draws them.

use shapefile::{Multipatch, Patch, PointZ};

type Polygon = Vec<Vec<[f64; 3]>>;

fn xyz(p: &PointZ) -> [f64; 3] {
    [p.x, p.y, p.z]
}

fn triangle(a: &PointZ, b: &PointZ, c: &PointZ) -> Polygon {
    vec![vec![xyz(a), xyz(b), xyz(c), xyz(a)]]
}

/// The patches of `shape` as polygons, in the order of its parts.
pub(crate) fn polygons(shape: &Multipatch) -> Vec<Polygon> {
    let mut out: Vec<Polygon> = Vec::new();
    // The polygon whose holes may still follow.
    let mut open: Option<usize> = None;
    for patch in shape.patches() {
        match patch {
            // Vertex k (from the third) closes a triangle with the two before it.
            Patch::TriangleStrip(ps) => {
                open = None;
                out.extend(ps.windows(3).map(|w| triangle(&w[0], &w[1], &w[2])));
            }
            // ... or with the one before it and the first.
            Patch::TriangleFan(ps) => {
                open = None;
                if let Some((first, rest)) = ps.split_first() {
                    out.extend(rest.windows(2).map(|w| triangle(first, &w[0], &w[1])));
                }
            }
            Patch::OuterRing(ps) | Patch::FirstRing(ps) => {
                out.push(vec![ps.iter().map(xyz).collect()]);
                open = Some(out.len() - 1);
            }
            Patch::InnerRing(ps) | Patch::Ring(ps) => match open {
                Some(k) => out[k].push(ps.iter().map(xyz).collect()),
                // A hole before any outer ring: kept as its own polygon, as OGR does.
                None => {
                    out.push(vec![ps.iter().map(xyz).collect()]);
                    open = Some(out.len() - 1);
                }
            },
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> PointZ {
        PointZ::new(x, y, z, shapefile::NO_DATA)
    }

    #[test]
    fn strips_fans_and_rings_become_ogrs_polygons() {
        let shape = Multipatch::with_parts(vec![
            Patch::TriangleStrip(vec![p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.), p(1., 1., 0.)]),
            Patch::TriangleFan(vec![p(5., 5., 1.), p(6., 5., 1.), p(6., 6., 1.), p(5., 6., 1.)]),
            Patch::OuterRing(vec![p(0., 0., 9.), p(9., 0., 9.), p(9., 9., 9.), p(0., 0., 9.)]),
            Patch::InnerRing(vec![p(5., 1., 9.), p(6., 1., 9.), p(6., 2., 9.), p(5., 1., 9.)]),
            Patch::FirstRing(vec![p(0., 0., 3.), p(2., 0., 3.), p(2., 2., 3.), p(0., 0., 3.)]),
            Patch::Ring(vec![p(1.5, 0.2, 3.), p(1.8, 0.2, 3.), p(1.8, 0.5, 3.), p(1.5, 0.2, 3.)]),
        ]);
        let polygons = polygons(&shape);
        // Two strip triangles, two fan triangles, two polygons with a hole each.
        assert_eq!(polygons.len(), 6);
        assert_eq!(polygons[0][0][..3], [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
        assert_eq!(polygons[1][0][..3], [[1., 0., 0.], [0., 1., 0.], [1., 1., 0.]]);
        assert_eq!(polygons[2][0][..3], [[5., 5., 1.], [6., 5., 1.], [6., 6., 1.]]);
        assert_eq!(polygons[3][0][..3], [[5., 5., 1.], [6., 6., 1.], [5., 6., 1.]]);
        assert_eq!(polygons[4].len(), 2);
        assert_eq!(polygons[5].len(), 2);
    }
}
