//! `hillshade`: a grey shaded-relief colour layer from a height source.

use relief_source::{
    ColorTile, DirtySet, GenerateContext, GridKind, Payload, PayloadKind, SampleKind, Source, SourceError, SourceInfo,
    SourceSpec, TileKey, geodesy,
};

use crate::window::HeightWindow;

pub const HILLSHADE_KIND: &str = "hillshade";
/// The payloads of a hillshade's inputs, in order.
pub const HILLSHADE_INPUTS: &[PayloadKind] = &[PayloadKind::Height];

#[derive(Debug)]
pub struct Hillshade {
    id: String,
    inputs: Vec<String>,
    azimuth_deg: f64,
    altitude_deg: f64,
    z_factor: f64,
}

impl Hillshade {
    pub fn open(spec: &SourceSpec) -> Result<Self, SourceError> {
        spec.only_options(&["azimuth_deg", "altitude_deg", "z_factor"])?;
        if spec.inputs.len() != 1 {
            return Err(SourceError::option(
                "inputs",
                format!("hillshade takes one height input, got {}", spec.inputs.len()),
            ));
        }
        if !spec.paths.is_empty() {
            return Err(SourceError::option("path", "hillshade reads no files: give it 'inputs'"));
        }
        let altitude_deg = spec.number("altitude_deg")?.unwrap_or(45.0);
        if !(0.0..=90.0).contains(&altitude_deg) {
            return Err(SourceError::option("altitude_deg", format!("{altitude_deg} is not between 0 and 90")));
        }
        Ok(Self {
            id: spec.id.clone(),
            inputs: spec.inputs.clone(),
            azimuth_deg: spec.number("azimuth_deg")?.unwrap_or(315.0),
            altitude_deg,
            z_factor: spec.number("z_factor")?.unwrap_or(1.0),
        })
    }
}

impl Source for Hillshade {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        HILLSHADE_KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Color
    }

    fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn info(&self) -> SourceInfo {
        let mut info = SourceInfo::default();
        info.details.insert("azimuth_deg".into(), self.azimuth_deg.to_string());
        info.details.insert("altitude_deg".into(), self.altitude_deg.to_string());
        info.details.insert("z_factor".into(), self.z_factor.to_string());
        info
    }

    /// Each texel is shaded from the four height samples at its corners.
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let grid = ctx.grid;
        let n = i64::from(grid.tile_size());
        let lattice = grid.lattice(key, SampleKind::TexelWithBorder);
        let mut window = HeightWindow::new(ctx, 0, key.level);
        let (x0, y0) = (i64::from(key.x) * n, i64::from(key.y) * n);
        let (az, alt) = (self.azimuth_deg.to_radians(), self.altitude_deg.to_radians());
        let light = [az.sin() * alt.cos(), az.cos() * alt.cos(), alt.sin()];
        let (step_x_m, step_y_m) = match grid.kind {
            GridKind::Geodetic => {
                let m_per_deg = geodesy::MEAN_RADIUS_M.to_radians();
                (lattice.step_x * m_per_deg, lattice.step_y * m_per_deg)
            }
            GridKind::Projected(_) => (lattice.step_x, lattice.step_y),
        };
        // Corner samples: columns x0-1 ..= x0+n+1, rows likewise.
        let side = (n + 3) as usize;
        let mut corners = Vec::with_capacity(side * side);
        for gy in (y0 - 1)..=(y0 + n + 1) {
            for gx in (x0 - 1)..=(x0 + n + 1) {
                corners.push(window.get(gx, gy)?);
            }
        }
        let mut rgba = Vec::with_capacity(lattice.cols * lattice.rows * 4);
        for j in 0..lattice.rows {
            let cos_lat = match grid.kind {
                GridKind::Geodetic => lattice.y(j).to_radians().cos().abs().max(1e-6),
                GridKind::Projected(_) => 1.0,
            };
            let dx = step_x_m * cos_lat;
            for i in 0..lattice.cols {
                let c = |di: usize, dj: usize| f64::from(corners[(j + dj) * side + i + di]);
                let (nw, ne, sw, se) = (c(0, 0), c(1, 0), c(0, 1), c(1, 1));
                if [nw, ne, sw, se].iter().any(|h| h.is_nan()) {
                    rgba.extend([0, 0, 0, 0]);
                    continue;
                }
                let dzdx = (ne + se - nw - sw) / (2.0 * dx) * self.z_factor;
                let dzdy = (nw + ne - sw - se) / (2.0 * step_y_m) * self.z_factor;
                let normal = [-dzdx, -dzdy, 1.0];
                let len = (normal[0] * normal[0] + normal[1] * normal[1] + 1.0).sqrt();
                let shade = ((normal[0] * light[0] + normal[1] * light[1] + normal[2] * light[2]) / len).max(0.0);
                let v = (shade * 255.0).round() as u8;
                rgba.extend([v, v, v, 255]);
            }
        }
        Ok(Payload::Color(ColorTile { size: lattice.cols, rgba }))
    }

    /// A texel reads the samples at its corners, and the border texel one
    /// sample past the tile: one sample of margin.
    fn dirty_from_input(&self, _input: usize, dirt: &DirtySet) -> DirtySet {
        dirt.dilate_samples(1)
    }
}
