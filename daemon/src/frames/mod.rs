//! Frames for many viewers. A view is (camera, size, quality): the hub
//! renders each distinct view once per change of generation and hands the
//! frame to every stream showing it through a latest-wins slot (a
//! `tokio::sync::watch`), so a slow stream skips frames and never queues
//! them. Distinct views take turns on the one device, round-robin.
//!
//! Limits: at most [`MAX_VIEWS`] distinct views at once and
//! [`FRAME_MEMORY_BYTES`] of frames held for them (colour, depth and PNG,
//! about 9 bytes a pixel); a stream that would add a distinct view past
//! either is refused, and streams that share a view never are. Each stream
//! holds at most one frame on its way out.

mod frame;
mod hub;
mod stream;
mod views;

pub use frame::{Encoded, FrameFormat, HubFrame, Published, ViewKey};
pub use hub::{FRAME_MEMORY_BYTES, FrameHub, HubCounters, MAX_VIEWS, Subscription};
pub use stream::{CameraSource, FrameStream, StreamSpec, start};
pub use views::{Holder, OpenView, ViewSettings, Views};
