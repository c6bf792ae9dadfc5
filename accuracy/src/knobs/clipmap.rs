//! The clipmap's `n` (samples per level side) and `L` (levels): the demo
//! range rendered at 1280 x 720 from two cameras (looking down, and
//! towards the horizon), the surface each frame draws read back from its
//! depth buffer and compared with the terrain's formula; the time is the
//! still frame's.

use relief_daemon::view::SceneTerrain;
use relief_renderer::{ClipmapConfig, Pose};

use super::data::surface_error;
use super::{Context, HD, demo_pose, frame_ms, median, still_frames};
use crate::sweep::{Row, Sweep};

fn sweep(
    cx: &Context,
    terrain: &SceneTerrain<'_>,
    grid: &relief_source::TileGrid,
    at: &Pose,
) -> anyhow::Result<Vec<Row>> {
    let mut rows = Vec::new();
    for n in [31usize, 63, 127, 255] {
        for levels in [4usize, 6, 8, 10] {
            let config = ClipmapConfig::new(n, levels);
            let frames = still_frames(&cx.gpu, terrain, grid, config, &HD, at, 5)?;
            let time = median(frames.iter().map(frame_ms).collect());
            let last = frames.last().ok_or_else(|| anyhow::anyhow!("no frame"))?;
            let (rms, max) = surface_error(last);
            rows.push(
                Row::new(format!("n {n}, L {levels}"), time, rms)
                    .default_if(config == ClipmapConfig::default())
                    .with("max error m", format!("{max:.1}"))
                    .with("level blocks drawn", last.drawn.terrain_blocks_drawn.to_string()),
            );
        }
    }
    Ok(rows)
}

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let scene = cx.load(&cx.demo)?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let down = demo_pose();
    let horizon = Pose { pitch_deg: -6.0, position: [down.position[0], down.position[1] - 0.25, 2500.0], ..down };
    let reference = "the terrain's formula, at the ground point each pixel's depth gives (f64)";
    let why = "Levels set how far the fine mesh reaches, n how fine it is near the eye; n 255 cuts the error near \
               the eye for two to four times the frame, too slow for a live view on a CPU device, and 4 levels \
               leave most of the view to the coarse base. Between 6 and 8 levels these two views do not justify \
               the default: where 6 levels reach the view's far edge, the two more cost their draw and, towards \
               the horizon, measured a larger error, not a smaller one (the finest levels sit where the ground is \
               seen most obliquely). 8 was chosen for views from higher up and wider, which these two do not \
               cover; a sweep over altitudes is what should settle it, and until then 6 is the better-supported \
               setting for views like these.";
    Ok(vec![
        Sweep {
            knob: "clipmap_grid_size and clipmap_levels".into(),
            case: "The demo range (heights from a formula) at 1280 x 720 from its camera, 9 km up and 25 degrees \
                   down; each setting's still frame."
                .into(),
            reference: reference.into(),
            error: "RMS height error of the drawn surface, m".into(),
            time: "still frame ms, median of 5".into(),
            rows: sweep(cx, &terrain, &snap.grid, &down)?,
            why_default: why.into(),
        },
        Sweep {
            knob: "clipmap_grid_size and clipmap_levels, towards the horizon".into(),
            case: "The same range at 1280 x 720 from 2,500 m, 6 degrees down, looking along the range: most of the \
                   ground is far away."
                .into(),
            reference: reference.into(),
            error: "RMS height error of the drawn surface, m".into(),
            time: "still frame ms, median of 5".into(),
            rows: sweep(cx, &terrain, &snap.grid, &horizon)?,
            why_default: why.into(),
        },
    ])
}
