//! The `fog` effect: exponential height fog laid over the drawn frame by
//! one full-screen pass that reads the depth buffer (`fog.wgsl` has the
//! model). Built only for a scene that declares fog; independent of any
//! atmosphere.

use bytemuck::{Pod, Zeroable};

use super::overlay::{Eye, Overlay, over_frame};

/// Height fog: density at the base height, how fast it thins upwards, and
/// its colour (straight RGB, 0..1) in full daylight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fog {
    /// Extinction per metre at `base_m` (visibility is about 3.9 / density).
    pub density_per_m: f64,
    /// The height over which the density falls by e.
    pub falloff_m: f64,
    /// The height (above the datum) where the density is `density_per_m`.
    pub base_m: f64,
    pub color: [f64; 3],
}

impl Fog {
    /// A light haze: 13 km visibility at sea level, thinning by e every km.
    pub const DEFAULT: Self = Self { density_per_m: 3.0e-4, falloff_m: 1000.0, base_m: 0.0, color: [0.78, 0.80, 0.83] };

    /// Each value in its range, or the field and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(self.density_per_m.is_finite() && (0.0..=1.0).contains(&self.density_per_m)) {
            return Err(("density", format!("{} is not from 0 to 1 per metre", self.density_per_m)));
        }
        if !(self.falloff_m.is_finite() && (1.0..=1.0e6).contains(&self.falloff_m)) {
            return Err(("falloff_m", format!("{} is not from 1 to 1,000,000 m", self.falloff_m)));
        }
        if !(self.base_m.is_finite() && self.base_m.abs() <= 1.0e5) {
            return Err(("base_m", format!("{} is not within 100 km of the datum", self.base_m)));
        }
        Ok(())
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
struct FogUniform {
    eye: Eye,
    params: [f32; 4],
    color: [f32; 4],
}

/// The fog pass: a full-screen overlay.
pub struct FogPass(Overlay);

impl FogPass {
    pub fn new(device: &wgpu::Device, frame_buffer: &wgpu::Buffer) -> Self {
        let target = over_frame(wgpu::BlendState::ALPHA_BLENDING);
        Self(Overlay::new::<FogUniform>(device, frame_buffer, ("fog", include_str!("fog.wgsl")), target, None))
    }

    /// The frame's fog uniform written (lit by the sun's `daylight`, 0 to
    /// 1), and the bind group over this frame's depth.
    pub fn prepare(
        &self,
        gpu: &crate::gpu::Gpu,
        frame_buffer: &wgpu::Buffer,
        depth: &wgpu::TextureView,
        fog: &Fog,
        eye: Eye,
        daylight: f64,
    ) -> wgpu::BindGroup {
        let light = (0.08 + 0.92 * daylight) as f32;
        // The eye's height above the base in falloff heights, and the
        // density there (bounded as the shader bounds a ray's far end).
        let above = (eye.height_m() - fog.base_m) / fog.falloff_m;
        let at_eye = fog.density_per_m * (-above.clamp(-80.0, 80.0)).exp();
        let u = FogUniform {
            eye,
            params: [fog.density_per_m as f32, fog.falloff_m as f32, above as f32, at_eye as f32],
            color: [fog.color[0] as f32 * light, fog.color[1] as f32 * light, fog.color[2] as f32 * light, 1.0],
        };
        self.0.prepare(gpu, frame_buffer, depth, &u)
    }

    pub fn record(&self, pass: &mut wgpu::RenderPass<'_>, bind_group: &wgpu::BindGroup) {
        self.0.record(pass, bind_group, None);
    }
}
