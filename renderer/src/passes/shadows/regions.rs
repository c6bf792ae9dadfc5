//! The texels of a cascade's map that changed areas cover: each area's
//! points seen from the sun through the cascade's matrix, boxed, widened
//! by a margin, and the boxes merged where they meet.

use glam::DVec3;

use super::cascades::Cascade;
use crate::passes::casting::Area;

/// Texels added round each area's box: the rasterizer's reach past a
/// triangle's edge and the lookup's linear filter.
const MARGIN_TEXELS: f64 = 2.0;

/// Rectangles kept apart in one map; more are merged into their box (each
/// region chooses its casters again: a few cost less than many).
const MOST_RECTS: usize = 3;

/// A rectangle of a map's texels, x and y from the top left, half-open.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TexelRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl TexelRect {
    pub fn texels(&self) -> u64 {
        u64::from(self.x1 - self.x0) * u64::from(self.y1 - self.y0)
    }

    fn meets(&self, o: &Self) -> bool {
        self.x0 <= o.x1 && o.x0 <= self.x1 && self.y0 <= o.y1 && o.y0 <= self.y1
    }

    fn union(&self, o: &Self) -> Self {
        Self { x0: self.x0.min(o.x0), y0: self.y0.min(o.y0), x1: self.x1.max(o.x1), y1: self.y1.max(o.y1) }
    }

    /// As a scissor: x, y, width, height.
    pub fn scissor(&self) -> [u32; 4] {
        [self.x0, self.y0, self.x1 - self.x0, self.y1 - self.y0]
    }
}

/// The texels of `cascade`'s map (`size` a side) that `area` covers, seen
/// from `eye` (world); None when it lies off the map.
pub fn texels(cascade: &Cascade, eye: DVec3, area: &Area, size: u32) -> Option<TexelRect> {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &area.points {
        let q = cascade.clip * (*p - eye).extend(1.0);
        // Columns from the left, rows from the top (NDC y up).
        let (u, v) = (f64::midpoint(q.x, 1.0) * f64::from(size), (1.0 - q.y) / 2.0 * f64::from(size));
        (lo, hi) = ([lo[0].min(u), lo[1].min(v)], [hi[0].max(u), hi[1].max(v)]);
    }
    if !(lo[0].is_finite() && lo[1].is_finite() && hi[0].is_finite() && hi[1].is_finite()) {
        return None;
    }
    let side = f64::from(size);
    let clamp = |v: f64| v.clamp(0.0, side) as u32;
    let rect = TexelRect {
        x0: clamp((lo[0] - MARGIN_TEXELS).floor()),
        y0: clamp((lo[1] - MARGIN_TEXELS).floor()),
        x1: clamp((hi[0] + MARGIN_TEXELS).ceil()),
        y1: clamp((hi[1] + MARGIN_TEXELS).ceil()),
    };
    (rect.x1 > rect.x0 && rect.y1 > rect.y0).then_some(rect)
}

/// `rects` with those that meet merged, at most [`MOST_RECTS`] (else their
/// box).
pub fn merged(mut rects: Vec<TexelRect>) -> Vec<TexelRect> {
    let mut changed = true;
    while changed {
        changed = false;
        'outer: for i in 0..rects.len() {
            for j in i + 1..rects.len() {
                if rects[i].meets(&rects[j]) {
                    rects[i] = rects[i].union(&rects[j]);
                    rects.swap_remove(j);
                    changed = true;
                    break 'outer;
                }
            }
        }
    }
    if rects.len() > MOST_RECTS {
        let all = rects.iter().skip(1).fold(rects[0], |a, r| a.union(r));
        return vec![all];
    }
    rects
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(x0: u32, y0: u32, x1: u32, y1: u32) -> TexelRect {
        TexelRect { x0, y0, x1, y1 }
    }

    #[test]
    fn rects_that_meet_merge_and_apart_ones_stay() {
        let m = merged(vec![rect(0, 0, 10, 10), rect(5, 5, 20, 20), rect(100, 100, 110, 110)]);
        assert_eq!(m.len(), 2);
        assert!(m.contains(&rect(0, 0, 20, 20)) && m.contains(&rect(100, 100, 110, 110)));
        let many: Vec<TexelRect> = (0..5).map(|k| rect(k * 20, 0, k * 20 + 5, 5)).collect();
        assert_eq!(merged(many), vec![rect(0, 0, 85, 5)]);
    }
}
