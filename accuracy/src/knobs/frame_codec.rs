//! `frame_jpeg_quality`: the codec frames travel in while a view is
//! interactive. The demo range at 1280 x 720 with every effect it
//! declares, encoded as PNG (lossless, the frame at rest) and as JPEG at
//! each quality, then decoded (by the `image` crate's decoder, as a
//! viewer would): each encoding's pixels against the frame itself.

use relief_daemon::codec::Codec;
use relief_daemon::picture::DEFAULT_FRAME_JPEG_QUALITY;
use relief_daemon::view::SceneTerrain;
use relief_renderer::{ClipmapConfig, Frame, RenderSettings};

use super::{Context, HD, demo_pose, median, rgba_difference};
use crate::sweep::{Row, Sweep};

/// Encodings timed per setting (the median kept).
const RUNS: usize = 7;
const QUALITIES: [u8; 9] = [30, 50, 60, 70, 80, 85, 90, 95, 100];

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let scene = cx.load(&cx.demo)?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let e = relief_daemon::picture::Picture::of(&snap.manifest).effect_settings;
    let settings = RenderSettings { atmosphere: e.atmosphere, fog: e.fog, shadows: e.shadows, water: e.water, ..HD };
    let frames =
        super::still_frames(&cx.gpu, &terrain, &snap.grid, ClipmapConfig::default(), &settings, &demo_pose(), 1)?;
    let frame = frames.last().ok_or_else(|| anyhow::anyhow!("no frame"))?;
    let mut rows = Vec::new();
    let codecs = std::iter::once(Codec::Png).chain(QUALITIES.map(Codec::Jpeg));
    for codec in codecs {
        let (bytes, encode_ms) = timed(codec, frame)?;
        let (decoded, decode_ms) = decode(&bytes)?;
        let (rms, max) = rgba_difference(&frame.rgba, &decoded);
        let default = codec == Codec::Jpeg(DEFAULT_FRAME_JPEG_QUALITY);
        rows.push(
            Row::new(codec.name(), bytes.len() as f64 / 1024.0, rms)
                .default_if(default)
                .with("encode ms", format!("{encode_ms:.1}"))
                .with("decode ms", format!("{decode_ms:.1}"))
                .with("max error", format!("{max:.0}")),
        );
    }
    let why_default = why(&rows);
    Ok(vec![Sweep {
        knob: "frame_jpeg_quality".into(),
        case: format!(
            "The demo range at 1280 x 720 from its camera (9 km up, 25 degrees down) with every effect it declares \
             (lighting, shadows, water, atmosphere, fog), the frame a viewer gets; PNG is what it gets at rest, \
             JPEG q what it gets while its camera moves ([quality] frame_jpeg_quality, 4:2:0 chroma). The cost \
             of a setting is its bytes: what the wire and the viewer's decoder pay for every frame while the \
             camera moves (encoding takes about the same time at every quality: the median of {RUNS} encodings \
             on this machine's CPU, once per frame for all the streams that share it)."
        ),
        reference: "the rendered frame itself (RGBA8), which PNG reproduces exactly".into(),
        error: "RMS difference of every pixel's R, G and B (0-255) after decoding".into(),
        time: "KiB per frame".into(),
        rows,
        why_default,
    }])
}

/// The encoding of `frame` by `codec`, and its median time, ms.
fn timed(codec: Codec, frame: &Frame) -> anyhow::Result<(Vec<u8>, f64)> {
    let mut times = Vec::new();
    let mut bytes = Vec::new();
    for _ in 0..RUNS {
        let started = std::time::Instant::now();
        bytes = codec.encode(&frame.rgba, frame.width, frame.height).map_err(anyhow::Error::msg)?;
        times.push(started.elapsed().as_secs_f64() * 1e3);
    }
    Ok((bytes, median(times)))
}

/// The image back as RGBA8, and the time decoding took, ms.
fn decode(bytes: &[u8]) -> anyhow::Result<(Vec<u8>, f64)> {
    let started = std::time::Instant::now();
    let image = image::load_from_memory(bytes)?.to_rgba8().into_raw();
    Ok((image, started.elapsed().as_secs_f64() * 1e3))
}

/// Why quality 80, from the rows measured.
fn why(rows: &[Row]) -> String {
    let get = |name: &str| rows.iter().find(|r| r.setting == name);
    let ms = |r: &Row| r.extra.iter().find(|(h, _)| h == "encode ms").map_or_else(String::new, |(_, v)| v.clone());
    let (Some(png), Some(q80), Some(q95), Some(q50)) = (get("png"), get("jpeg 80"), get("jpeg 95"), get("jpeg 50"))
    else {
        return "the sweep did not measure the settings it compares".into();
    };
    format!(
        "A lossless PNG of this frame is {:.0} KiB ({} ms to encode); JPEG at 80 is {:.0} KiB ({} ms), {:.0} times \
         fewer bytes, with an RMS error of {:.2} levels (95: {:.0} KiB, {:.2}; 50: {:.0} KiB, {:.2}). While the \
         camera moves a frame lives for a fraction of a second; above 80 the bytes climb fast for little less \
         error, below it the error climbs for few bytes saved. At rest the frame is lossless whatever this knob \
         says.",
        png.time,
        ms(png),
        q80.time,
        ms(q80),
        png.time / q80.time,
        q80.error,
        q95.time,
        q95.error,
        q50.time,
        q50.error
    )
}
