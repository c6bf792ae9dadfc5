//! Each frame's sorting of the instances in reach (f64, on the CPU, tiles
//! in parallel): whole tiles out of reach or out of view passed over, each
//! instance culled to the view, thinned by its distance band and split
//! into its model's list or the billboards', with the dither ranges that
//! cross-fade the two.

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use relief_source::Payload;
use std::sync::Arc;

use super::models::{GpuInstance, GpuModel};
use super::view::InstancesView;
use crate::camera::{Frustum, Sees};

/// One instance of a tile, ready for sorting.
pub struct Placed {
    pub world: DVec3,
    pub east: Vec3,
    pub up: Vec3,
    pub scale: f32,
    /// Its own random number (0..1, from its feature id): thinning keeps
    /// the instances whose number is under the band's density.
    pub random: f64,
    pub slot: u32,
    /// Placed as a billboard whatever its distance (`render_as`).
    pub billboard_only: bool,
}

pub struct PlacedTile {
    pub payload: Arc<Payload>,
    pub placed: Vec<Placed>,
    /// A sphere holding every instance whole (world): whole tiles out of
    /// reach or out of view are passed over.
    pub centre: DVec3,
    pub radius: f64,
}

/// What sorting needs of a model: its size, and its billboard's quad.
pub struct Shape {
    radius: f32,
    height: f32,
    billboard: [f32; 4],
}

impl Shape {
    pub fn of(model: &GpuModel) -> Self {
        Self { radius: model.model.radius(), height: model.model.height(), billboard: model.billboard(1.0) }
    }
}

/// A frame's instances: a list per model slot, the billboards, and how
/// many were in reach and in view before the bands thinned them.
#[derive(Default)]
pub struct Sorted {
    pub models: Vec<Vec<GpuInstance>>,
    /// The tile's instances (their places in it) drawn as models: what it
    /// casts into the shadow maps.
    pub cast: Vec<u32>,
    pub billboards: Vec<GpuInstance>,
    pub in_view: usize,
}

impl Sorted {
    pub fn merge(mut self, other: Self) -> Self {
        if self.models.len() < other.models.len() {
            self.models.resize(other.models.len(), Vec::new());
        }
        for (mine, theirs) in self.models.iter_mut().zip(other.models) {
            mine.extend(theirs);
        }
        self.billboards.extend(other.billboards);
        self.cast.extend(other.cast);
        self.in_view += other.in_view;
        self
    }
}

/// Each tile's instances sorted, in the order of `tiles`.
pub fn sort(tiles: &[&PlacedTile], at: &InstancesView<'_>, shapes: &[Shape]) -> Vec<Sorted> {
    let reach = at.bands.reach_m();
    let cull = at.view.frustum(at.aspect);
    tiles
        .par_iter()
        .map(|tile| {
            let mut out = Sorted { models: vec![Vec::new(); shapes.len()], ..Sorted::default() };
            let rel = tile.centre - at.view.eye;
            if tile.placed.is_empty() || rel.length() - tile.radius > reach || !cull.sees(rel, tile.radius) {
                return out;
            }
            for (i, p) in tile.placed.iter().enumerate() {
                if place(p, at, &cull, shapes, reach, &mut out) {
                    out.cast.push(i as u32);
                }
            }
            out
        })
        .collect()
}

/// Sorts one instance into `out`; true when it is drawn as a model.
fn place(p: &Placed, at: &InstancesView<'_>, cull: &Frustum, shapes: &[Shape], reach: f64, out: &mut Sorted) -> bool {
    let rel = p.world - at.view.eye;
    let d = rel.length();
    if d > reach {
        return false;
    }
    let shape = &shapes[p.slot as usize];
    let centre = rel + (p.up * p.scale * shape.height / 2.0).as_dvec3();
    if !cull.sees(centre, f64::from(p.scale * (shape.radius.max(shape.height / 2.0) + 1.0))) {
        return false;
    }
    out.in_view += 1;
    let (shown, mut model_share) = at.bands.coverage(d, p.random);
    if p.billboard_only {
        model_share = 0.0;
    }
    if shown <= 0.0 {
        return false;
    }
    let split = (shown * model_share) as f32;
    let r = rel.as_vec3();
    let [w, bottom, top, layer] = shape.billboard;
    let mut instance = GpuInstance {
        pos: [r.x, r.y, r.z, p.scale],
        east: [p.east.x, p.east.y, p.east.z, 0.0],
        up: [p.up.x, p.up.y, p.up.z, split],
        billboard: [w * p.scale, bottom * p.scale, top * p.scale, layer],
    };
    if model_share > 0.0 {
        out.models[p.slot as usize].push(instance);
    }
    if model_share < 1.0 {
        instance.east[3] = split;
        instance.up[3] = shown as f32;
        out.billboards.push(instance);
    }
    model_share > 0.0
}
