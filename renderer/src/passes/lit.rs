//! The lit passes' pipelines (terrain, buildings, instances): each made
//! plain, and again as a twin receiving the shadows of the frame's
//! cascades while the scene casts them.

use super::pipeline::{pipeline, shader};
use super::shadows::receiving;

/// A lit pass's shader (terrain, buildings, instances): `shader` of its
/// source made to receive the shadows of a frame casting `cascades` maps,
/// or none (`shadows::receiving`).
pub fn lit_shader(device: &wgpu::Device, label: &str, source: &str, cascades: Option<u32>) -> wgpu::ShaderModule {
    shader(device, label, &receiving(source, cascades))
}

/// One pipeline of a lit pass, as both it and its shadow-receiving twin
/// are made: its label, its own bind group's layout (group 0), its stages
/// and vertex buffers.
pub struct LitPipeline<'a> {
    pub label: &'a str,
    pub group0: &'a wgpu::BindGroupLayout,
    pub stages: (&'a str, &'a str),
    pub buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
}

impl LitPipeline<'_> {
    /// The pipeline from `shader`; with `lookup` (the shadow cascades'
    /// layout, bound as group 1), the twin receiving shadows.
    pub fn build(
        &self,
        device: &wgpu::Device,
        shader: &wgpu::ShaderModule,
        lookup: Option<&wgpu::BindGroupLayout>,
    ) -> wgpu::RenderPipeline {
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(self.label),
            bind_group_layouts: &[Some(self.group0), lookup],
            immediate_size: 0,
        });
        pipeline(device, self.label, &layout, shader, self.stages, self.buffers)
    }
}

/// A lit pass's pipelines for frames that cast shadows: its shader built
/// again to receive the shadows of `cascades` maps (`shadows::receiving`),
/// the cascades' lookup bound as group 1. Made the first time a frame
/// casts shadows, and again when the cascade count changes; gone when the
/// scene casts none.
pub struct Receiving {
    cascades: u32,
    pipelines: Vec<wgpu::RenderPipeline>,
}

impl Receiving {
    /// Brings a pass's twins (`slot`) to `lookup` (the cascades' layout and
    /// count): kept while made for that count, else made anew from the
    /// pass's `source` and `pipelines`; none without a lookup.
    pub fn update(
        slot: &mut Option<Self>,
        device: &wgpu::Device,
        lookup: Option<(&wgpu::BindGroupLayout, u32)>,
        (label, source): (&str, &str),
        pipelines: &[LitPipeline<'_>],
    ) {
        let Some((lookup, cascades)) = lookup else {
            *slot = None;
            return;
        };
        if slot.as_ref().is_some_and(|r| r.cascades == cascades) {
            return;
        }
        let shader = lit_shader(device, label, source, Some(cascades));
        let pipelines = pipelines.iter().map(|p| p.build(device, &shader, Some(lookup))).collect();
        *slot = Some(Self { cascades, pipelines });
    }

    /// The pipelines a pass draws with: the twins in `slot`, with the
    /// cascades' bind group (`shadows`) set as group 1, when the frame
    /// casts shadows; else its `plain` ones.
    pub fn choose<'a, const N: usize>(
        slot: Option<&'a Self>,
        pass: &mut wgpu::RenderPass<'_>,
        shadows: Option<&wgpu::BindGroup>,
        plain: [&'a wgpu::RenderPipeline; N],
    ) -> [&'a wgpu::RenderPipeline; N] {
        match (shadows, slot) {
            (Some(lookup), Some(twins)) if twins.pipelines.len() == N => {
                pass.set_bind_group(1, lookup, &[]);
                std::array::from_fn(|i| &twins.pipelines[i])
            }
            _ => plain,
        }
    }
}
