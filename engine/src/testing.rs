//! What the daemon's unit tests share: a source with known tiles and a
//! scene of it.

use std::path::Path;
use std::sync::Arc;

use relief_source::{
    GenerateContext, HeightTile, Payload, PayloadKind, Source, SourceError, SourceSpec, TileGrid, TileKey,
};

use crate::graph::{SceneSnapshot, Slot};
use crate::manifest::Manifest;

/// A source whose tiles are flat at their level, so results are known. It
/// reads no files: its content address comes from its kind, options and
/// the grid.
#[derive(Debug)]
pub(crate) struct Flat;

impl Source for Flat {
    fn id(&self) -> &'static str {
        "flat"
    }
    fn kind(&self) -> &'static str {
        "test"
    }
    fn output(&self) -> PayloadKind {
        PayloadKind::Height
    }
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let n = ctx.grid.tile_size() as usize + 1;
        Ok(Payload::Height(HeightTile { size: n, heights: vec![f32::from(key.level); n * n] }))
    }
}

/// Generation `generation` of a scene of the flat source alone, on a
/// 64-sample geodetic grid, its content address yet to be worked out.
pub(crate) fn flat_snapshot(generation: u64) -> SceneSnapshot {
    let manifest = Manifest::parse("[scene]\nname = \"t\"\n", Path::new("/t/scene.toml")).expect("the manifest parses");
    let slot = Slot {
        spec: SourceSpec { id: "flat".into(), kind: "test".into(), ..SourceSpec::default() },
        source: Some(Arc::new(Flat)),
        error: None,
        version: 1,
        effective_version: 7,
        inputs: vec![],
        active: true,
        content: crate::content::ContentKey::default(),
    };
    SceneSnapshot {
        generation,
        manifest: Arc::new(manifest),
        grid: TileGrid::geodetic(64).expect("a grid"),
        slots: vec![slot],
    }
}
