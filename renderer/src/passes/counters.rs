//! The passes by name, and what each has cost: built or not, runs and
//! milliseconds.

use std::time::Instant;

/// Terrain: the clipmap levels over the coarse base, coloured by the
/// colour layer, lit by the `lighting` effect.
pub const TERRAIN: &str = "terrain";
/// Buildings: the `buildings` layer's meshes, lifted onto the drawn
/// terrain. Built only for a scene with that layer.
pub const BUILDINGS: &str = "buildings";
/// Instances: the `instances` layer's models and billboards. Built only
/// for a scene with that layer.
pub const INSTANCES: &str = "instances";
/// Atmosphere: the `atmosphere` effect's sky and aerial perspective, laid
/// over everything drawn. Built only for a scene that declares it.
pub const ATMOSPHERE: &str = "atmosphere";
/// Fog: the `fog` effect, laid over everything drawn (and the atmosphere).
/// Built only for a scene that declares it.
pub const FOG: &str = "fog";
/// Shadows: the `shadows` effect, cascaded shadow maps drawn from the sun
/// (terrain, buildings and instance models cast) before the frame's
/// colour; the lit passes take the sunlight they hide from each pixel
/// they draw (timed in those passes). Built only for a scene that
/// declares it.
pub const SHADOWS: &str = "shadows";
/// Water: the `water` effect, the water layer drawn as a surface at its
/// level or on the terrain. Built only for a scene that declares it.
pub const WATER: &str = "water";
/// Every pass a renderer knows, in the order a frame runs them.
pub const ALL: &[&str] = &[SHADOWS, TERRAIN, BUILDINGS, INSTANCES, WATER, ATMOSPHERE, FOG];

/// One pass's record.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PassStats {
    pub name: &'static str,
    /// Its pipelines and buffers exist.
    pub built: bool,
    /// Frames it ran in.
    pub runs: u64,
    /// Wall time over those runs, milliseconds: preparing (tiles, uploads)
    /// and the device drawing it.
    pub total_ms: f64,
}

/// The record of every pass a renderer knows, built or not.
#[derive(Debug, Clone, PartialEq)]
pub struct PassCounters {
    stats: Vec<PassStats>,
}

impl Default for PassCounters {
    fn default() -> Self {
        Self { stats: ALL.iter().map(|&name| PassStats { name, ..PassStats::default() }).collect() }
    }
}

impl PassCounters {
    fn entry(&mut self, name: &'static str) -> &mut PassStats {
        let at = self.stats.iter().position(|s| s.name == name).unwrap_or_else(|| {
            self.stats.push(PassStats { name, ..PassStats::default() });
            self.stats.len() - 1
        });
        &mut self.stats[at]
    }

    /// A run of `name` that started at `started`; returns its milliseconds.
    pub fn ran(&mut self, name: &'static str, started: Instant) -> f64 {
        let ms = started.elapsed().as_secs_f64() * 1e3;
        self.add_run(name, ms);
        ms
    }

    /// A run of `name` that took `ms`.
    pub fn add_run(&mut self, name: &'static str, ms: f64) {
        let e = self.entry(name);
        e.runs += 1;
        e.total_ms += ms;
    }

    /// Whether `name` is built now.
    pub fn set_built(&mut self, name: &'static str, built: bool) {
        self.entry(name).built = built;
    }

    pub fn is_built(&self, name: &str) -> bool {
        self.stats.iter().any(|s| s.name == name && s.built)
    }

    pub fn stats(&self) -> &[PassStats] {
        &self.stats
    }
}
