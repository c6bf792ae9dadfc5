// The scattering, computed at a coarser resolution, laid over the frame:
// sampled bilinearly at each frame pixel.

struct Composite {
    // Frame pixels to a side of each scattering texel (x).
    scale: vec4<f32>,
}

@group(0) @binding(0) var scattered: texture_2d<f32>;
@group(0) @binding(1) var bilinear: sampler;
@group(0) @binding(2) var<storage, read> composite: Composite;

struct CompositeIn {
    @builtin(position) position: vec4<f32>,
    // The scale, read once for the triangle and handed to every pixel.
    @location(0) @interpolate(flat) scale: vec4<f32>,
}

@vertex
fn vs_composite(@builtin(vertex_index) vi: u32) -> CompositeIn {
    return CompositeIn(fullscreen_corner(vi), composite.scale);
}

@fragment
fn fs_composite(input: CompositeIn) -> @location(0) vec4<f32> {
    let frag = input.position;
    let texels = vec2<f32>(textureDimensions(scattered));
    let uv = frag.xy / (input.scale.x * texels);
    return textureSampleLevel(scattered, bilinear, uv, 0.0);
}
