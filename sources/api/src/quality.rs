//! The named accuracy knobs that sources read. Each trades accuracy for
//! time; a benchmark sweeps it (see `sources/gdal/benches/pyramid.rs`).

use std::fmt;
use std::str::FromStr;

/// The resampling kernel used when a source is warped into the tile grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Resampling {
    Nearest,
    #[default]
    Bilinear,
    /// Keys' cubic convolution, a = -0.5 (GDAL's `cubic`).
    Cubic,
    /// Lanczos windowed sinc, a = 3 (GDAL's `lanczos`).
    Lanczos,
}

impl Resampling {
    pub const ALL: [Self; 4] = [Self::Nearest, Self::Bilinear, Self::Cubic, Self::Lanczos];

    /// Half-width of the kernel in source pixels.
    pub fn radius(self) -> usize {
        match self {
            Self::Nearest | Self::Bilinear => 1,
            Self::Cubic => 2,
            Self::Lanczos => 3,
        }
    }

    /// The kernel's weight at distance `t` (in source pixels) from the sample.
    pub fn weight(self, t: f64) -> f64 {
        let t = t.abs();
        match self {
            Self::Nearest => {
                if t < 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            Self::Bilinear => (1.0 - t).max(0.0),
            Self::Cubic => {
                const A: f64 = -0.5;
                if t < 1.0 {
                    ((A + 2.0) * t - (A + 3.0)) * t * t + 1.0
                } else if t < 2.0 {
                    ((A * t - 5.0 * A) * t + 8.0 * A) * t - 4.0 * A
                } else {
                    0.0
                }
            }
            Self::Lanczos => {
                const A: f64 = 3.0;
                if t < 1e-12 {
                    1.0
                } else if t < A {
                    let pt = std::f64::consts::PI * t;
                    A * pt.sin() * (pt / A).sin() / (pt * pt)
                } else {
                    0.0
                }
            }
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Nearest => "nearest",
            Self::Bilinear => "bilinear",
            Self::Cubic => "cubic",
            Self::Lanczos => "lanczos",
        }
    }
}

impl fmt::Display for Resampling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Resampling {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|r| r.name() == s)
            .ok_or_else(|| format!("unknown resampling '{s}' (expected nearest, bilinear, cubic or lanczos)"))
    }
}

/// The accuracy knobs that tile generation reads, from the manifest's
/// `[quality]` section, optionally overridden per request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quality {
    /// Kernel used to warp rasters into the grid.
    pub resampling: Resampling,
    /// Largest error, in output samples, allowed when reprojection is
    /// approximated by interpolating exact transforms on a coarser lattice.
    /// 0 transforms every sample exactly (GDAL's `-et`).
    pub reprojection_error_px: f64,
}

impl Default for Quality {
    fn default() -> Self {
        Self { resampling: Resampling::Bilinear, reprojection_error_px: 0.125 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_are_one_at_zero_and_sum_to_one_on_integer_offsets() {
        for r in Resampling::ALL {
            assert!((r.weight(0.0) - 1.0).abs() < 1e-12, "{r}");
            // Interpolating kernels: zero at every other integer offset.
            for k in 1..=r.radius() {
                assert!(r.weight(k as f64).abs() < 1e-12, "{r} at {k}");
            }
        }
    }

    #[test]
    fn kernels_partition_unity_approximately() {
        for r in [Resampling::Bilinear, Resampling::Cubic] {
            for f in [0.1, 0.25, 0.5, 0.9] {
                let radius = r.radius() as i64;
                let sum: f64 = (-radius + 1..=radius).map(|k| r.weight(k as f64 - f)).sum();
                assert!((sum - 1.0).abs() < 1e-12, "{r} at {f}: {sum}");
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for r in Resampling::ALL {
            assert_eq!(r.name().parse::<Resampling>(), Ok(r));
        }
        assert!("bicubic".parse::<Resampling>().is_err());
    }
}
