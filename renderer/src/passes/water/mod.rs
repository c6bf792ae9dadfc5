//! The `water` effect: the scene's water layer drawn as a water surface at
//! a given level or on the terrain (`water.wgsl` has the model), one
//! full-screen pass over the frame's depth reading a window of the water
//! mask round the camera (`mask.rs`) and a tiling wave normal map. Built
//! only for a scene that declares it; its layer is read only then.

mod mask;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use relief_source::Extent;

use self::mask::Window;
pub use self::mask::{MASK_SIZE, WaterSamples};
use super::overlay::{Eye, Overlay, over_frame};
use crate::error::RenderError;
use crate::gpu::Gpu;
use crate::surface::Surface;
use crate::target::Target;

/// The water's knobs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Water {
    /// The surface's height above the datum, metres; None: on the terrain.
    pub level_m: Option<f64>,
    /// The water's own colour (straight RGB, 0..1), in full daylight.
    pub color: [f64; 3],
    /// Metres of water that let e^-1 of the bottom through.
    pub clarity_m: f64,
}

impl Water {
    pub const DEFAULT: Self = Self { level_m: None, color: [0.08, 0.24, 0.30], clarity_m: 4.0 };

    /// Each value in its range, or the field and what is wrong.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if let Some(level) = self.level_m
            && !(level.is_finite() && level.abs() <= 1.0e4)
        {
            return Err(("level_m", format!("{level} is not within 10,000 m of the datum")));
        }
        if !(self.clarity_m.is_finite() && (0.01..=1000.0).contains(&self.clarity_m)) {
            return Err(("clarity_m", format!("{} is not from 0.01 to 1,000 m", self.clarity_m)));
        }
        Ok(())
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
struct WaterUniform {
    eye: Eye,
    east: [f32; 4],
    north: [f32; 4],
    place: [f32; 4],
    body: [f32; 4],
    /// The frame's sun and light terms (`FrameUniform`'s).
    sun: [f32; 4],
    light: [f32; 4],
}

/// What a frame's water needs besides its knobs.
pub struct WaterView<'a> {
    pub eye: Eye,
    /// The frame's sun and light terms (`FrameUniform`'s).
    pub sun_light: ([f32; 4], [f32; 4]),
    /// The frame's eye-relative view-projection.
    pub view_proj: glam::Mat4,
    /// The eye, world axes, and the grid point under it.
    pub eye_world: DVec3,
    pub under: (f64, f64),
    /// The eye's height above the datum, and above the drawn ground.
    pub eye_height_m: f64,
    pub above_ground_m: f64,
    /// The ground's radius under the eye (None over flat ground).
    pub ground_radius_m: Option<f64>,
    pub surface: &'a Surface,
    pub samples: &'a dyn WaterSamples,
}

/// Texels to a side of the wave normal map.
const WAVES: u32 = 128;

/// The water pass: the overlay, the mask window and its texture, the waves.
pub struct WaterPass {
    overlay: Overlay,
    mask: wgpu::Texture,
    textures: wgpu::BindGroup,
    window: Option<Window>,
    /// Where the water layer changed since the window was read (grid
    /// units): read again at the next frame, only there.
    pending: Vec<Extent>,
    /// Coverage texels the last frame read (a window read whole, or the
    /// blocks over what changed).
    pub texels_read: u64,
}

impl WaterPass {
    pub fn new(gpu: &Gpu, frame_buffer: &wgpu::Buffer) -> Self {
        let device = &gpu.device;
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty,
            count: None,
        };
        let texture = wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        };
        let filtering = wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("water textures"),
            entries: &[entry(0, texture), entry(1, texture), entry(2, filtering), entry(3, filtering)],
        });
        // Premultiplied: the water's light added, what lies below kept by
        // what the water lets through.
        let blend = wgpu::BlendState {
            color: wgpu::BlendComponent {
                src_factor: wgpu::BlendFactor::One,
                dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                operation: wgpu::BlendOperation::Add,
            },
            alpha: wgpu::BlendComponent::OVER,
        };
        let overlay = Overlay::new::<WaterUniform>(
            device,
            frame_buffer,
            ("water", include_str!("water.wgsl")),
            over_frame(blend),
            Some((&layout, 0)),
        );
        let texture =
            |label, side: u32, format| crate::passes::pipeline::sampled_texture(device, label, side, 1, format);
        let mask = texture("water mask", MASK_SIZE as u32, wgpu::TextureFormat::R8Unorm);
        let waves = texture("water waves", WAVES, wgpu::TextureFormat::Rgba8Unorm);
        write(gpu, &waves, WAVES, 4, &wave_slopes());
        let sampler = |mode| {
            device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("water"),
                address_mode_u: mode,
                address_mode_v: mode,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            })
        };
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let textures = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("water textures"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&view(&mask)) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view(&waves)) },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler(wgpu::AddressMode::ClampToEdge)),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::Sampler(&sampler(wgpu::AddressMode::Repeat)),
                },
            ],
        });
        Self { overlay, mask, textures, window: None, pending: Vec::new(), texels_read: 0 }
    }

    /// What the pass holds, bytes: the coverage texture and window, the
    /// wave map.
    pub fn held_bytes(&self) -> u64 {
        let window = self.window.as_ref().map_or(0, |w| w.texels.len() as u64);
        crate::passes::pipeline::texture_bytes(&self.mask) + u64::from(WAVES * WAVES * 4) + window
    }

    /// The scene rebuilt the water layer's tiles in `area`: the texels of
    /// the window over it are read again at the next frame.
    pub fn invalidate(&mut self, area: &Extent) {
        if self.window.is_some() {
            self.pending.push(*area);
        }
    }

    /// Draws the water over `target`; nothing while the layer's tiles are
    /// not ready.
    pub fn run(
        &mut self,
        gpu: &Gpu,
        frame_buffer: &wgpu::Buffer,
        target: &Target,
        water: &Water,
        at: &WaterView<'_>,
    ) -> Result<(), RenderError> {
        // Far enough round the camera for what it sees in detail: 3 km
        // at the ground, 60 km from high up.
        let half_m = (at.above_ground_m * 6.0 + 3000.0).min(60_000.0);
        let ground = at.surface.world(at.under.0, at.under.1, 0.0);
        self.texels_read = 0;
        let pending = std::mem::take(&mut self.pending);
        if let Some(window) = self.window.as_mut().filter(|w| w.serves(ground, half_m)) {
            for area in &pending {
                match window.refresh(at.surface, at.samples, area) {
                    Ok(Some((cols, rows))) => {
                        let block: Vec<u8> = rows
                            .clone()
                            .flat_map(|r| &window.texels[r * MASK_SIZE + cols.start..][..cols.len()])
                            .copied()
                            .collect();
                        write_block(
                            gpu,
                            &self.mask,
                            (cols.start as u32, rows.start as u32),
                            (cols.len() as u32, rows.len() as u32),
                            &block,
                        );
                        self.texels_read += (cols.len() * rows.len()) as u64;
                    }
                    Ok(None) => {}
                    // Not ready: read the window whole once it is.
                    Err(()) => {
                        self.window = None;
                        break;
                    }
                }
            }
        } else {
            self.window = None;
        }
        if self.window.is_none() {
            self.window = Window::read(at.surface, at.samples, at.under, half_m);
            if let Some(w) = &self.window {
                write(gpu, &self.mask, MASK_SIZE as u32, 1, &w.texels);
                self.texels_read += w.texels.len() as u64;
            }
        }
        let Some(window) = &self.window else { return Ok(()) };
        // No water round the camera: nothing to draw. Else only the part
        // of the screen the water's box can cover.
        let Some(wet) = window.wet else { return Ok(()) };
        // On the planet the surface falls away below the window's plane.
        let sag = at.ground_radius_m.map_or(0.0, |r| window.half_m * window.half_m / r);
        let heights = water.level_m.map_or([-500.0, 9000.0], |l| [l - 1.0 - sag, l + 1.0]);
        let scissor = screen_box(at, window, wet, heights, (target.width, target.height));
        if scissor.is_some_and(|[_, _, w, h]| w == 0 || h == 0) {
            return Ok(());
        }
        // The eye's place over the window, from the window's centre at the datum.
        let from_centre = at.eye_world - window.centre;
        let (e, n) = (window.east.as_vec3(), window.north.as_vec3());
        let u = WaterUniform {
            eye: at.eye,
            east: [e.x, e.y, e.z, window.half_m as f32],
            north: [n.x, n.y, n.z, if water.level_m.is_some() { 1.0 } else { 0.0 }],
            place: [
                from_centre.dot(window.east) as f32,
                from_centre.dot(window.north) as f32,
                (at.eye_height_m - water.level_m.unwrap_or(0.0)) as f32,
                at.ground_radius_m.unwrap_or(0.0) as f32,
            ],
            body: [water.color[0] as f32, water.color[1] as f32, water.color[2] as f32, water.clarity_m as f32],
            sun: at.sun_light.0,
            light: at.sun_light.1,
        };
        let bind_group = self.overlay.prepare(gpu, frame_buffer, target.depth_view(), &u);
        target.run_overlay(gpu, "water", |pass| {
            if let Some([x, y, w, h]) = scissor {
                pass.set_scissor_rect(x, y, w, h);
            }
            self.overlay.record(pass, &bind_group, Some(&self.textures));
        })
    }
}

/// The pixels (x, y, width, height) the box of the window's wet part
/// between `heights` (above the datum at the window's centre) covers in a
/// frame `size` pixels; None (the whole frame) when a corner is behind the
/// eye.
fn screen_box(
    at: &WaterView<'_>,
    window: &Window,
    (e, n): ([f64; 2], [f64; 2]),
    heights: [f64; 2],
    (width, height): (u32, u32),
) -> Option<[u32; 4]> {
    let up = window.east.cross(window.north);
    let margin = 2.0 * window.half_m / MASK_SIZE as f64;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (ee, nn, hh) in [e[0] - margin, e[1] + margin]
        .into_iter()
        .flat_map(|ee| [n[0] - margin, n[1] + margin].map(|nn| (ee, nn)))
        .flat_map(|(ee, nn)| heights.map(|hh| (ee, nn, hh)))
    {
        let p = window.centre + window.east * ee + window.north * nn + up * hh - at.eye_world;
        let clip = at.view_proj * p.as_vec3().extend(1.0);
        if clip.w <= 1e-3 {
            return None;
        }
        let (x, y) = (f64::from(clip.x / clip.w), f64::from(clip.y / clip.w));
        (lo, hi) = ([lo[0].min(x), lo[1].min(y)], [hi[0].max(x), hi[1].max(y)]);
    }
    let px = |v: f64, size: u32| (f64::midpoint(v, 1.0).clamp(0.0, 1.0) * f64::from(size)).round() as u32;
    let (x0, x1) = (px(lo[0], width), px(hi[0], width));
    // Rows run down from the top: NDC y up.
    let (y0, y1) = (height - px(hi[1], height), height - px(lo[1], height));
    Some([x0, y0, x1 - x0, y1 - y0])
}

/// Writes one-byte `texels` into the block of a texture at `origin`,
/// `size` texels.
fn write_block(gpu: &Gpu, texture: &wgpu::Texture, (x, y): (u32, u32), (width, height): (u32, u32), texels: &[u8]) {
    gpu.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d { x, y, z: 0 },
            aspect: wgpu::TextureAspect::All,
        },
        texels,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(width), rows_per_image: Some(height) },
        wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
    );
}

/// Writes `texels` (`bytes` per texel) into a square texture `side` wide.
fn write(gpu: &Gpu, texture: &wgpu::Texture, side: u32, bytes: u32, texels: &[u8]) {
    gpu.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        texels,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(side * bytes), rows_per_image: Some(side) },
        wgpu::Extent3d { width: side, height: side, depth_or_array_layers: 1 },
    );
}

/// The wave normal map: the slopes (east, north; 0.5 is flat) of a sum of
/// sines with whole wave numbers, so it tiles; deterministic.
fn wave_slopes() -> Vec<u8> {
    const WAVES_OF: [(f64, f64, f64, f64); 6] = [
        (1.0, 2.0, 1.0, 0.3),
        (3.0, -1.0, 0.6, 1.7),
        (-2.0, 5.0, 0.35, 4.1),
        (7.0, 3.0, 0.2, 2.2),
        (-5.0, -8.0, 0.12, 5.3),
        (11.0, -6.0, 0.08, 0.9),
    ];
    let tau = std::f64::consts::TAU;
    let slopes: Vec<(f64, f64)> = (0..WAVES * WAVES)
        .map(|k| {
            let (u, v) = (f64::from(k % WAVES) / f64::from(WAVES), f64::from(k / WAVES) / f64::from(WAVES));
            WAVES_OF.iter().fold((0.0, 0.0), |(sx, sy), &(kx, ky, a, phase)| {
                let c = (tau * (kx * u + ky * v) + phase).cos() * a * tau;
                (sx + c * kx, sy + c * ky)
            })
        })
        .collect();
    let most = slopes.iter().map(|(x, y)| x.abs().max(y.abs())).fold(1e-9, f64::max);
    slopes
        .iter()
        .flat_map(|&(x, y)| {
            let byte = |s: f64| ((s / most * 0.5 + 0.5) * 255.0).round() as u8;
            [byte(x), byte(y), 128, 255]
        })
        .collect()
}
