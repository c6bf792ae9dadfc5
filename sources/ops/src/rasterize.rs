//! `rasterize`: features drawn into a colour layer, antialiased, anchored
//! in map space so edges meet across tiles.

use std::collections::{BTreeMap, HashSet};

use relief_source::colors::{by_value, kml_color, parse_color};

use relief_source::{
    ColorTile, DirtySet, Feature, GenerateContext, Geometry, GridKind, Lattice, Payload, PayloadKind, SampleKind,
    Source, SourceError, SourceInfo, SourceSpec, TileKey, geodesy,
};

pub const RASTERIZE_KIND: &str = "rasterize";
/// The payloads of a rasterizer's inputs, in order.
pub const RASTERIZE_INPUTS: &[PayloadKind] = &[PayloadKind::Features];

/// A line width, in texels of the level drawn or in metres on the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Width {
    Texels(f64),
    Metres(f64),
}

/// How features are drawn. Colours are straight (not premultiplied) RGBA
/// in 0..1.
#[derive(Debug, Clone, PartialEq)]
pub struct Style {
    pub fill: Option<[f64; 4]>,
    pub stroke: Option<[f64; 4]>,
    pub width: Width,
    /// Colour polygons by this attribute (a fixed palette, by value).
    pub color_by: Option<String>,
    /// Sub-samples per texel side (the `antialias` knob): 1 is aliased,
    /// 4 gives 16 coverage levels.
    pub antialias: u32,
}

impl Default for Style {
    fn default() -> Self {
        Self {
            fill: Some([0.85, 0.45, 0.2, 0.7]),
            stroke: Some([0.2, 0.2, 0.2, 1.0]),
            width: Width::Texels(1.0),
            color_by: None,
            antialias: 4,
        }
    }
}

#[derive(Debug)]
pub struct Rasterize {
    id: String,
    inputs: Vec<String>,
    style: Style,
}

impl Rasterize {
    pub fn open(spec: &SourceSpec) -> Result<Self, SourceError> {
        spec.only_options(&["fill", "stroke", "stroke_width_px", "stroke_width_m", "color_by", "antialias"])?;
        if spec.inputs.len() != 1 {
            return Err(SourceError::option("inputs", "rasterize takes one features input"));
        }
        let mut style = Style::default();
        if let Some(f) = spec.text("fill")? {
            style.fill = if f == "none" { None } else { Some(parse_color("fill", f)?) };
        }
        if let Some(s) = spec.text("stroke")? {
            style.stroke = if s == "none" { None } else { Some(parse_color("stroke", s)?) };
        }
        match (spec.number("stroke_width_px")?, spec.number("stroke_width_m")?) {
            (Some(_), Some(_)) => {
                return Err(SourceError::option("stroke_width_m", "give stroke_width_px or stroke_width_m, not both"));
            }
            (Some(px), None) if px >= 0.0 => style.width = Width::Texels(px),
            (None, Some(m)) if m >= 0.0 => style.width = Width::Metres(m),
            (None, None) => {}
            _ => return Err(SourceError::option("stroke_width_px", "widths are not negative")),
        }
        style.color_by = spec.text("color_by")?.map(str::to_owned);
        if let Some(a) = spec.number("antialias")? {
            if !(1.0..=16.0).contains(&a) || a.fract() != 0.0 {
                return Err(SourceError::option("antialias", format!("{a} is not a whole number from 1 to 16")));
            }
            style.antialias = a as u32;
        }
        Ok(Self { id: spec.id.clone(), inputs: spec.inputs.clone(), style })
    }
}

/// A polygon's rings, or a line, ready to draw, in grid coordinates.
enum Shape<'a> {
    Rings(Rings<'a>, [f64; 4]),
    Line(Vec<[f64; 2]>, &'a Feature),
}

/// A polygon's rings as drawn: the feature's own, read in place, or copies
/// unwrapped across the antimeridian.
type Rings<'a> = std::borrow::Cow<'a, [Vec<[f64; 3]>]>;

/// Every edge of every ring: x0, y0, x1, y1.
fn edges<'a>(rings: &'a Rings<'_>) -> impl Iterator<Item = [f64; 4]> + 'a {
    rings.iter().flat_map(|r| r.windows(2).map(|w| [w[0][0], w[0][1], w[1][0], w[1][1]]))
}

/// The box round the exterior ring: (west, south), (east, north).
fn exterior_box(rings: &Rings<'_>) -> ([f64; 2], [f64; 2]) {
    rings.first().map_or(&[][..], Vec::as_slice).iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
    })
}

/// On the geodetic grid a ring that jumps across the antimeridian is drawn
/// twice, unwrapped east and west, rather than smeared round the planet.
fn unwrapped(rings: &[Vec<[f64; 3]>], geodetic: bool) -> Vec<Rings<'_>> {
    // An edge along a pole from -180 to 180 closes a polar cap (Natural
    // Earth's Antarctica); it is not a crossing.
    let along_pole = |w: &[[f64; 3]]| w[0][1].abs() == 90.0 && w[1][1].abs() == 90.0;
    let crosses =
        geodetic && rings.iter().any(|r| r.windows(2).any(|w| (w[1][0] - w[0][0]).abs() > 180.0 && !along_pole(w)));
    if !crosses {
        return vec![Rings::Borrowed(rings)];
    }
    let shifted = |by: f64| -> Rings<'_> {
        Rings::Owned(
            rings
                .iter()
                .map(|r| r.iter().map(|p| [if p[0] < 0.0 { p[0] + 360.0 } else { p[0] } + by, p[1], p[2]]).collect())
                .collect(),
        )
    };
    vec![shifted(0.0), shifted(-360.0)]
}

/// Adds the sub-samples `start..end` of one sub-row (`ss` to a texel) to
/// `row`: the partial texels at either end at once, the whole texels
/// between as differences in `runs` for `sum_runs`.
fn add_run(row: &mut [u32], runs: &mut [i32], start: usize, end: usize, ss: usize) {
    if start >= end {
        return;
    }
    let (first, last) = (start / ss, end / ss);
    if first == last {
        row[first] += (end - start) as u32;
        return;
    }
    row[first] += ((first + 1) * ss - start) as u32;
    runs[first + 1] += ss as i32;
    runs[last] -= ss as i32;
    if !end.is_multiple_of(ss) {
        row[last] += (end - last * ss) as u32;
    }
}

/// Adds the whole texels `add_run` noted to `row`, and clears the notes.
fn sum_runs(row: &mut [u32], runs: &mut [i32]) {
    let mut level = 0i32;
    for (texel, d) in row.iter_mut().zip(runs.iter_mut()) {
        level += *d;
        *d = 0;
        *texel = (*texel as i32 + level) as u32;
    }
    runs[row.len()] = 0;
}

/// A thread's composite and coverage buffers, kept from tile to tile: a
/// fresh 2 MB allocation per tile cost more in page faults than drawing.
#[derive(Default)]
struct Scratch {
    premul: Vec<[f64; 4]>,
    coverage: Vec<u32>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Draws `features` on `lattice` (texel centres, border included): RGBA8.
pub fn render(features: &[&Feature], lattice: &Lattice, geodetic: bool, style: &Style) -> Vec<u8> {
    SCRATCH.with_borrow_mut(|scratch| render_with(features, lattice, geodetic, style, scratch))
}

fn render_with(
    features: &[&Feature],
    lattice: &Lattice,
    geodetic: bool,
    style: &Style,
    scratch: &mut Scratch,
) -> Vec<u8> {
    let (cols, rows) = (lattice.cols, lattice.rows);
    let ss = style.antialias.max(1) as usize;
    let off: Vec<f64> = (0..ss).map(|s| (s as f64 + 0.5) / ss as f64 - 0.5).collect();
    let Scratch { premul, coverage } = scratch;
    // Both are all zero between tiles (only what a tile touched is
    // cleared after it): a mostly empty tile costs little.
    if premul.len() != cols * rows {
        *premul = vec![[0.0; 4]; cols * rows];
        *coverage = vec![0; cols * rows];
    }
    // The texels any shape touched.
    let (mut drawn_rows, mut drawn_columns) = (rows..0, cols..0);
    let fill_of = |f: &Feature| -> Option<[f64; 4]> {
        if let Some(attr) = &style.color_by {
            let c = by_value(f.properties.get(attr)?);
            return Some([c[0], c[1], c[2], 0.7]);
        }
        f.properties.get("fill_color").and_then(|c| kml_color(c)).or(style.fill)
    };
    // The texels' own area: border texels included, half a texel out.
    let bounds = relief_source::Extent::new(
        lattice.x(0) - lattice.step_x / 2.0,
        lattice.y(rows - 1) - lattice.step_y / 2.0,
        lattice.x(cols - 1) + lattice.step_x / 2.0,
        lattice.y(0) + lattice.step_y / 2.0,
    );
    let mut shapes = Vec::new();
    for &f in features {
        match &f.geometry {
            Geometry::Polygons(polys) => {
                if let Some(color) = fill_of(f) {
                    for rings in polys {
                        // A polygon wholly beside the tile (west included: all
                        // its crossings pair up west of every texel) covers nothing.
                        for version in unwrapped(rings, geodetic) {
                            let (lo, hi) = exterior_box(&version);
                            if hi[0] >= bounds.min_x
                                && lo[0] <= bounds.max_x
                                && hi[1] >= bounds.min_y
                                && lo[1] <= bounds.max_y
                            {
                                shapes.push(Shape::Rings(version, color));
                            }
                        }
                    }
                }
                if style.stroke.is_some() {
                    for ring in polys.iter().flatten() {
                        shapes.push(Shape::Line(ring.iter().map(|p| [p[0], p[1]]).collect(), f));
                    }
                }
            }
            Geometry::Lines(lines) => {
                for l in lines {
                    shapes.push(Shape::Line(l.iter().map(|p| [p[0], p[1]]).collect(), f));
                }
            }
            Geometry::Points(_) => {}
        }
    }
    let over = |dst: &mut [f64; 4], color: [f64; 4], coverage: f64| {
        let a = color[3] * coverage;
        for k in 0..3 {
            dst[k] = color[k] * a + dst[k] * (1.0 - a);
        }
        dst[3] = a + dst[3] * (1.0 - a);
    };
    // One coverage buffer for every shape; only the rows and columns a
    // shape touched are composited and cleared (a tile at level 0 holds
    // hundreds of shapes).
    // Whole texels covered by runs, as differences along the row (summed
    // once a row's sub-rows are done): a run costs the same whatever its
    // length.
    let mut runs = vec![0i32; cols + 1];
    let full = (ss * ss) as f64;
    let mut flush = |coverage: &mut [u32],
                     rows_touched: std::ops::Range<usize>,
                     columns: std::ops::Range<usize>,
                     color: [f64; 4]| {
        if rows_touched.is_empty() || columns.is_empty() {
            return;
        }
        drawn_rows = drawn_rows.start.min(rows_touched.start)..drawn_rows.end.max(rows_touched.end);
        drawn_columns = drawn_columns.start.min(columns.start)..drawn_columns.end.max(columns.end);
        for j in rows_touched {
            let span = j * cols + columns.start..j * cols + columns.end;
            for (dst, c) in premul[span.clone()].iter_mut().zip(&mut coverage[span]) {
                if *c > 0 {
                    over(dst, color, f64::from(*c) / full);
                    *c = 0;
                }
            }
        }
    };
    // Fills: even-odd crossings along each sub-row, sweeping north to
    // south with only the edges that span the row (an active edge list).
    for shape in &shapes {
        let Shape::Rings(rings, color) = shape else { continue };
        // Only edges that span one of this tile's rows and reach its west of
        // its east edge can change a crossing count here.
        let (top, bottom) = (lattice.y(0) + lattice.step_y / 2.0, lattice.y(rows - 1) - lattice.step_y / 2.0);
        let east = lattice.x(cols - 1) + lattice.step_x / 2.0;
        let mut edges: Vec<[f64; 4]> = edges(rings)
            .filter(|e| e[1] != e[3] && e[1].max(e[3]) >= bottom && e[1].min(e[3]) <= top && e[0].min(e[2]) <= east)
            .collect();
        if edges.is_empty() {
            continue;
        }
        // By their northern end, northernmost first.
        edges.sort_by(|a, b| b[1].max(b[3]).total_cmp(&a[1].max(a[3])));
        let mut next = 0;
        let mut active: Vec<[f64; 4]> = Vec::new();
        let mut xs: Vec<f64> = Vec::new();
        let (mut touched, mut columns) = (rows..0, cols..0);
        // Sub-sample s of a row sits at x(0) + ((s + 0.5) / ss - 0.5) * step:
        // the first one at or east of x.
        let first_at_or_after = |x: f64| {
            ((((x - lattice.x(0)) / lattice.step_x + 0.5) * ss as f64 - 0.5).ceil().max(0.0) as usize).min(cols * ss)
        };
        // From the row above the shape's northernmost point; done once
        // every edge has been passed.
        let north = edges[0][1].max(edges[0][3]);
        let first_row = ((lattice.y(0) - north) / lattice.step_y - 1.0).floor().clamp(0.0, rows as f64) as usize;
        for j in first_row..rows {
            if next == edges.len() && active.is_empty() {
                break;
            }
            let mut runs_open = false;
            for oy in &off {
                let y = lattice.y(j) - oy * lattice.step_y;
                while next < edges.len() && edges[next][1].max(edges[next][3]) >= y {
                    active.push(edges[next]);
                    next += 1;
                }
                active.retain(|e| e[1].min(e[3]) <= y);
                if active.is_empty() {
                    continue;
                }
                runs_open = true;
                touched = touched.start.min(j)..touched.end.max(j + 1);
                xs.clear();
                for &[x0, y0, x1, y1] in &active {
                    if (y0 <= y) != (y1 <= y) {
                        xs.push(x0 + (y - y0) / (y1 - y0) * (x1 - x0));
                    }
                }
                xs.sort_by(f64::total_cmp);
                // Even-odd: sub-samples in [x_2k, x_2k+1) are inside; add
                // whole runs of them to their texels. Edges wholly east of
                // the tile were dropped: a run left open at the end reaches
                // past the east edge.
                let row = &mut coverage[j * cols..(j + 1) * cols];
                for pair in xs.chunks(2) {
                    let start = first_at_or_after(pair[0]);
                    let end = pair.get(1).map_or(cols * ss, |&x| first_at_or_after(x));
                    if start < end {
                        columns = columns.start.min(start / ss)..columns.end.max((end - 1) / ss + 1);
                    }
                    add_run(row, &mut runs, start, end, ss);
                }
            }
            if runs_open {
                sum_runs(&mut coverage[j * cols..(j + 1) * cols], &mut runs);
            }
        }
        flush(coverage, touched, columns, *color);
    }
    // Strokes: sub-samples within half the width of a segment.
    if let Some(stroke) = style.stroke {
        for shape in &shapes {
            let Shape::Line(line, f) = shape else { continue };
            let color = f.properties.get("line_color").and_then(|c| kml_color(c)).unwrap_or(stroke);
            let width = f.properties.get("line_width").and_then(|w| w.parse().ok()).map_or(style.width, Width::Texels);
            // Distances measured in texels (or metres) along each axis.
            let scale = |lat: f64| match width {
                Width::Texels(w) => (1.0 / lattice.step_x, 1.0 / lattice.step_y, w / 2.0),
                Width::Metres(w) if geodetic => {
                    let m = geodesy::MEAN_RADIUS_M.to_radians();
                    (m * lat.to_radians().cos().abs(), m, w / 2.0)
                }
                Width::Metres(w) => (1.0, 1.0, w / 2.0),
            };
            let mut touched = rows..0;
            for seg in line.windows(2) {
                let ([x0, y0], [x1, y1]) = (seg[0], seg[1]);
                if geodetic && (x1 - x0).abs() > 180.0 {
                    continue;
                }
                let (sx, sy, half) = scale(f64::midpoint(y0, y1));
                let (rx, ry) = (half / sx, half / sy);
                let (lo_x, hi_x) = (x0.min(x1) - rx, x0.max(x1) + rx);
                let (lo_y, hi_y) = (y0.min(y1) - ry, y0.max(y1) + ry);
                let i0 = ((lo_x - lattice.x(0)) / lattice.step_x).floor().max(0.0) as usize;
                let i1 = (((hi_x - lattice.x(0)) / lattice.step_x).ceil().max(0.0) as usize + 1).min(cols);
                let j0 = ((lattice.y(0) - hi_y) / lattice.step_y).floor().max(0.0) as usize;
                let j1 = (((lattice.y(0) - lo_y) / lattice.step_y).ceil().max(0.0) as usize + 1).min(rows);
                if j0 < j1 && i0 < i1 {
                    touched = touched.start.min(j0)..touched.end.max(j1);
                }
                let (dx, dy) = ((x1 - x0) * sx, (y1 - y0) * sy);
                let len2 = dx * dx + dy * dy;
                for j in j0..j1 {
                    for i in i0..i1 {
                        let mut n = 0;
                        for oy in &off {
                            for ox in &off {
                                let (px, py) = (
                                    (lattice.x(i) + ox * lattice.step_x - x0) * sx,
                                    (lattice.y(j) - oy * lattice.step_y - y0) * sy,
                                );
                                let t = if len2 > 0.0 { ((px * dx + py * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
                                let (ex, ey) = (px - t * dx, py - t * dy);
                                if ex * ex + ey * ey <= half * half {
                                    n += 1;
                                }
                            }
                        }
                        let c = &mut coverage[j * cols + i];
                        *c = (*c).max(n);
                    }
                }
            }
            flush(coverage, touched, 0..cols, color);
        }
    }
    let mut rgba = vec![0u8; cols * rows * 4];
    // Un-premultiplied by one reciprocal, rounded to the nearest byte by
    // + 0.5 and the saturating cast (cheaper than `round`, the same for
    // these non-negative values).
    let byte = |v: f64| (v + 0.5) as u8;
    for j in drawn_rows {
        for i in drawn_columns.clone() {
            let k = j * cols + i;
            let p = std::mem::take(&mut premul[k]);
            let a = p[3];
            if a > 0.0 {
                let scale = 255.0 / a;
                rgba[4 * k..4 * k + 4].copy_from_slice(&[
                    byte(p[0] * scale),
                    byte(p[1] * scale),
                    byte(p[2] * scale),
                    byte(a * 255.0),
                ]);
            }
        }
    }
    rgba
}

impl Source for Rasterize {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        RASTERIZE_KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Color
    }

    fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn info(&self) -> SourceInfo {
        let mut details = BTreeMap::new();
        details.insert("antialias".into(), self.style.antialias.to_string());
        details.insert("stroke_width".into(), format!("{:?}", self.style.width));
        SourceInfo { details, ..SourceInfo::default() }
    }

    /// The features of this tile and its neighbours (a stroke or a border
    /// texel can reach across the edge), drawn on the tile's texels.
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let grid = ctx.grid;
        let lattice = grid.lattice(key, SampleKind::TexelWithBorder);
        let margin = match self.style.width {
            Width::Texels(w) => (w / 2.0 + 2.0) * lattice.step_x.max(lattice.step_y),
            Width::Metres(w) => w / 2.0 / 30_000.0 + 2.0 * lattice.step_x.max(lattice.step_y),
        };
        let reach = grid.tile_extent(key).dilate(margin, margin);
        let tiles = grid
            .keys_overlapping(key.level, &reach)
            .into_iter()
            .map(|k| ctx.inputs.tile(0, k))
            .collect::<Result<Vec<_>, _>>()?;
        let mut seen = HashSet::new();
        let mut features: Vec<&Feature> = Vec::new();
        for tile in &tiles {
            let Payload::Features(tile) = tile.as_ref() else {
                return Err(SourceError::Input {
                    input: self.inputs[0].clone(),
                    message: "expected feature tiles".into(),
                });
            };
            for f in &tile.features {
                if seen.insert((f.id, std::mem::discriminant(&f.geometry))) {
                    features.push(f);
                }
            }
        }
        let geodetic = matches!(grid.kind, GridKind::Geodetic);
        Ok(Payload::Color(ColorTile { size: lattice.cols, rgba: render(&features, &lattice, geodetic, &self.style) }))
    }

    /// A texel reads features up to a stroke's half width away, and the
    /// border texel one texel past the tile.
    fn dirty_from_input(&self, _input: usize, dirt: &DirtySet) -> DirtySet {
        let texels = match self.style.width {
            Width::Texels(w) => (w / 2.0).ceil() as u32 + 2,
            Width::Metres(_) => 8,
        };
        dirt.dilate_samples(texels)
    }
}

#[cfg(test)]
mod tests {
    use relief_source::{TileGrid, TileKey};

    use super::*;

    fn square(id: u64, x0: f64, y0: f64, x1: f64, y1: f64) -> Feature {
        let ring = vec![[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0], [x0, y0, 0.0]];
        Feature { id, geometry: Geometry::Polygons(vec![vec![ring]]), properties: BTreeMap::new() }
    }

    fn line(id: u64, points: &[[f64; 2]]) -> Feature {
        Feature {
            id,
            geometry: Geometry::Lines(vec![points.iter().map(|p| [p[0], p[1], 0.0]).collect()]),
            properties: BTreeMap::new(),
        }
    }

    #[test]
    fn tiles_meet_at_their_seams_exactly() {
        // A polygon and a diagonal line across the corner of four tiles.
        let grid = TileGrid::geodetic(64).unwrap();
        let corner = grid.tile_extent(TileKey::new(6, 100, 20));
        let (cx, cy) = (corner.max_x, corner.min_y);
        let features =
            [square(1, cx - 0.7, cy - 0.5, cx + 0.4, cy + 0.9), line(2, &[[cx - 1.0, cy - 1.1], [cx + 1.2, cy + 0.8]])];
        let style = Style::default();
        let draw = |x, y| {
            render(
                &features.iter().collect::<Vec<_>>(),
                &grid.lattice(TileKey::new(6, x, y), SampleKind::TexelWithBorder),
                true,
                &style,
            )
        };
        let (nw, ne, sw) = (draw(100, 20), draw(101, 20), draw(100, 21));
        let px = |t: &[u8], i: usize, j: usize| t[(j * 66 + i) * 4..(j * 66 + i) * 4 + 4].to_vec();
        for j in 0..66 {
            // East border of nw == first core column of ne, and back.
            assert_eq!(px(&nw, 65, j), px(&ne, 1, j), "row {j}");
            assert_eq!(px(&nw, 64, j), px(&ne, 0, j), "row {j}");
        }
        for i in 0..66 {
            assert_eq!(px(&nw, i, 65), px(&sw, i, 1), "column {i}");
        }
        // The seam is really crossed: something drawn on both sides.
        assert!((0..66).any(|j| px(&nw, 64, j)[3] > 0) && (0..66).any(|j| px(&ne, 1, j)[3] > 0));
        // The four tiles stitched equal one raster of the whole extent: the
        // level above with tiles twice as wide has the very same texels.
        let whole_grid = TileGrid::geodetic(128).unwrap();
        let whole = render(
            &features.iter().collect::<Vec<_>>(),
            &whole_grid.lattice(TileKey::new(5, 50, 10), SampleKind::TexelWithBorder),
            true,
            &style,
        );
        let se = draw(101, 21);
        for (tile, (ox, oy)) in [(&nw, (0, 0)), (&ne, (64, 0)), (&sw, (0, 64)), (&se, (64, 64))] {
            for j in 1..65 {
                for i in 1..65 {
                    assert_eq!(
                        px(tile, i, j),
                        whole[((oy + j) * 130 + ox + i) * 4..((oy + j) * 130 + ox + i) * 4 + 4].to_vec(),
                        "texel {i},{j} of the tile at +{ox},+{oy}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_ring_across_the_antimeridian_is_not_smeared_round_the_planet() {
        let grid = TileGrid::geodetic(64).unwrap();
        let ring = vec![
            [179.0, -17.0, 0.0],
            [-179.0, -17.0, 0.0],
            [-179.0, -16.0, 0.0],
            [179.0, -16.0, 0.0],
            [179.0, -17.0, 0.0],
        ];
        let f = Feature { id: 1, geometry: Geometry::Polygons(vec![vec![ring]]), properties: BTreeMap::new() };
        let style = Style { stroke: None, ..Style::default() };
        let level = 3;
        let (cols, _) = grid.tiles_at(level);
        let row = grid.key_at(level, 0.0, -16.5).unwrap().y;
        let covered = |x: u32| {
            render(&[&f], &grid.lattice(TileKey::new(level, x, row), SampleKind::TexelWithBorder), true, &style)
                .chunks(4)
                .any(|p| p[3] > 0)
        };
        assert!(covered(0) && covered(cols - 1), "both ends of the date line");
        assert!((1..cols - 1).all(|x| !covered(x)), "nothing in between");
    }

    #[test]
    fn a_polar_cap_closed_along_the_pole_covers_every_longitude() {
        // Antarctica as Natural Earth draws it: the ring returns along -90.
        let grid = TileGrid::geodetic(64).unwrap();
        let ring = vec![
            [-180.0, -90.0, 0.0],
            [-180.0, -80.0, 0.0],
            [0.0, -75.0, 0.0],
            [180.0, -80.0, 0.0],
            [180.0, -90.0, 0.0],
            [-180.0, -90.0, 0.0],
        ];
        let f = Feature { id: 1, geometry: Geometry::Polygons(vec![vec![ring]]), properties: BTreeMap::new() };
        let style = Style { stroke: None, ..Style::default() };
        let (cols, rows) = grid.tiles_at(2);
        for x in 0..cols {
            let rgba =
                render(&[&f], &grid.lattice(TileKey::new(2, x, rows - 1), SampleKind::TexelWithBorder), true, &style);
            assert!((1..65).all(|i| rgba[(64 * 66 + i) * 4 + 3] > 0), "tile {x}: gap at the pole");
        }
    }

    proptest::proptest! {
        /// Runs added as partial texels and differences give what adding
        /// every sub-sample to its texel gives.
        #[test]
        fn runs_add_up_as_their_sub_samples(ss in 1usize..9, runs in proptest::collection::vec((0usize..80, 0usize..80), 0..12)) {
            let cols = 10;
            let (mut fast, mut notes, mut slow) = (vec![0u32; cols], vec![0i32; cols + 1], vec![0u32; cols]);
            for (a, b) in runs {
                let (start, end) = (a.min(b).min(cols * ss), a.max(b).min(cols * ss));
                add_run(&mut fast, &mut notes, start, end, ss);
                for s in start..end {
                    slow[s / ss] += 1;
                }
            }
            sum_runs(&mut fast, &mut notes);
            proptest::prop_assert_eq!(fast, slow);
            proptest::prop_assert!(notes.iter().all(|d| *d == 0));
        }
    }

    #[test]
    fn holes_stay_empty_and_antialiasing_grades_edges() {
        let grid = TileGrid::geodetic(64).unwrap();
        let key = TileKey::new(8, 300, 60);
        let t = grid.tile_extent(key);
        let (w, h) = (t.width(), t.height());
        let outer = vec![
            [t.min_x + 0.1 * w, t.min_y + 0.1 * h, 0.0],
            [t.max_x - 0.1 * w, t.min_y + 0.1 * h, 0.0],
            [t.max_x - 0.1 * w, t.max_y - 0.1 * h, 0.0],
            [t.min_x + 0.1 * w, t.max_y - 0.1 * h, 0.0],
            [t.min_x + 0.1 * w, t.min_y + 0.1 * h, 0.0],
        ];
        let hole = vec![
            [t.min_x + 0.4 * w, t.min_y + 0.4 * h, 0.0],
            [t.min_x + 0.6 * w, t.min_y + 0.4 * h, 0.0],
            [t.min_x + 0.6 * w, t.min_y + 0.6 * h, 0.0],
            [t.min_x + 0.4 * w, t.min_y + 0.6 * h, 0.0],
            [t.min_x + 0.4 * w, t.min_y + 0.4 * h, 0.0],
        ];
        let f = Feature { id: 1, geometry: Geometry::Polygons(vec![vec![outer, hole]]), properties: BTreeMap::new() };
        let style = Style { stroke: None, fill: Some([1.0, 0.0, 0.0, 1.0]), ..Style::default() };
        let rgba = render(&[&f], &grid.lattice(key, SampleKind::TexelWithBorder), true, &style);
        let alpha = |i: usize, j: usize| rgba[(j * 66 + i) * 4 + 3];
        assert_eq!(alpha(33, 33), 0, "the hole");
        assert_eq!(alpha(15, 15), 255, "inside");
        assert_eq!(alpha(2, 2), 0, "outside");
        assert!((0..66).any(|i| (1..255).contains(&alpha(i, 33))), "graded edge texels");
    }
}
