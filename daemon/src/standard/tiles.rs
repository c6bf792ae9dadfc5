//! The standard tiles of one scene: what every format shares (the
//! encoded-tile cache, the counters, answers and errors).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use bytes::Bytes;
use relief_proto::v1 as pb;
use tokio_util::sync::CancellationToken;

use crate::scene::Scene;
use crate::scene_tiles::ModelCache;

/// Bytes of encoded standard tiles kept in memory (a group of the demo's
/// forest is some 40 MB of GLB); the state's `memory` shows what is held.
const ENCODED_BUDGET_BYTES: u64 = 256 * 1024 * 1024;

/// The first part of an encoded tile's address: its format.
pub(super) const FORMAT_TERRAIN: u64 = 1;
pub(super) const FORMAT_XYZ: u64 = 2;
pub(super) const FORMAT_GLB: u64 = 3;

/// A short version string of what something is made of (12 hex digits).
pub(super) fn version_of(made_of: &[u64]) -> String {
    format!("{:012x}", xxhash_rust::xxh3::xxh3_64(&bytes_of(made_of)) >> 16)
}

/// The address an encoded tile is kept under, from what it is made of
/// (its format first).
pub(super) fn address_of(made_of: &[u64]) -> u128 {
    xxhash_rust::xxh3::xxh3_128(&bytes_of(made_of))
}

fn bytes_of(values: &[u64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Why a standard tile or description cannot be served; each names what
/// was asked and what is wrong.
#[derive(Debug, Clone, thiserror::Error)]
pub enum StandardError {
    /// Not in this scene (a tile outside `available`, a format the scene
    /// does not offer): 404.
    #[error("{0}")]
    NotFound(String),
    /// The client asked for what this layer cannot give (an unknown
    /// extension in `Accept`): 406.
    #[error("{0}")]
    NotAcceptable(String),
    /// A malformed address: 400.
    #[error("{0}")]
    Invalid(String),
    /// The data behind is not ready (a failed source, shutting down): 503.
    #[error("{0}")]
    Unavailable(String),
    /// Past a limit (streams open at once): 429.
    #[error("{0}")]
    TooMany(String),
}

/// How long a client may keep an answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheRule {
    /// A versioned URL of the current version: it never changes.
    Immutable,
    /// A versioned URL of an older version, answered with the current
    /// tile: keep it briefly.
    Short,
    /// A description (`layer.json`) or an unversioned URL: ask again each
    /// time (the ETag makes that cheap).
    Revalidate,
}

impl CacheRule {
    /// The rule for a URL that named version `asked` (or none) when the
    /// current one is `current`.
    pub fn for_version(asked: Option<&str>, current: &str) -> Self {
        match asked {
            Some(v) if v == current => Self::Immutable,
            Some(_) => Self::Short,
            None => Self::Revalidate,
        }
    }
}

/// One encoded tile, and its ETag (a hash of its bytes).
#[derive(Debug)]
pub struct Encoded {
    pub bytes: Bytes,
    pub etag: String,
    pub content_type: &'static str,
    /// The bytes gzipped, made with them (on the tile pool, where they are
    /// encoded); None for a PNG, which gzip would not shrink.
    pub gzip: Option<Bytes>,
    /// Where a 3D Tiles content tile stands (None: not content, or nothing
    /// to draw).
    pub placement: Option<Placement>,
}

/// A GLB's place in its tileset: `boundingVolume.region` and `transform`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub region: [f64; 6],
    pub transform: [f64; 16],
}

impl Encoded {
    pub(super) fn new(bytes: Vec<u8>, content_type: &'static str) -> Self {
        let etag = format!("\"{:016x}\"", xxhash_rust::xxh3::xxh3_64(&bytes));
        let gzip = (content_type != "image/png").then(|| Bytes::from(relief_standard_tiles::gzip(&bytes)));
        Self { bytes: Bytes::from(bytes), etag, content_type, gzip, placement: None }
    }

    /// A 3D Tiles content tile and where it stands.
    pub(super) fn placed(bytes: Vec<u8>, content_type: &'static str, placement: Placement) -> Self {
        Self { placement: Some(placement), ..Self::new(bytes, content_type) }
    }

    /// Bytes held: the tile and its gzipped copy.
    fn weight(&self) -> u32 {
        u32::try_from(self.bytes.len() + self.gzip.as_ref().map_or(0, Bytes::len)).unwrap_or(u32::MAX)
    }
}

/// A tile as served: its bytes, how long to keep them, and the version
/// of the layer they belong to.
#[derive(Debug, Clone)]
pub struct Answer {
    pub encoded: Arc<Encoded>,
    pub cache: CacheRule,
    pub version: String,
    pub generation: u64,
}

/// What the standard tiles cost, for the scene state.
#[derive(Debug, Default)]
pub(super) struct Counters {
    pub(super) terrain_built: AtomicU64,
    pub(super) terrain_served: AtomicU64,
    pub(super) terrarium_built: AtomicU64,
    pub(super) imagery_built: AtomicU64,
    pub(super) glb_built: AtomicU64,
    pub(super) not_modified: AtomicU64,
    pub(super) notices_sent: AtomicU64,
    pub(super) change_streams: AtomicU64,
}

/// The standard tiles of one scene.
pub struct StandardTiles {
    pub(super) scene: Arc<Scene>,
    /// Differs between runs of reliefd, so that a version (and the URLs
    /// clients cache for a year) never names other content after a restart.
    pub(super) boot: u64,
    pub(super) encoded: moka::sync::Cache<u128, Arc<Encoded>>,
    pub(super) counters: Counters,
    pub(super) shutdown: CancellationToken,
    /// The instances' models, read once per file version.
    pub(super) models: ModelCache,
}

impl StandardTiles {
    pub fn new(scene: &Arc<Scene>, shutdown: CancellationToken) -> Arc<Self> {
        let started = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
        let boot = xxhash_rust::xxh3::xxh3_64(format!("{}-{}", started.as_nanos(), std::process::id()).as_bytes());
        let encoded = moka::sync::Cache::builder()
            .max_capacity(ENCODED_BUDGET_BYTES)
            .weigher(|_, e: &Arc<Encoded>| e.weight())
            .build();
        Arc::new(Self {
            scene: Arc::clone(scene),
            boot,
            encoded,
            counters: Counters::default(),
            shutdown,
            models: ModelCache::default(),
        })
    }

    /// The counters for the scene state.
    pub fn state(&self) -> pb::StandardTiles {
        let c = &self.counters;
        pb::StandardTiles {
            terrain_tiles_built: c.terrain_built.load(Ordering::Relaxed),
            terrain_tiles_served: c.terrain_served.load(Ordering::Relaxed),
            terrarium_tiles_built: c.terrarium_built.load(Ordering::Relaxed),
            imagery_tiles_built: c.imagery_built.load(Ordering::Relaxed),
            glb_tiles_built: c.glb_built.load(Ordering::Relaxed),
            not_modified: c.not_modified.load(Ordering::Relaxed),
            change_notices_sent: c.notices_sent.load(Ordering::Relaxed),
            change_streams: c.change_streams.load(Ordering::Relaxed),
            encoded_bytes: self.encoded.weighted_size(),
        }
    }

    /// Counts an answer of 304 Not Modified (the client's ETag matched).
    pub fn count_not_modified(&self) {
        self.counters.not_modified.fetch_add(1, Ordering::Relaxed);
    }
}
