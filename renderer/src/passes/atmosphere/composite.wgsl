// The scattering, computed at a coarser resolution, laid over the frame:
// sampled bilinearly at each frame pixel.

struct Composite {
    // Frame pixels to a side of each scattering texel (x).
    scale: vec4<f32>,
}

@group(0) @binding(0) var scattered: texture_2d<f32>;
@group(0) @binding(1) var bilinear: sampler;
@group(0) @binding(2) var<storage, read> composite: Composite;

@fragment
fn fs_composite(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let texels = vec2<f32>(textureDimensions(scattered));
    let uv = frag.xy / (composite.scale.x * texels);
    return textureSampleLevel(scattered, bilinear, uv, 0.0);
}
