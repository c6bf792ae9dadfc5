//! Building one instance tile: each rule's candidates that the tile owns,
//! kept where the class raster holds the rule's class, thinned by the
//! density raster, anchored on the ground; then the point layer's points;
//! then the class counts of the tiles of the scatter's level it covers.

use std::collections::BTreeMap;

use relief_source::{
    GenerateContext, Geometry, Instance, InstanceKind, InstanceTile, Payload, SourceError, TileGrid, TileKey,
};

use super::counts::TileCounts;
use super::lattice::{Draws, draw, hash, offsets, wrap_lon};
use super::{COARSER_LEVELS, Scatter};
use crate::window::HeightWindow;

/// Salt of the draws of a point feature's instance.
const POINT_SALT: u64 = 0x706f_696e_7473;

/// The inputs of one tile, read at the scatter's level.
struct Reader<'a, 'c> {
    scatter: &'a Scatter,
    ctx: &'a GenerateContext<'c>,
    grid: &'a TileGrid,
    level: u8,
    classes: HeightWindow<'a, 'c>,
    ground: HeightWindow<'a, 'c>,
    density: Option<HeightWindow<'a, 'c>>,
}

impl<'a, 'c> Reader<'a, 'c> {
    fn new(scatter: &'a Scatter, ctx: &'a GenerateContext<'c>, level: u8) -> Self {
        Self {
            scatter,
            ctx,
            grid: ctx.grid,
            level,
            classes: HeightWindow::new(ctx, 0, level),
            ground: HeightWindow::new(ctx, 1, level),
            density: scatter.roles.density.map(|n| HeightWindow::new(ctx, n, level)),
        }
    }

    /// The class of the class raster's sample nearest (x, y); None for nodata.
    fn class_at(&mut self, x: f64, y: f64) -> Result<Option<i64>, SourceError> {
        let (gx, gy) = self.grid.sample_coords(self.level, x, y);
        let (i, j) = (gx.round() as i64, gy.round() as i64);
        let value = self.classes.get(i, j).map_err(self.scatter.input_error(0))?;
        let (sx, sy) = self.grid.sample_point(self.level, i, j);
        class_of(self.scatter, self.ctx, value, sx, sy)
    }

    /// The density factor at (x, y): bilinear, clamped to 0..1, nodata 0.
    fn density_at(&mut self, x: f64, y: f64) -> Result<f64, SourceError> {
        let Some(window) = self.density.as_mut() else { return Ok(1.0) };
        let n = self.scatter.roles.density.unwrap_or_default();
        let v = window.height_at(x, y).map_err(self.scatter.input_error(n))?;
        Ok(if v.is_nan() { 0.0 } else { f64::from(v).clamp(0.0, 1.0) })
    }

    /// The lowest ground of a footprint: the bilinear height at the centre
    /// and at `radius_m` east, west, north and south; None where any is
    /// nodata. Read at the fixed level, so it does not move when the
    /// terrain's level of detail does.
    fn anchor(&mut self, x: f64, y: f64, radius_m: f64) -> Result<Option<f64>, SourceError> {
        let (east, north) = offsets(self.grid, y, radius_m);
        let mut low = f32::INFINITY;
        for (px, py) in [(x, y), (x + east, y), (x - east, y), (x, y + north), (x, y - north)] {
            let h = self.ground.height_at(px, py).map_err(self.scatter.input_error(1))?;
            if h.is_nan() {
                return Ok(None);
            }
            low = low.min(h);
        }
        Ok(Some(f64::from(low)))
    }
}

/// A class sample's code; nodata is None, a value that is not an integer
/// fails the tile (a class raster read with an interpolating kernel).
fn class_of(
    scatter: &Scatter,
    ctx: &GenerateContext<'_>,
    value: f32,
    x: f64,
    y: f64,
) -> Result<Option<i64>, SourceError> {
    let grid = ctx.grid;
    if value.is_nan() {
        return Ok(None);
    }
    if value.is_finite() && value.fract() == 0.0 {
        return Ok(Some(value as i64));
    }
    let at = if grid.is_geodetic() { format!("({:.7}, {y:.7})", wrap_lon(x)) } else { format!("({x:.2}, {y:.2})") };
    let id = &scatter.inputs[0];
    let files: Vec<String> = ctx.inputs.files(0).iter().map(|f| f.display().to_string()).collect();
    let read = if files.is_empty() { String::new() } else { format!(" (reading {})", files.join(", ")) };
    Err(SourceError::Input {
        input: id.clone(),
        message: format!(
            "class raster '{id}'{read} holds {value} at {at}: class codes are integers (an integer band, read \
             with resampling = \"nearest\" on source '{id}', which also keeps classes in its coarser levels)"
        ),
    })
}

impl Scatter {
    /// Names input `n` by its id in an error that numbers it (a height
    /// window's, for one).
    fn input_error(&self, n: usize) -> impl Fn(SourceError) -> SourceError + '_ {
        move |e| match e {
            SourceError::Input { input, message } if input == n.to_string() => {
                SourceError::Input { input: self.inputs[n].clone(), message }
            }
            other => other,
        }
    }

    pub(super) fn build(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<InstanceTile, SourceError> {
        let grid = ctx.grid;
        let _ = self.grid.get_or_init(|| grid.clone());
        let level = self.level(grid);
        let coarsest = level.saturating_sub(COARSER_LEVELS);
        if key.level < coarsest {
            return Err(SourceError::option(
                "level",
                format!(
                    "tile {key} is coarser than level {coarsest}, the coarsest scatter '{}' builds (its level \
                     {level} less {COARSER_LEVELS}): it would hold too many instances",
                    self.id
                ),
            ));
        }
        let extent = grid.tile_extent(key);
        let mut reader = Reader::new(self, ctx, level);
        let mut tile = InstanceTile::default();
        // The class of each instance, for the counts.
        let mut classes: Vec<Option<i64>> = Vec::new();
        for (rule, lattice) in self.rules.iter().zip(&self.lattices) {
            let Some(lattice) = lattice else { continue };
            lattice.for_each(grid, &extent, |c| {
                if grid.key_at(key.level, c.x, c.y) != Some(key)
                    || reader.class_at(c.x, c.y)? != Some(rule.class)
                    || c.draws.unit(draw::ACCEPT) >= reader.density_at(c.x, c.y)?
                {
                    return Ok(());
                }
                let scale = rule.scale(c.draws.unit(draw::SCALE));
                let Some(z) = reader.anchor(c.x, c.y, self.anchor_radius_m * scale)? else { return Ok(()) };
                tile.instances.push(Instance {
                    feature_id: c.draws.feature_id(),
                    position: [c.x, c.y, z],
                    kind: InstanceKind::Model,
                    model: rule.model(c.draws.unit(draw::MODEL)).to_owned(),
                    scale,
                    rotation_deg: rule.rotation_deg(c.draws.unit(draw::ROTATION)),
                });
                classes.push(Some(rule.class));
                Ok::<(), SourceError>(())
            })?;
        }
        if let Some(n) = self.roles.points {
            self.place_points(key, ctx, n, &mut reader, &mut tile, &mut classes)?;
        }
        if key.level <= level {
            let counts = self.count(key, ctx, level, &tile, &classes)?;
            self.counts.replace(counts);
        }
        Ok(tile)
    }

    /// Each point the tile owns becomes an instance: the model of its
    /// `model` attribute, or one drawn by its class's rule shares; scale
    /// and rotation drawn from its class's rule (1 and any angle without).
    fn place_points(
        &self,
        key: TileKey,
        ctx: &GenerateContext<'_>,
        n: usize,
        reader: &mut Reader<'_, '_>,
        tile: &mut InstanceTile,
        classes: &mut Vec<Option<i64>>,
    ) -> Result<(), SourceError> {
        let input = ctx.inputs.tile(n, key).map_err(self.input_error(n))?;
        let Payload::Features(features) = input.as_ref() else {
            return Err(SourceError::Input {
                input: self.inputs[n].clone(),
                message: format!("the points input gives {} tiles, not features", input.kind()),
            });
        };
        for feature in &features.features {
            let Geometry::Points(points) = &feature.geometry else { continue };
            let attribute = feature.properties.get("model").map(|m| m.trim()).filter(|m| !m.is_empty());
            for (k, p) in points.iter().enumerate() {
                if ctx.grid.key_at(key.level, p[0], p[1]) != Some(key) {
                    continue;
                }
                let mut skip = |reason: String| {
                    tile.skipped.push(relief_source::Skipped { feature_id: feature.id, reason });
                };
                let class = reader.class_at(p[0], p[1])?;
                let rule = class.and_then(|c| self.rule_of(c));
                let draws = Draws(hash(&[self.seed, POINT_SALT, feature.id, k as u64]));
                let model = match (attribute, rule) {
                    (Some(m), _) if self.known_models.iter().any(|k| k == m) => m.to_owned(),
                    (Some(m), _) => {
                        skip(format!("model '{m}' is not known (known: {})", self.known_models.join(", ")));
                        continue;
                    }
                    (None, Some(rule)) => rule.model(draws.unit(draw::MODEL)).to_owned(),
                    (None, None) => {
                        let what =
                            class.map_or_else(|| "no class".to_owned(), |c| format!("class {c}, which has no rule"));
                        skip(format!("the point has no 'model' attribute and stands on {what}"));
                        continue;
                    }
                };
                let (scale, rotation_deg) = match rule {
                    Some(r) => (r.scale(draws.unit(draw::SCALE)), r.rotation_deg(draws.unit(draw::ROTATION))),
                    None => (1.0, draws.unit(draw::ROTATION) * 360.0),
                };
                let Some(z) = reader.anchor(p[0], p[1], self.anchor_radius_m * scale)? else {
                    skip("the ground has no data under the point".into());
                    continue;
                };
                tile.instances.push(Instance {
                    feature_id: feature.id,
                    position: [p[0], p[1], z],
                    kind: InstanceKind::Model,
                    model,
                    scale,
                    rotation_deg,
                });
                classes.push(class);
            }
        }
        Ok(())
    }

    /// The class counts of every tile of the scatter's level inside `key`
    /// (which is that level or coarser): the class samples each owns (its
    /// N x N samples without the east column and south row it shares) and
    /// the instances it owns.
    fn count(
        &self,
        key: TileKey,
        ctx: &GenerateContext<'_>,
        level: u8,
        tile: &InstanceTile,
        classes: &[Option<i64>],
    ) -> Result<Vec<(TileKey, TileCounts)>, SourceError> {
        let grid = ctx.grid;
        let side = 1u32 << (level - key.level);
        let mut out: BTreeMap<TileKey, TileCounts> = BTreeMap::new();
        for dy in 0..side {
            for dx in 0..side {
                let child = TileKey::new(level, key.x * side + dx, key.y * side + dy);
                let payload = ctx.inputs.tile(0, child).map_err(self.input_error(0))?;
                let Payload::Height(h) = payload.as_ref() else {
                    return Err(SourceError::Input {
                        input: self.inputs[0].clone(),
                        message: format!("the class raster gives {} tiles, not heights", payload.kind()),
                    });
                };
                let lattice = grid.lattice(child, relief_source::SampleKind::Corner);
                let owned = h.size.saturating_sub(1);
                let counts = out.entry(child).or_default();
                for j in 0..owned {
                    for i in 0..owned {
                        if let Some(class) = class_of(self, ctx, h.get(i, j), lattice.x(i), lattice.y(j))? {
                            counts.entry(class).or_default().samples += 1;
                        }
                    }
                }
            }
        }
        for (instance, class) in tile.instances.iter().zip(classes) {
            let [x, y, _] = instance.position;
            if let (Some(class), Some(owner)) = (class, grid.key_at(level, x, y))
                && let Some(counts) = out.get_mut(&owner)
            {
                counts.entry(*class).or_default().instances += 1;
            }
        }
        Ok(out.into_iter().collect())
    }
}
