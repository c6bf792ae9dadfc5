//! Reading an input's height samples by global sample index, across tile
//! borders, the antimeridian and the poles.

use std::collections::HashMap;
use std::sync::Arc;

use relief_source::{GenerateContext, Payload, SourceError, TileKey};

/// Height samples of one input at one level, addressed by global
/// corner-sample index (column X grows east, row Y grows south). Tiles are
/// fetched from the input on first use.
pub struct HeightWindow<'a, 'c> {
    ctx: &'a GenerateContext<'c>,
    input: usize,
    level: u8,
    tiles: HashMap<TileKey, Arc<Payload>>,
}

impl<'a, 'c> HeightWindow<'a, 'c> {
    pub fn new(ctx: &'a GenerateContext<'c>, input: usize, level: u8) -> Self {
        Self { ctx, input, level, tiles: HashMap::new() }
    }

    /// The height at global sample (X, Y); NaN for nodata. On the geodetic
    /// grid columns wrap and rows past a pole continue half way round the
    /// planet; a projected grid repeats its edge samples.
    pub fn get(&mut self, gx: i64, gy: i64) -> Result<f32, SourceError> {
        let (key, i, j) = self.ctx.grid.corner_sample(self.level, gx, gy);
        let tile = if let Some(t) = self.tiles.get(&key) {
            Arc::clone(t)
        } else {
            let t = self.ctx.inputs.tile(self.input, key)?;
            self.tiles.insert(key, Arc::clone(&t));
            t
        };
        let Payload::Height(h) = tile.as_ref() else {
            return Err(SourceError::Input {
                input: self.input.to_string(),
                message: format!("expected a height tile, got a {} tile", tile.kind()),
            });
        };
        Ok(h.get(i, j))
    }
}

impl HeightWindow<'_, '_> {
    /// The height at grid-CRS point (x, y), bilinear between the four
    /// samples round it; NaN where any of them is nodata.
    pub fn height_at(&mut self, x: f64, y: f64) -> Result<f32, SourceError> {
        let (gx, gy) = self.ctx.grid.sample_coords(self.level, x, y);
        let (x0, y0) = (gx.floor(), gy.floor());
        let (fx, fy) = ((gx - x0) as f32, (gy - y0) as f32);
        let (i, j) = (x0 as i64, y0 as i64);
        let (a, b) = (self.get(i, j)?, self.get(i + 1, j)?);
        let (c, d) = (self.get(i, j + 1)?, self.get(i + 1, j + 1)?);
        let top = a + (b - a) * fx;
        let bottom = c + (d - c) * fx;
        Ok(top + (bottom - top) * fy)
    }
}
