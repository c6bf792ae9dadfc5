//! The loaded model: plain indexed triangles.

/// A model as plain triangles, in metres, in glTF's axes: +Y up, +X right,
/// +Z towards the viewer (so on the ground x is east, y up and z south).
///
/// The node transforms of the default scene (or scene 0) are applied; the
/// origin is where the model stands on the ground.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, one per vertex. When the file has none they are
    /// computed: each vertex gets the area-weighted sum of the normals of
    /// the faces that share it.
    pub normals: Vec<[f32; 3]>,
    /// One colour per vertex: the material's base colour factor times
    /// `COLOR_0` where present, as straight (not premultiplied) RGBA with
    /// sRGB-encoded 0..1 values, as a PNG would store them.
    pub colors: Vec<[f32; 4]>,
    /// A triangle list, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
    pub bounds: Bounds,
}

/// An axis-aligned box around a model's positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

impl Bounds {
    /// The box around `positions`; all zero when there are none.
    pub(crate) fn of(positions: &[[f32; 3]]) -> Self {
        let Some(first) = positions.first() else {
            return Self { min: [0.0; 3], max: [0.0; 3] };
        };
        positions.iter().fold(Self { min: *first, max: *first }, |b, p| Self {
            min: [b.min[0].min(p[0]), b.min[1].min(p[1]), b.min[2].min(p[2])],
            max: [b.max[0].max(p[0]), b.max[1].max(p[1]), b.max[2].max(p[2])],
        })
    }
}

impl Model {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Height above the origin: the top of the bounds (`bounds.max[1]`).
    pub fn height(&self) -> f32 {
        self.bounds.max[1]
    }

    /// The largest horizontal distance of a vertex from the vertical axis
    /// through the origin.
    pub fn radius(&self) -> f32 {
        self.positions.iter().map(|p| p[0].hypot(p[2])).fold(0.0, f32::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_height_and_radius() {
        let positions = vec![[1.0, -1.0, 0.0], [0.0, 4.0, -3.0], [-2.0, 0.5, 1.0]];
        let model = Model {
            bounds: Bounds::of(&positions),
            normals: vec![[0.0, 1.0, 0.0]; 3],
            colors: vec![[1.0; 4]; 3],
            indices: vec![0, 1, 2],
            positions,
        };
        assert_eq!(model.bounds, Bounds { min: [-2.0, -1.0, -3.0], max: [1.0, 4.0, 1.0] });
        assert_eq!(model.height(), 4.0);
        assert_eq!(model.radius(), 3.0);
        assert_eq!(model.triangle_count(), 1);
    }
}
