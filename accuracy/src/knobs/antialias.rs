//! The `rasterize` op's `antialias`: sub-samples per texel side. Polygons
//! of known geometry (two 512-gon circles, two thin rotated rectangles,
//! two stars) written as GeoJSON, read by an `ogr` source and drawn by
//! `rasterize` sources that differ only in `antialias`; each texel's alpha
//! compared with the exact fraction of it the polygons cover, found by
//! clipping them against the texel's square in f64.

use std::fmt::Write as _;

use relief_examples::write_manifest;
use relief_source::{Payload, Quality, TileKey};

use super::data::{ErrorStats, NO_DISK_CACHE, forget, source_index, timed_tile};
use super::{Context, median};
use crate::sweep::{Row, Sweep};

const SETTINGS: [u32; 5] = [1, 2, 4, 8, 16];
/// The op's default (`Style::default().antialias`).
const DEFAULT: u32 = 4;
const ROUNDS: usize = 9;
/// The block drawn: 2 x 2 tiles of level 10 from this one (north-west).
const LEVEL: u8 = 10;
const FIRST: (u32, u32) = (1080, 256);

/// A polygon in texel units of the block: x east, y south from its
/// north-west corner.
type Polygon = Vec<[f64; 2]>;

fn circle(cx: f64, cy: f64, r: f64, n: usize) -> Polygon {
    (0..n)
        .map(|k| {
            let (s, c) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
            [cx + r * c, cy + r * s]
        })
        .collect()
}

fn rectangle(cx: f64, cy: f64, length: f64, width: f64, angle_deg: f64) -> Polygon {
    let (s, c) = angle_deg.to_radians().sin_cos();
    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(a, b): &(f64, f64)| {
            let (u, v) = (a * length / 2.0, b * width / 2.0);
            [cx + u * c - v * s, cy + u * s + v * c]
        })
        .collect()
}

/// A simple (not self-crossing) star of `points` points.
fn star(cx: f64, cy: f64, outer: f64, inner: f64, points: usize, angle_deg: f64) -> Polygon {
    (0..2 * points)
        .map(|k| {
            let r = if k % 2 == 0 { outer } else { inner };
            let (s, c) = (angle_deg.to_radians() + std::f64::consts::PI * k as f64 / points as f64).sin_cos();
            [cx + r * c, cy + r * s]
        })
        .collect()
}

/// The shapes, disjoint (so a texel's coverage is one shape's), one across
/// the corner where the four tiles meet.
fn shapes() -> Vec<Polygon> {
    vec![
        circle(256.3, 255.7, 40.2, 512),
        circle(100.37, 400.81, 6.3, 512),
        rectangle(380.2, 120.45, 150.0, 0.7, 17.0),
        rectangle(120.8, 130.1, 90.0, 3.3, 61.0),
        star(400.55, 390.3, 45.0, 18.0, 5, 7.0),
        star(160.1, 260.9, 30.0, 12.0, 5, 33.0),
    ]
}

/// The area of `polygon` inside the square [x0, x0 + 1] x [y0, y0 + 1]:
/// Sutherland-Hodgman against the square's four sides, then the shoelace.
fn area_in_square(polygon: &[[f64; 2]], x0: f64, y0: f64) -> f64 {
    let mut ring: Vec<[f64; 2]> = polygon.to_vec();
    // Each side as (axis, bound, keep the side above the bound).
    for (axis, bound, above) in [(0, x0, true), (0, x0 + 1.0, false), (1, y0, true), (1, y0 + 1.0, false)] {
        if ring.is_empty() {
            return 0.0;
        }
        let inside = |p: &[f64; 2]| if above { p[axis] >= bound } else { p[axis] <= bound };
        let mut out = Vec::with_capacity(ring.len() + 4);
        for k in 0..ring.len() {
            let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
            let (ia, ib) = (inside(&a), inside(&b));
            if ia {
                out.push(a);
            }
            if ia != ib {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        ring = out;
    }
    let twice: f64 = (0..ring.len())
        .map(|k| {
            let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice.abs() / 2.0
}

/// Exact coverage of the core texels of the block's tile (tx, ty) (0 or
/// 1 each), `n` x `n`, row-major from the north-west.
fn exact_coverage(shapes: &[Polygon], tx: usize, ty: usize, n: usize) -> Vec<f64> {
    let mut cover = vec![0.0; n * n];
    let (ox, oy) = ((tx * n) as f64, (ty * n) as f64);
    for shape in shapes {
        let (lo, hi) = shape.iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
            ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
        });
        let i0 = (lo[0] - ox).floor().clamp(0.0, n as f64) as usize;
        let i1 = (hi[0] - ox).ceil().clamp(0.0, n as f64) as usize;
        let j0 = (lo[1] - oy).floor().clamp(0.0, n as f64) as usize;
        let j1 = (hi[1] - oy).ceil().clamp(0.0, n as f64) as usize;
        for j in j0..j1 {
            for i in i0..i1 {
                cover[j * n + i] += area_in_square(shape, ox + i as f64, oy + j as f64);
            }
        }
    }
    cover
}

/// Points of the block as GeoJSON coordinates in degrees.
fn coordinates(points: &[[f64; 2]], west: f64, north: f64, step: f64) -> String {
    let pairs: Vec<String> =
        points.iter().map(|p| format!("[{}, {}]", west + p[0] * step, north - p[1] * step)).collect();
    format!("[{}]", pairs.join(", "))
}

/// Polygons (closed here) or lines as a GeoJSON FeatureCollection in degrees.
fn geojson(parts: &[Polygon], lines: bool, west: f64, north: f64, step: f64) -> String {
    let features: Vec<String> = parts
        .iter()
        .enumerate()
        .map(|(id, part)| {
            let geometry = if lines {
                format!(r#"{{"type": "LineString", "coordinates": {}}}"#, coordinates(part, west, north, step))
            } else {
                let ring: Vec<[f64; 2]> = part.iter().chain(part.first()).copied().collect();
                format!(r#"{{"type": "Polygon", "coordinates": [{}]}}"#, coordinates(&ring, west, north, step))
            };
            format!(r#"{{"type": "Feature", "properties": {{"part": {id}}}, "geometry": {geometry}}}"#)
        })
        .collect();
    format!("{{\"type\": \"FeatureCollection\", \"features\": [\n{}\n]}}\n", features.join(",\n"))
}

/// Straight lines across the block, 2 to 84 degrees from east, 100 to
/// 230 texels long, well apart.
fn lines() -> Vec<Polygon> {
    vec![
        vec![[30.3, 40.7], [230.9, 50.2]],
        vec![[300.1, 30.4], [480.6, 134.6]],
        vec![[60.2, 300.5], [200.8, 441.1]],
        vec![[350.3, 250.9], [372.4, 480.2]],
    ]
}

/// What a line `width` texels wide covers: the segment swept by a disc
/// (its ends round, as the op draws them), as a polygon of 2 x 256 points
/// on the round ends.
fn capsule(a: [f64; 2], b: [f64; 2], width: f64) -> Polygon {
    let r = width / 2.0;
    let along = (b[1] - a[1]).atan2(b[0] - a[0]);
    let mut out = Vec::with_capacity(2 * 257);
    for (centre, start) in [(b, along - std::f64::consts::FRAC_PI_2), (a, along + std::f64::consts::FRAC_PI_2)] {
        for k in 0..=256 {
            let (s, c) = (start + std::f64::consts::PI * f64::from(k) / 256.0).sin_cos();
            out.push([centre[0] + r * c, centre[1] + r * s]);
        }
    }
    out
}

/// One case: what is written, how it is drawn, and what it covers exactly.
struct Case {
    name: &'static str,
    sentence: &'static str,
    /// Polygons, or lines when `lines`.
    parts: Vec<Polygon>,
    lines: bool,
    /// The `rasterize` options besides `antialias`.
    style: &'static str,
    /// The area each part covers exactly, as polygons.
    covered: Vec<Polygon>,
}

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let fills = Case {
        name: "antialias (rasterize, fills)",
        sentence: "Six polygons (two 512-vertex circles, radius 40 and 6 texels; rectangles 0.7 and 3.3 texels wide \
                   turned 17 and 61 degrees; two five-pointed stars), one across the corner of four tiles, drawn \
                   by `rasterize` as opaque fills without strokes",
        parts: shapes(),
        lines: false,
        style: "fill = \"#ffffffff\"\nstroke = \"none\"",
        covered: shapes(),
    };
    let strokes = Case {
        name: "antialias (rasterize, 1 px lines)",
        sentence: "Four straight lines 100 to 230 texels long, 2 to 84 degrees from east, drawn by `rasterize` as \
                   opaque strokes 1 texel wide (the default width)",
        parts: lines(),
        lines: true,
        style: "fill = \"none\"\nstroke = \"#ffffffff\"\nstroke_width_px = 1",
        covered: lines().iter().map(|l| capsule(l[0], l[1], 1.0)).collect(),
    };
    [fills, strokes].iter().enumerate().map(|(n, case)| sweep(cx, case, n)).collect()
}

fn sweep(cx: &Context, case: &Case, n_case: usize) -> anyhow::Result<Sweep> {
    let dir = cx.dir.path().join(format!("antialias-{n_case}"));
    std::fs::create_dir_all(&dir)?;
    let grid =
        relief_source::TileGrid::geodetic(relief_source::TileGrid::DEFAULT_TILE_SIZE).map_err(anyhow::Error::msg)?;
    let corner = grid.tile_extent(TileKey::new(LEVEL, FIRST.0, FIRST.1));
    let step = grid.sample_step(LEVEL);
    std::fs::write(dir.join("shapes.geojson"), geojson(&case.parts, case.lines, corner.min_x, corner.max_y, step))?;
    let mut text = String::from(
        "[scene]\nname = \"antialias\"\n\n[[source]]\nid = \"shapes\"\nkind = \"ogr\"\npath = \"shapes.geojson\"\n",
    );
    for aa in SETTINGS {
        let _ = write!(
            text,
            "\n[[source]]\nid = \"aa-{aa}\"\nkind = \"rasterize\"\ninputs = [\"shapes\"]\n{}\nantialias = {aa}\n",
            case.style
        );
    }
    text.push_str(NO_DISK_CACHE);
    let scene = cx.load(&write_manifest(&dir, &text)?)?;
    let snap = scene.snapshot();
    anyhow::ensure!(snap.grid == grid, "the scene's grid is not the default geodetic one");
    let n = grid.tile_size() as usize;
    let quality = Quality::default();
    // The features the op reads, cached first: only the drawing is timed.
    let input = source_index(&snap, "shapes")?;
    for y in FIRST.1 - 1..=FIRST.1 + 2 {
        for x in FIRST.0 - 1..=FIRST.0 + 2 {
            timed_tile(&scene, &snap, input, TileKey::new(LEVEL, x, y), &quality)?;
        }
    }
    let tiles: Vec<(usize, usize)> = (0..2).flat_map(|ty| (0..2).map(move |tx| (tx, ty))).collect();
    let exact: Vec<Vec<f64>> = tiles.iter().map(|&(tx, ty)| exact_coverage(&case.covered, tx, ty, n)).collect();
    let indices = SETTINGS.map(|aa| source_index(&snap, &format!("aa-{aa}")));
    // Rounds outside, settings inside: a busy spell on the machine falls on
    // every setting alike.
    let mut times = vec![Vec::new(); SETTINGS.len()];
    let mut edges = vec![ErrorStats::default(); SETTINGS.len()];
    let mut elsewhere = vec![0usize; SETTINGS.len()];
    for round in 0..ROUNDS {
        for (s, (aa, index)) in SETTINGS.iter().zip(&indices).enumerate() {
            let index = *index.as_ref().map_err(|e| anyhow::anyhow!("{e:#}"))?;
            forget(&scene, &snap, index);
            for (&(tx, ty), exact) in tiles.iter().zip(&exact) {
                let key = TileKey::new(LEVEL, FIRST.0 + tx as u32, FIRST.1 + ty as u32);
                let (ms, payload) = timed_tile(&scene, &snap, index, key, &quality)?;
                times[s].push(ms);
                if round > 0 {
                    continue;
                }
                let Payload::Color(tile) = payload.as_ref() else {
                    anyhow::bail!("source 'aa-{aa}' gave no colour tile for {key}");
                };
                anyhow::ensure!(tile.size == n + 2, "tile {key} is {} texels a side, not {}", tile.size, n + 2);
                for j in 0..n {
                    for i in 0..n {
                        let alpha = f64::from(tile.rgba[((j + 1) * tile.size + i + 1) * 4 + 3]) / 255.0;
                        let e = exact[j * n + i];
                        if e > 1e-12 && e < 1.0 - 1e-12 {
                            edges[s].add(alpha - e);
                        } else if (alpha - e).abs() > 0.6 / 255.0 {
                            elsewhere[s] += 1;
                        }
                    }
                }
            }
        }
    }
    let edge_texels = edges[0].count();
    let rows: Vec<Row> = SETTINGS
        .into_iter()
        .zip(times)
        .zip(edges.iter().zip(&elsewhere))
        .map(|((aa, times), (edges, elsewhere))| {
            Row::new(aa.to_string(), median(times), edges.rms())
                .default_if(aa == DEFAULT)
                .with("samples per texel", (aa * aa).to_string())
                .with("max error", format!("{:.3}", edges.max()))
                .with("wrong texels off the edges", elsewhere.to_string())
        })
        .collect();
    let find =
        |aa: u32| rows.iter().find(|r| r.setting == aa.to_string()).map_or((f64::NAN, f64::NAN), |r| (r.error, r.time));
    let (one, two, four, eight, sixteen) = (find(1), find(2), find(4), find(8), find(16));
    let slope = (one.0 / sixteen.0).ln() / 16f64.ln();
    let how = if case.lines {
        "A stroke tests every sub-sample near a segment, antialias squared per texel, so its cost grows with the square"
    } else {
        "A fill sweeps antialias sub-rows per texel row and adds whole runs of sub-samples at once, so its cost grows \
         with the sub-rows alone, and slowly where a tile has few edges"
    };
    let mut why = format!(
        "The coverage error on the texels an edge crosses falls about as antialias^-{slope:.1}: {:.3} RMS aliased, \
         {:.3} at 2, {:.3} at 4, {:.3} at 8, {:.4} at 16 (rounding to the alpha byte alone is 0.0011 RMS). {how}: \
         {:.2} ms a tile at 1, {:.2} at 4, {:.2} at 8, {:.2} at 16. 4 is the default: {:.0} times less error than \
         aliased for {:.1} times its time",
        one.0,
        two.0,
        four.0,
        eight.0,
        sixteen.0,
        one.1,
        four.1,
        eight.1,
        sixteen.1,
        one.0 / four.0,
        four.1 / one.1,
    );
    if case.lines {
        let _ = write!(
            why,
            "; each doubling past it cuts the error about {:.0} times again for {:.1} then {:.1} times the time \
             (worth it for fine line work seen close).",
            (four.0 / sixteen.0).sqrt(),
            eight.1 / four.1,
            sixteen.1 / eight.1
        );
    } else {
        let _ = write!(
            why,
            ". On fills alone the knob costs little here (16 takes {:.1} times the time of 4), so a fill-only layer \
             loses little at 8 or 16; the default is held at 4 by the strokes that share the knob (the next table).",
            sixteen.1 / four.1
        );
    }
    Ok(Sweep {
        knob: case.name.into(),
        case: format!(
            "{}, written as GeoJSON and read by an `ogr` source, into the 4 tiles of level 10 they lie on (256 x 256 \
             texels each, 0.00069 degrees); {edge_texels} texels that an edge crosses.",
            case.sentence
        ),
        reference: "each texel's exact covered fraction: the polygons (for a line, the segment swept by a disc of \
                    its width, 512 points on its round ends) clipped against the texel's square \
                    (Sutherland-Hodgman) and measured by the shoelace formula, in f64"
            .into(),
        error: "RMS of (alpha / 255 - exact coverage) over the texels an edge crosses (coverage 0..1)".into(),
        time: format!(
            "ms per colour tile drawn (input features cached), median of {} ({ROUNDS} rounds)",
            tiles.len() * ROUNDS
        ),
        rows,
        why_default: why,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipped_areas_add_up_to_the_polygon() {
        let shape = star(5.3, 4.7, 4.0, 1.6, 5, 12.0);
        let whole: f64 = (0..shape.len())
            .map(|k| {
                let (a, b) = (shape[k], shape[(k + 1) % shape.len()]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            .abs()
            / 2.0;
        let pieces: f64 = (0..11)
            .flat_map(|j| (0..11).map(move |i| (i, j)))
            .map(|(i, j)| area_in_square(&shape, f64::from(i), f64::from(j)))
            .sum();
        assert!((whole - pieces).abs() < 1e-9, "{whole} vs {pieces}");
        assert!((area_in_square(&rectangle(0.5, 0.5, 1.0, 1.0, 0.0), 0.0, 0.0) - 1.0).abs() < 1e-12);
    }
}
