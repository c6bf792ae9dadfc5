//! The shadows' reference: a CPU ray-cast on an analytic height field says
//! which drawn ground pixels the sun cannot reach, and a frame with shadows
//! is scored against it, pixel by pixel.

use glam::DVec3;
use relief_renderer::{Frame, SunAngles};

/// Two smooth peaks (1,700 m and 1,400 m) over a 1,000 m plain in the
/// 20 km UTM scene: long shadows on the plain, and one peak's on the other.
pub fn peaks(x: f64, y: f64) -> f64 {
    let bump = |cx: f64, cy: f64, h: f64, s: f64| h * (-((x - cx).powi(2) + (y - cy).powi(2)) / (2.0 * s * s)).exp();
    1000.0 + bump(300_000.0, 5_100_000.0, 700.0, 600.0) + bump(302_000.0, 5_099_000.0, 400.0, 400.0)
}

/// Towards the sun in a flat scene's axes (east, north, up).
pub fn sun_dir(sun: SunAngles) -> DVec3 {
    let (az, el) = (sun.azimuth_deg.to_radians(), sun.elevation_deg.to_radians());
    DVec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin())
}

/// Whether the sun ray from ground point (x, y) meets `height` above it:
/// marched in 5 m steps for 20 km.
pub fn in_shadow(height: fn(f64, f64) -> f64, x: f64, y: f64, sun: DVec3) -> bool {
    let z = height(x, y);
    (1..4000).any(|k| {
        let p = DVec3::new(x, y, z) + sun * (f64::from(k) * 5.0);
        height(p.x, p.y) > p.z
    })
}

/// The analytic surface's up-facing unit normal at (x, y).
fn normal(height: fn(f64, f64) -> f64, x: f64, y: f64) -> DVec3 {
    let e = 1.0;
    let dx = (height(x + e, y) - height(x - e, y)) / (2.0 * e);
    let dy = (height(x, y + e) - height(x, y - e)) / (2.0 * e);
    DVec3::new(-dx, -dy, 1.0).normalize()
}

/// How a frame's shadows compare with the ray-cast.
#[derive(Debug, Clone, Copy, Default)]
pub struct Score {
    /// Ground pixels compared: facing the sun enough that a shadow shows
    /// (sunlight at least 0.15 of full), and not too dark to tell.
    pub compared: usize,
    /// Those the ray-cast puts in shadow, and those the frame put in shadow.
    pub reference_shadowed: usize,
    pub drawn_shadowed: usize,
    /// Pixels where the two disagree.
    pub wrong: usize,
    /// Mean offset of the drawn shadowed pixels from the scene's centre
    /// along the sun's horizontal direction, metres (negative: away from
    /// the sun).
    pub towards_sun_m: f64,
}

impl Score {
    pub fn misclassified(&self) -> f64 {
        self.wrong as f64 / self.compared.max(1) as f64
    }
}

/// Scores `shadowed` (a frame with shadows) against the ray-cast, `lit`
/// being the same view without them: a pixel is drawn in shadow where it
/// lost more than half of what full shadow would take. `(ambient,
/// diffuse)` are the lighting's terms for this sun.
pub fn score(
    lit: &Frame,
    shadowed: &Frame,
    height: fn(f64, f64) -> f64,
    sun: SunAngles,
    (ambient, diffuse): (f64, f64),
) -> Score {
    let s = sun_dir(sun);
    let across = DVec3::new(s.x, s.y, 0.0).normalize_or_zero();
    let mut out = Score::default();
    let mut offsets = 0.0;
    for py in 0..lit.height {
        for px in 0..lit.width {
            let i = (py * lit.width + px) as usize;
            let depth = lit.depth[i];
            if depth <= 0.0 {
                continue;
            }
            let (dir, dist) = lit.view.unproject(f64::from(px), f64::from(py), lit.width, lit.height, depth);
            let p = lit.view.eye + dir * dist;
            let n = normal(height, p.x, p.y);
            let sunlight = n.dot(s);
            if sunlight < 0.15 {
                continue;
            }
            let lum = |f: &Frame| (0..3).map(|k| f64::from(f.rgba[i * 4 + k])).sum::<f64>();
            let (before, after) = (lum(lit), lum(shadowed));
            if before < 60.0 {
                continue;
            }
            let full = ambient / (ambient + diffuse * sunlight);
            let drawn = after / before < f64::midpoint(1.0, full);
            let reference = in_shadow(height, p.x, p.y, s);
            out.compared += 1;
            out.reference_shadowed += usize::from(reference);
            out.drawn_shadowed += usize::from(drawn);
            out.wrong += usize::from(drawn != reference);
            if drawn {
                offsets += (p - DVec3::new(301_000.0, 5_099_300.0, 0.0)).dot(across);
            }
        }
    }
    out.towards_sun_m = offsets / out.drawn_shadowed.max(1) as f64;
    out
}
