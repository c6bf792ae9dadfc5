//! Distance bands (Savelli et al.): how much of the instances layer is
//! drawn at a distance, and where models give way to billboards. Every
//! change is a ramp, never a step: an instance fades out (dithered) over
//! the distance its band's density takes to fall past its own random
//! number, and models and billboards cross-fade, so nothing pops.

/// The instances layer's accuracy knobs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InstanceBands {
    /// Outer edges of the three bands, metres from the eye.
    pub edges_m: [f64; 3],
    /// The share of instances drawn in each band (0..=1).
    pub densities: [f64; 3],
    /// Models nearer than this, billboards farther, metres.
    pub model_distance_m: f64,
}

impl Default for InstanceBands {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The farthest a band may reach: instances are what stands near the
/// camera (beyond, each frame would sort millions of them).
pub const MAX_REACH_M: f64 = 20_000.0;
/// A ramp's width as a share of the distance it is centred on.
const RAMP: f64 = 0.1;
/// How much density an instance takes to fade in or out: the share of
/// instances fading at once where the density falls. Random numbers are
/// scaled into 0..1 - SOFT so that at full density every instance is whole.
const SOFT: f64 = 0.02;

impl InstanceBands {
    /// 700 / 1,400 / 3,000 m at 100 / 80 / 50 % (Savelli et al.); models
    /// to 400 m.
    pub const DEFAULT: Self =
        Self { edges_m: [700.0, 1400.0, 3000.0], densities: [1.0, 0.8, 0.5], model_distance_m: 400.0 };

    /// The reference: every instance a model, all drawn, to `reach_m`.
    pub fn reference(reach_m: f64) -> Self {
        Self { edges_m: [reach_m; 3], densities: [1.0; 3], model_distance_m: reach_m * 2.0 }
    }

    /// Checks the knobs: increasing edges, densities in 0..=1, a model
    /// distance of 0 or more. Names the knob at fault.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let [a, b, c] = self.edges_m;
        if !(a > 0.0 && a <= b && b <= c && c <= MAX_REACH_M) {
            return Err((
                "instance_bands_m",
                format!("{a}, {b}, {c} are not increasing distances from above 0 to {MAX_REACH_M} m"),
            ));
        }
        if let Some(d) = self.densities.iter().find(|d| !(0.0..=1.0).contains(*d)) {
            return Err(("instance_band_densities", format!("{d} is not a share from 0 to 1")));
        }
        if !(self.model_distance_m >= 0.0 && self.model_distance_m.is_finite()) {
            return Err(("instance_model_distance_m", format!("{} is not 0 m or more", self.model_distance_m)));
        }
        Ok(())
    }

    /// The farthest any instance is drawn, metres.
    pub fn reach_m(&self) -> f64 {
        self.edges_m[2] * (1.0 + RAMP / 2.0)
    }

    /// The share of instances drawn at `d` metres: each band's density,
    /// ramped linearly over RAMP of each edge; 0 past the last band.
    pub fn density(&self, d: f64) -> f64 {
        let mut value = self.densities[0];
        let next = [self.densities[1], self.densities[2], 0.0];
        for (k, &edge) in self.edges_m.iter().enumerate() {
            let half = edge * RAMP / 2.0;
            let t = ((d - (edge - half)) / (2.0 * half)).clamp(0.0, 1.0);
            if t > 0.0 {
                value = value + (next[k] - value) * t;
            }
        }
        value
    }

    /// How much of an instance with random number `r` (0..1) shows at `d`
    /// metres (0 hidden, 1 whole), and how much of that is its model
    /// (1 model only, 0 billboard only).
    pub fn coverage(&self, d: f64, r: f64) -> (f64, f64) {
        let shown = ((self.density(d) - r * (1.0 - SOFT)) / SOFT).clamp(0.0, 1.0);
        let half = (self.model_distance_m * RAMP / 2.0).max(1.0);
        let model = ((self.model_distance_m + half - d) / (2.0 * half)).clamp(0.0, 1.0);
        (shown, model)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn density_steps_through_the_bands_with_ramps() {
        let b = InstanceBands::default();
        assert_eq!(b.density(0.0), 1.0);
        assert_eq!(b.density(600.0), 1.0);
        assert!((b.density(1000.0) - 0.8).abs() < 1e-12);
        assert!((b.density(2000.0) - 0.5).abs() < 1e-12);
        assert_eq!(b.density(3200.0), 0.0);
        // Half way across the first ramp: half way between the bands.
        assert!((b.density(700.0) - 0.9).abs() < 1e-12);
        // Continuous everywhere: no step larger than a ramp's slope allows.
        let mut last = b.density(0.0);
        for i in 1..40_000 {
            let d = f64::from(i) * 0.1;
            let v = b.density(d);
            assert!((v - last).abs() < 0.01, "jump at {d} m: {last} to {v}");
            last = v;
        }
    }

    #[test]
    fn an_instance_fades_out_over_distance_not_at_once() {
        let b = InstanceBands::default();
        // r = 0.9 is kept at full density and dropped at 80 %.
        let (near, _) = b.coverage(100.0, 0.9);
        let (far, _) = b.coverage(1000.0, 0.9);
        assert_eq!((near, far), (1.0, 0.0));
        let fading: Vec<f64> =
            (660..=740).map(|d| b.coverage(f64::from(d), 0.9).0).filter(|s| *s > 0.0 && *s < 1.0).collect();
        assert!(fading.len() > 5, "fades over several metres: {fading:?}");
    }

    #[test]
    fn models_cross_fade_into_billboards() {
        let b = InstanceBands::default();
        assert_eq!(b.coverage(100.0, 0.1).1, 1.0);
        assert_eq!(b.coverage(600.0, 0.1).1, 0.0);
        let mid = b.coverage(400.0, 0.1).1;
        assert!((mid - 0.5).abs() < 1e-9, "{mid}");
    }

    #[test]
    fn bad_knobs_are_named() {
        let b = InstanceBands { edges_m: [700.0, 600.0, 3000.0], ..InstanceBands::default() };
        assert_eq!(b.validate().unwrap_err().0, "instance_bands_m");
        let mut b = InstanceBands::default();
        b.densities[1] = 1.5;
        assert_eq!(b.validate().unwrap_err().0, "instance_band_densities");
        let far = InstanceBands { edges_m: [700.0, 1400.0, 50_000.0], ..InstanceBands::default() };
        assert_eq!(far.validate().unwrap_err().0, "instance_bands_m");
        let b = InstanceBands { model_distance_m: f64::NAN, ..InstanceBands::default() };
        assert_eq!(b.validate().unwrap_err().0, "instance_model_distance_m");
        assert!(InstanceBands::reference(5000.0).validate().is_ok());
    }
}
