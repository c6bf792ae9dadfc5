//! Where a frame looks from, as the instances are chosen and sorted for it.

use super::bands::InstanceBands;
use crate::camera::View;
use crate::surface::Surface;

/// Where a frame looks from, for choosing and sorting instances.
#[derive(Clone, Copy)]
pub struct InstancesView<'a> {
    pub surface: &'a Surface,
    pub view: &'a View,
    pub aspect: f64,
    /// The camera's grid point and height (metres).
    pub camera: [f64; 3],
    /// The drawn ground under the camera, when the terrain is there.
    pub ground_m: Option<f64>,
    pub bands: &'a InstanceBands,
}
