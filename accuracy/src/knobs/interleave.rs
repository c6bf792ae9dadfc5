//! Timing settings in turn rather than one after another: on a shared
//! machine the load drifts over a minute, and a sweep that timed each
//! setting's frames together would hand one setting a busy spell and the
//! next a quiet one. Each round renders every setting once (forwards, then
//! backwards the next round), and each setting's time is its fastest over
//! the rounds: on lavapipe a frame is CPU work, another process's load only
//! ever adds to it (frames of one setting here ranged over 2-4x on a busy
//! 2-core machine while their fastest agreed within 20%), so the fastest is
//! the least disturbed.

use relief_renderer::Frame;

/// One setting's frames: each timed frame's pass times, and the last frame.
pub struct Timed {
    pub passes: Vec<Vec<(&'static str, f64)>>,
    pub last: Frame,
}

impl Timed {
    /// The fastest over the rounds of the frame's pass times summed, ms.
    pub fn frame_ms(&self) -> f64 {
        fastest(self.passes.iter().map(|p| p.iter().map(|(_, ms)| ms).sum()))
    }

    /// The fastest over the rounds of pass `name`'s time (0 where it did
    /// not run), ms.
    pub fn pass_ms(&self, name: &str) -> f64 {
        fastest(self.passes.iter().map(|p| p.iter().filter(|(n, _)| *n == name).map(|(_, ms)| ms).sum()))
    }
}

fn fastest(times: impl Iterator<Item = f64>) -> f64 {
    times.fold(f64::NAN, f64::min)
}

/// `rounds` timed frames of each of `settings` settings, in turn, from
/// `render(k)` (setting k's frame). Every setting first renders one frame
/// that is not timed (it fills the levels, builds tiles and passes); with
/// `shared` (the settings share one renderer, so a change of setting may
/// rebuild what a pass holds) every timed frame follows one more that is
/// not.
pub fn interleaved(
    settings: usize,
    rounds: usize,
    shared: bool,
    mut render: impl FnMut(usize) -> anyhow::Result<Frame>,
) -> anyhow::Result<Vec<Timed>> {
    let mut passes: Vec<Vec<Vec<(&'static str, f64)>>> = vec![Vec::new(); settings];
    let mut last: Vec<Option<Frame>> = (0..settings).map(|_| None).collect();
    for k in 0..settings {
        render(k)?;
    }
    for round in 0..rounds {
        let order: Vec<usize> = if round % 2 == 0 { (0..settings).collect() } else { (0..settings).rev().collect() };
        for k in order {
            if shared {
                render(k)?;
            }
            let frame = render(k)?;
            passes[k].push(frame.passes.clone());
            last[k] = Some(frame);
        }
    }
    passes
        .into_iter()
        .zip(last)
        .map(|(passes, last)| {
            let last = last.ok_or_else(|| anyhow::anyhow!("no timed frame (rounds is 0)"))?;
            Ok(Timed { passes, last })
        })
        .collect()
}
