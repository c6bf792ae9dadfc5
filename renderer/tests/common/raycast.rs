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
/// marched in 5 m steps until it climbs above `top_m` (the surface's
/// highest point) or has gone 20 km.
pub fn in_shadow(height: fn(f64, f64) -> f64, top_m: f64, x: f64, y: f64, sun: DVec3) -> bool {
    let z = height(x, y);
    (1..4000)
        .map(|k| DVec3::new(x, y, z) + sun * (f64::from(k) * 5.0))
        .take_while(|p| p.z <= top_m)
        .any(|p| height(p.x, p.y) > p.z)
}

/// The peaks' highest point, metres.
pub const PEAKS_TOP_M: f64 = 2_200.0;

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

/// One ground pixel the reference judges: whether the ray-cast finds it
/// in shadow, and what full shadow would leave of its light.
#[derive(Debug, Clone, Copy)]
pub struct Judged {
    pub pixel: usize,
    pub in_shadow: bool,
    pub full_shadow: f64,
    /// Along the sun's horizontal direction from the peaks, metres.
    pub towards_sun_m: f64,
}

/// The reference for the view of `lit` (a frame without shadows): every
/// ground pixel facing the sun enough that a shadow shows (sunlight at
/// least 0.15 of full) and not too dark to tell, ray-cast on `height`.
/// `(ambient, diffuse)` are the lighting's terms for this sun.
pub fn reference(
    lit: &Frame,
    height: fn(f64, f64) -> f64,
    top_m: f64,
    sun: SunAngles,
    (ambient, diffuse): (f64, f64),
) -> Vec<Judged> {
    let s = sun_dir(sun);
    let across = DVec3::new(s.x, s.y, 0.0).normalize_or_zero();
    let mut out = Vec::new();
    for py in 0..lit.height {
        for px in 0..lit.width {
            let i = (py * lit.width + px) as usize;
            let depth = lit.depth[i];
            if depth <= 0.0 || luminance(lit, i) < 60.0 {
                continue;
            }
            let (dir, dist) = lit.view.unproject(f64::from(px), f64::from(py), lit.width, lit.height, depth);
            let p = lit.view.eye + dir * dist;
            let sunlight = normal(height, p.x, p.y).dot(s);
            if sunlight < 0.15 {
                continue;
            }
            out.push(Judged {
                pixel: i,
                in_shadow: in_shadow(height, top_m, p.x, p.y, s),
                full_shadow: ambient / (ambient + diffuse * sunlight),
                towards_sun_m: (p - DVec3::new(301_000.0, 5_099_300.0, 0.0)).dot(across),
            });
        }
    }
    out
}

fn luminance(f: &Frame, i: usize) -> f64 {
    (0..3).map(|k| f64::from(f.rgba[i * 4 + k])).sum()
}

/// Scores `shadowed` (a frame with shadows) against the reference judged
/// on `lit` (the same view without them): a pixel is drawn in shadow where
/// it lost more than half of what full shadow would take.
pub fn score(judged: &[Judged], lit: &Frame, shadowed: &Frame) -> Score {
    let mut out = Score::default();
    let mut offsets = 0.0;
    for j in judged {
        let drawn = luminance(shadowed, j.pixel) / luminance(lit, j.pixel) < f64::midpoint(1.0, j.full_shadow);
        out.compared += 1;
        out.reference_shadowed += usize::from(j.in_shadow);
        out.drawn_shadowed += usize::from(drawn);
        out.wrong += usize::from(drawn != j.in_shadow);
        if drawn {
            offsets += j.towards_sun_m;
        }
    }
    out.towards_sun_m = offsets / out.drawn_shadowed.max(1) as f64;
    out
}
