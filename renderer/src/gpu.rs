//! The headless device: a GPU when there is one, else Mesa's lavapipe
//! (software Vulkan), which wgpu finds like any other adapter.

use crate::error::RenderError;

#[derive(Debug)]
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Adapter name and backend, for the scene state and benchmark tables.
    pub description: String,
    pub is_software: bool,
}

impl Gpu {
    /// Opens the best adapter there is (discrete or integrated GPU before
    /// a CPU rasterizer). `WGPU_BACKEND` and friends are honoured.
    pub fn headless() -> Result<Self, RenderError> {
        // Vulkan (lavapipe included), Metal or DX12; GL only when WGPU_BACKEND
        // asks for it (probing EGL on a headless machine only logs errors).
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::PRIMARY;
        let instance = wgpu::Instance::new(desc.with_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("relief"),
            // The flat inputs the full-screen passes take (`overlay`): as many
            // as the adapter has (lavapipe 31; the downlevel 15 would not
            // carry the shadowed atmosphere's 17).
            required_limits: wgpu::Limits {
                max_inter_stage_shader_variables: adapter.limits().max_inter_stage_shader_variables,
                ..wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits())
            },
            ..Default::default()
        }))
        .map_err(|e| RenderError::Device(e.to_string()))?;
        Ok(Self {
            device,
            queue,
            description: format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type),
            is_software: info.device_type == wgpu::DeviceType::Cpu,
        })
    }

    /// The largest image side this device renders.
    pub fn max_size(&self) -> u32 {
        self.device.limits().max_texture_dimension_2d
    }
}
