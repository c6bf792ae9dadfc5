//! A distinct view's key and the frames rendered for it: shared by every
//! stream that shows it, each encoded once per codec.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use bytes::Bytes;

use crate::codec::Codec;
use crate::view::{Camera, Overrides, Rendered, ViewError};

/// Bytes a frame holds per pixel: RGBA, f32 depth, and its PNG at most.
const BYTES_PER_PIXEL: u64 = 4 + 4 + 1;

/// One distinct render: what every stream showing it shares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewKey {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    /// The request's quality overrides.
    pub overrides: Overrides,
    /// Drawn while the viewer drags (at `interactive_scale`).
    pub interactive: bool,
}

impl ViewKey {
    pub fn frame_bytes(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height) * BYTES_PER_PIXEL
    }
}

/// How a stream or a call wants its frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameFormat {
    /// Raw RGBA8.
    Rgba,
    Png,
    /// JPEG of this quality (1 to 100), always.
    Jpeg(u8),
    /// JPEG of this quality while the view is interactive (the camera
    /// moving), PNG (lossless) at rest.
    Live(u8),
}

impl FrameFormat {
    /// The codec for a frame, interactive or at rest; None for raw RGBA.
    pub fn codec(self, interactive: bool) -> Option<Codec> {
        match self {
            Self::Rgba => None,
            Self::Jpeg(q) => Some(Codec::Jpeg(q)),
            Self::Live(q) if interactive => Some(Codec::Jpeg(q)),
            Self::Png | Self::Live(_) => Some(Codec::Png),
        }
    }
}

/// An encoded image and the milliseconds its encoding took.
pub type Encoded = Result<(Bytes, f64), String>;

/// A rendered frame as the hub shares it; each encoding is made once, by
/// the first stream that wants it, and shared with the frames that carry
/// it over to later generations.
pub struct HubFrame {
    pub rendered: Arc<Rendered>,
    pub rgba: Bytes,
    /// The generation it is shown for: the one it was rendered at, or a
    /// later one that changed nothing it draws.
    pub generation: u64,
    /// Shown again for a later generation, not rendered again.
    pub carried_over: bool,
    /// Drawn while its view was interactive (smaller, and lossy on the
    /// wire where the stream asks for `Live`).
    pub interactive: bool,
    encoded: Arc<Mutex<HashMap<Codec, Encoded>>>,
}

impl HubFrame {
    pub fn new(mut rendered: Rendered, interactive: bool) -> Self {
        let rgba = Bytes::from(std::mem::take(&mut rendered.frame.rgba));
        let generation = rendered.generation;
        let carried_over = rendered.carried_over;
        let encoded = Arc::default();
        Self { rendered: Arc::new(rendered), rgba, generation, carried_over, interactive, encoded }
    }

    /// This frame shown for a later `generation` that changed nothing it
    /// draws: the same image and encodings.
    #[must_use]
    pub fn carried(&self, generation: u64) -> Self {
        Self {
            rendered: Arc::clone(&self.rendered),
            rgba: self.rgba.clone(),
            generation,
            carried_over: true,
            interactive: self.interactive,
            encoded: Arc::clone(&self.encoded),
        }
    }

    /// The frame encoded by `codec`, on first use, and how long that took.
    /// Blocking.
    pub fn encoded(&self, codec: Codec) -> Encoded {
        let mut done = self.encoded.lock().expect("never held across a panic");
        done.entry(codec)
            .or_insert_with(|| {
                let f = &self.rendered.frame;
                let started = std::time::Instant::now();
                let image = codec.encode(&self.rgba, f.width, f.height)?;
                Ok((Bytes::from(image), started.elapsed().as_secs_f64() * 1e3))
            })
            .clone()
    }

    /// What the frame holds, bytes: its colour, depth and encodings.
    pub fn held_bytes(&self) -> u64 {
        let encoded: usize =
            self.encoded.lock().expect("never held across a panic").values().flatten().map(|(b, _)| b.len()).sum();
        (self.rgba.len() + self.rendered.frame.depth.len() * 4 + encoded) as u64
    }

    pub fn is_encoded(&self, codec: Codec) -> bool {
        self.encoded.lock().expect("never held across a panic").contains_key(&codec)
    }
}

/// What a slot holds: nothing yet, the newest frame, or why it failed.
pub type Published = Option<Result<Arc<HubFrame>, Arc<ViewError>>>;
