//! Where each shadow cascade looks from the sun: the view split by
//! distance (the practical split scheme, between logarithmic and uniform),
//! each slice of the view's frustum boxed in the sun's axes, the box
//! reaching towards the sun far enough to take in what may cast onto it.
//! Positions are relative to the eye, as everything the GPU sees.

use glam::{DMat4, DVec3, DVec4};

use crate::camera::{Sees, View};

/// Weight of the logarithmic split against the uniform one: near cascades
/// small and sharp, far ones not needlessly coarse.
const SPLIT_LAMBDA: f64 = 0.8;

/// How high above the slice's ground a caster may stand (metres): the box
/// reaches towards the sun as far as a sun ray needs to climb this much.
const CASTER_RISE_M: f64 = 9_000.0;

/// The longest reach of a box towards the sun, metres (a sun at the
/// horizon would ask for any).
const MAX_REACH_M: f64 = 400_000.0;

/// Boxes are fixed in the world, not to the eye, and sized and placed on
/// a ladder, so that a camera moving a little finds the same boxes and
/// keeps its maps (`ShadowsPass`): each side at least `MARGIN` times what
/// the slice needs, rounded up to a power of 2^(1/4), its centre on a grid
/// of an eighth of the half side (within the margin, so the slice stays
/// inside), and its ends along the sun's rays on a grid of an eighth of
/// its length. The maps' texels are up to 1.1 x 2^(1/4) = 1.31 times those
/// of a box fitted to the slice alone.
const MARGIN: f64 = 1.1;
const RUNGS_PER_DOUBLING: f64 = 4.0;
const GRID: f64 = 8.0;

/// One cascade: its box and the matrix from eye-relative positions to the
/// shadow map (x, y in -1..1, depth 0..1 with nearer the sun greater).
#[derive(Debug, Clone, Copy)]
pub struct Cascade {
    pub bounds: LightBox,
    /// The box in the world (its centre across and ends along the sun's
    /// rays, from the world's origin), on the ladder: the same for every
    /// eye that finds the same box.
    pub anchored: [f64; 5],
    pub clip: DMat4,
    /// World metres per shadow-map texel.
    pub texel_m: f64,
    /// Depth per world metre towards the sun.
    pub depth_per_m: f64,
}

/// A box in the sun's axes: `right` and `up` across the sun's rays,
/// `toward` to the sun; centred at (x, y) across, from `z_lo` to `z_hi`
/// along.
#[derive(Debug, Clone, Copy)]
pub struct LightBox {
    right: DVec3,
    up: DVec3,
    toward: DVec3,
    pub x: f64,
    pub y: f64,
    pub half: f64,
    pub z_lo: f64,
    z_hi: f64,
}

impl LightBox {
    /// The sun's axes: right and up across its rays, towards it.
    pub fn axes(&self) -> (DVec3, DVec3, DVec3) {
        (self.right, self.up, self.toward)
    }

    /// The part of the box over texels `x0..x1` and rows `y0..y1` (from
    /// the top left) of a map `size` texels a side, along the whole of its
    /// depth.
    pub fn region(&self, (x0, y0, x1, y1): (u32, u32, u32, u32), size: u32) -> LightRegion {
        let across = |t: u32| 2.0 * f64::from(t) / f64::from(size) - 1.0;
        LightRegion {
            bounds: *self,
            x: (self.x + across(x0) * self.half, self.x + across(x1) * self.half),
            // Rows run down; the box's up runs up.
            y: (self.y - across(y1) * self.half, self.y - across(y0) * self.half),
        }
    }
}

/// A part of a [`LightBox`] across the sun's rays: what a region of its
/// map is drawn from.
#[derive(Debug, Clone, Copy)]
pub struct LightRegion {
    bounds: LightBox,
    x: (f64, f64),
    y: (f64, f64),
}

impl Sees for LightRegion {
    fn sees(&self, centre: DVec3, radius: f64) -> bool {
        let b = &self.bounds;
        let (x, y) = (centre.dot(b.right), centre.dot(b.up));
        x >= self.x.0 - radius
            && x <= self.x.1 + radius
            && y >= self.y.0 - radius
            && y <= self.y.1 + radius
            && b.sees(centre, radius)
    }
}

impl Sees for LightBox {
    fn sees(&self, centre: DVec3, radius: f64) -> bool {
        let (x, y, z) = (centre.dot(self.right) - self.x, centre.dot(self.up) - self.y, centre.dot(self.toward));
        x.abs() <= self.half + radius
            && y.abs() <= self.half + radius
            && z >= self.z_lo - radius
            && z <= self.z_hi + radius
    }
}

/// The distances splitting `near..far` into `count` slices.
pub fn splits(near: f64, far: f64, count: u32) -> Vec<f64> {
    (0..=count)
        .map(|i| {
            let t = f64::from(i) / f64::from(count);
            let log = near * (far / near).powf(t);
            let uniform = near + (far - near) * t;
            SPLIT_LAMBDA * log + (1.0 - SPLIT_LAMBDA) * uniform
        })
        .collect()
}

/// The cascades of `view` (images `aspect` wide per unit of height) for a
/// sun towards `sun` standing `sin_elevation` above the local horizon,
/// covering view distances `near..far` in `count` maps of `map_size`
/// texels a side.
pub fn fit(
    view: &View,
    aspect: f64,
    sun: DVec3,
    sin_elevation: f64,
    (near, far): (f64, f64),
    count: u32,
    map_size: u32,
) -> Vec<Cascade> {
    let toward = sun.normalize();
    let helper = if toward.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let right = helper.cross(toward).normalize();
    let up = toward.cross(right);
    let tan_y = (view.vertical_fov_deg.to_radians() / 2.0).tan();
    let tan_x = tan_y * aspect;
    let reach = (CASTER_RISE_M / sin_elevation.max(1e-3)).min(MAX_REACH_M);
    let d = splits(near, far, count);
    d.windows(2)
        .map(|w| {
            let corners = w.iter().flat_map(|&dist| {
                [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)].map(|(sx, sy)| {
                    view.forward * dist + view.right * (sx * dist * tan_x) + view.up * (sy * dist * tan_y)
                })
            });
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for p in corners {
                let q = DVec3::new(p.dot(right), p.dot(up), p.dot(toward));
                (lo, hi) = (lo.min(q), hi.max(q));
            }
            // Square texels: the larger side across, on the ladder.
            let needed = ((hi.x - lo.x).max(hi.y - lo.y) / 2.0).max(1.0);
            let half = 2f64.powf(((needed * MARGIN).log2() * RUNGS_PER_DOUBLING).ceil() / RUNGS_PER_DOUBLING);
            // The world's light-space place of the eye: boxes on the grids
            // there, then back relative to the eye.
            let at = DVec3::new(view.eye.dot(right), view.eye.dot(up), view.eye.dot(toward));
            let step = half / GRID;
            let snap = |v: f64| (v / step).round() * step;
            let (cx, cy) = (snap(f64::midpoint(lo.x, hi.x) + at.x), snap(f64::midpoint(lo.y, hi.y) + at.y));
            let length = (hi.z + reach) - (lo.z - 1.0);
            let z_step = 2f64.powf((length / GRID).log2().ceil());
            let z_lo_world = ((lo.z - 1.0 + at.z) / z_step).floor() * z_step;
            let z_hi_world = ((hi.z + reach + at.z) / z_step).ceil() * z_step;
            let (x, y) = (cx - at.x, cy - at.y);
            let (z_lo, z_hi) = (z_lo_world - at.z, z_hi_world - at.z);
            let depth_per_m = 1.0 / (z_hi - z_lo);
            let rows = [
                DVec4::new(right.x / half, right.y / half, right.z / half, -x / half),
                DVec4::new(up.x / half, up.y / half, up.z / half, -y / half),
                DVec4::new(toward.x, toward.y, toward.z, -z_lo) * depth_per_m,
                DVec4::W,
            ];
            Cascade {
                bounds: LightBox { right, up, toward, x, y, half, z_lo, z_hi },
                anchored: [cx, cy, half, z_lo_world, z_hi_world],
                clip: DMat4::from_cols(rows[0], rows[1], rows[2], rows[3]).transpose(),
                texel_m: 2.0 * half / f64::from(map_size),
                depth_per_m,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a test")]

    use super::*;
    use crate::camera::Pose;

    fn view() -> View {
        let pose = Pose {
            position: [0.0, 0.0, 500.0],
            heading_deg: 30.0,
            pitch_deg: -20.0,
            roll_deg: 0.0,
            vertical_fov_deg: 50.0,
        };
        View::new(DVec3::new(0.0, 0.0, 500.0), [DVec3::X, DVec3::Y, DVec3::Z], &pose)
    }

    #[test]
    fn splits_run_from_near_to_far_and_grow() {
        let s = splits(10.0, 20_000.0, 4);
        assert_eq!(s.len(), 5);
        assert!((s[0] - 10.0).abs() < 1e-9 && (s[4] - 20_000.0).abs() < 1e-6, "{s:?}");
        assert!(s.windows(3).all(|w| w[2] - w[1] > w[1] - w[0]), "{s:?}");
    }

    #[test]
    fn every_slice_lies_inside_its_map_with_nearer_the_sun_deeper() {
        let v = view();
        let sun = DVec3::new(0.5, -0.3, 0.4).normalize();
        let d = splits(50.0, 20_000.0, 3);
        for (k, c) in fit(&v, 16.0 / 9.0, sun, sun.z, (50.0, 20_000.0), 3, 2048).iter().enumerate() {
            for dist in [d[k], d[k + 1]] {
                for (sx, sy) in [(-1.0, -1.0), (1.0, 1.0), (1.0, -1.0)] {
                    let tan = 25f64.to_radians().tan();
                    let p = v.forward * dist + v.right * (sx * dist * tan * 16.0 / 9.0) + v.up * (sy * dist * tan);
                    let q = c.clip * p.extend(1.0);
                    assert!(q.x.abs() <= 1.0 + 1e-9 && q.y.abs() <= 1.0 + 1e-9, "{q:?}");
                    assert!((0.0..=1.0).contains(&q.z), "{q:?}");
                    assert!(c.bounds.sees(p, 1e-6));
                    // Towards the sun is deeper (reversed-Z, as the frame).
                    let above = c.clip * (p + sun * 100.0).extend(1.0);
                    assert!(above.z > q.z);
                    assert!((above.z - q.z - 100.0 * c.depth_per_m).abs() < 1e-9);
                }
            }
            // A point off the side of the box is not seen.
            assert!(!c.bounds.sees(v.right * 1e7, 1.0));
        }
    }

    #[test]
    fn a_camera_moved_a_little_finds_the_same_boxes_and_one_moved_far_new_ones() {
        let sun = DVec3::new(0.5, -0.3, 0.4).normalize();
        let at = |dx: f64| {
            let pose = Pose {
                position: [dx, 0.0, 500.0],
                heading_deg: 30.0,
                pitch_deg: -20.0,
                roll_deg: 0.0,
                vertical_fov_deg: 50.0,
            };
            let v = View::new(DVec3::new(dx, 0.0, 500.0), [DVec3::X, DVec3::Y, DVec3::Z], &pose);
            fit(&v, 16.0 / 9.0, sun, sun.z, (50.0, 20_000.0), 2, 1024).iter().map(|c| c.anchored).collect::<Vec<_>>()
        };
        let here = at(0.0);
        // Most 1 m steps keep both boxes; none moves the far one.
        let kept = (1..=20).filter(|&k| at(f64::from(k)) == here).count();
        assert!(kept >= 10, "{kept} of 20 one-metre steps kept the boxes");
        assert!((1..=20).all(|k| at(f64::from(k))[1] == here[1]));
        assert_ne!(at(2_000.0), here);
        // Fixed in the world: each box's half side is on the ladder.
        for a in &here {
            let rungs = a[2].log2() * RUNGS_PER_DOUBLING;
            assert!((rungs - rungs.round()).abs() < 1e-9, "{a:?}");
        }
    }
}
