//! What every pass of a frame reads: the camera's projection, the sun and
//! the eye, in one buffer the renderer writes once per frame (bound as
//! read-only storage: `crate::passes::pipeline::params_binding`).

use bytemuck::{Pod, Zeroable};
use glam::DVec3;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct FrameUniform {
    pub view_proj: [[f32; 4]; 4],
    pub sun: [f32; 4],
    pub light: [f32; 4],
    pub centre: [f32; 4],
    /// The eye in double-single parts (for meshes in world positions); w
    /// of `eye_low` is how far the terrain's base is sunk below the
    /// levels, in metres.
    pub eye_high: [f32; 4],
    pub eye_low: [f32; 4],
}

/// `v` as an f32 high part and the f32 remainder ("double-single"): the
/// shader subtracts the eye in two steps and keeps centimetres on a planet.
pub fn split(v: DVec3) -> ([f32; 3], [f32; 3]) {
    let high = v.as_vec3();
    let low = (v - high.as_dvec3()).as_vec3();
    (high.to_array(), low.to_array())
}

pub fn frame_buffer(device: &wgpu::Device) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("frame"),
        size: size_of::<FrameUniform>() as u64,
        usage: crate::passes::pipeline::PARAMS_USAGE,
        mapped_at_creation: false,
    })
}
