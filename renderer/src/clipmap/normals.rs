//! A level's surface normals, worked out on the CPU where its samples
//! change, so the vertex stage reads one texel for a vertex's normal
//! instead of four positions (and eight more for the coarser level's).
//!
//! A sample's normal is `cross(south, east)` of its four neighbours in the
//! window, normalised; neighbours past the window's edge are clamped to
//! it. So a sample's normal changes when it or a neighbour is written, and
//! when the window moves and its edge comes to lie elsewhere.

use glam::Vec3;

use super::{ClipLevel, Rect, storage_rects};

impl ClipLevel {
    /// Works out again the normals that the samples written in `written`
    /// (global indices) change, and those along the window's edge when the
    /// window has moved since the last time.
    pub(super) fn renormal(&mut self, written: &[Rect]) {
        let window = self.window();
        let mut rects: Vec<Rect> = written
            .iter()
            .map(|r| Rect { x: r.x.start - 1..r.x.end + 1, y: r.y.start - 1..r.y.end + 1 }.intersect(&window))
            .filter(|r| !r.is_empty())
            .collect();
        if self.normals_origin != Some(self.origin) {
            let (x, y) = (window.x.clone(), window.y.clone());
            rects.extend([
                Rect { x: x.start..x.start + 1, y: y.clone() },
                Rect { x: x.end - 1..x.end, y: y.clone() },
                Rect { x: x.clone(), y: y.start..y.start + 1 },
                Rect { x, y: y.end - 1..y.end },
            ]);
            self.normals_origin = Some(self.origin);
        }
        let n = self.n;
        for rect in rects {
            for gy in rect.y.clone() {
                for gx in rect.x.clone() {
                    let (normal, slot) = (self.normal_at(gx, gy), self.slot(gx, gy));
                    self.normals[slot] = [normal.x, normal.y, normal.z, 0.0];
                }
            }
            self.normal_dirty.extend(storage_rects(&rect, n));
        }
    }

    /// The stored position of global sample (gx, gy), clamped into the window.
    fn position(&self, gx: i64, gy: i64) -> Vec3 {
        let last = self.n as i64 - 1;
        let gx = self.origin.0 + (gx - self.origin.0).clamp(0, last);
        let gy = self.origin.1 + (gy - self.origin.1).clamp(0, last);
        let [x, y, z, _] = self.positions[self.slot(gx, gy)];
        Vec3::new(x, y, z)
    }

    /// Up from the samples round (gx, gy): cross(south, east), normalised,
    /// or zero where they do not span a plane (the shader then takes up).
    fn normal_at(&self, gx: i64, gy: i64) -> Vec3 {
        let east = self.position(gx + 1, gy) - self.position(gx - 1, gy);
        let south = self.position(gx, gy + 1) - self.position(gx, gy - 1);
        let normal = south.cross(east);
        let length = normal.length();
        if length > 1e-20 { normal / length } else { Vec3::ZERO }
    }
}
