// The sun's visibility from the shadow cascades (group 1), for every
// pass that asks whether the sun reaches a point: the shadows' own overlay
// and the atmosphere's in-scattering.

struct ShadowCascade {
    // Eye-relative position to the map: x, y in -1..1, depth 0..1.
    clip: mat4x4<f32>,
    // World metres per texel (x), depth bias in map units (y).
    params: vec4<f32>,
}

struct ShadowCascades {
    items: array<ShadowCascade, 4>,
    // Cascades in use (x), one texel in map units (y).
    info: vec4<f32>,
}

@group(1) @binding(0) var<storage, read> cascades: ShadowCascades;
@group(1) @binding(1) var shadow_maps: texture_depth_2d_array;
@group(1) @binding(2) var shadow_test: sampler_comparison;

// How much of the sun reaches eye-relative point p: 1 lit, 0 hidden. The
// finest cascade holding p answers, looked up 1.5 texels off the surface
// along `normal` (zero for a point in the air), filtered over
// (2 radius + 1)^2 bilinear comparisons. Past the last cascade, lit.
fn sun_visible(p: vec3<f32>, normal: vec3<f32>, radius: i32) -> f32 {
    let count = i32(cascades.info.x);
    for (var i = 0; i < count; i = i + 1) {
        let c = cascades.items[i];
        let q = c.clip * vec4<f32>(p + normal * (1.5 * c.params.x), 1.0);
        if abs(q.x) > 0.99 || abs(q.y) > 0.99 || q.z < 0.0 {
            continue;
        }
        if q.z >= 1.0 {
            return 1.0;
        }
        let uv = vec2<f32>(q.x * 0.5 + 0.5, 0.5 - q.y * 0.5);
        let reference = q.z + c.params.y;
        var sum = 0.0;
        var taps = 0.0;
        for (var dy = -radius; dy <= radius; dy = dy + 1) {
            for (var dx = -radius; dx <= radius; dx = dx + 1) {
                let at = uv + vec2<f32>(f32(dx), f32(dy)) * cascades.info.y;
                sum += textureSampleCompareLevel(shadow_maps, shadow_test, at, i, reference);
                taps += 1.0;
            }
        }
        return sum / taps;
    }
    return 1.0;
}
