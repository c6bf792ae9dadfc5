//! The passes a frame is drawn in, each in its own module, and what they
//! have cost. A renderer builds a pass (pipelines, buffers, textures) only
//! when the scene calls for it; the counters say which were built, how
//! often each ran and what it took.

pub mod buildings;
pub mod terrain;

use std::time::Instant;

/// Terrain: the clipmap levels over the coarse base, coloured by the
/// colour layer, lit by the `lighting` effect.
pub const TERRAIN: &str = "terrain";
/// Buildings: the `buildings` layer's meshes, lifted onto the drawn
/// terrain. Built only for a scene with that layer.
pub const BUILDINGS: &str = "buildings";
/// Every pass a renderer knows, in the order a frame runs them.
pub const ALL: &[&str] = &[TERRAIN, BUILDINGS];

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

    pub fn built(&mut self, name: &'static str) {
        self.entry(name).built = true;
    }

    /// A run of `name` that started at `started`; returns its milliseconds.
    pub fn ran(&mut self, name: &'static str, started: Instant) -> f64 {
        let ms = started.elapsed().as_secs_f64() * 1e3;
        let e = self.entry(name);
        e.runs += 1;
        e.total_ms += ms;
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
