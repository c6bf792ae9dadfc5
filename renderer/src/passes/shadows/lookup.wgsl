// The sun's visibility from the shadow cascades (group 1), for every
// pass that asks whether the sun reaches a point: the shadows' own overlay
// and the atmosphere's in-scattering.

// The cascades, from the overlay's flat table (`begin_shadows`): the sun's
// axes across its rays, right (0) and up (1), and towards it (2), with the
// cascades in use (0.w), one texel in map units (1.w) and texels to a side
// (2.w); then for each cascade its box's centre across (x, y), one over its
// half side (z) and its metres per texel (w) (3 + i); the box's near end
// along the sun's axis (7[i]) and map depth per metre (8[i]).
var<private> shadow_table: array<vec4<f32>, 9>;

@group(1) @binding(1) var shadow_maps: texture_depth_2d_array;
@group(1) @binding(2) var shadow_test: sampler_comparison;

// Takes this pixel's cascades from the overlay's flat inputs.
fn begin_shadows(input: OverlayIn) {
    shadow_table = table_of(input);
}

// Where eye-relative point p falls in the finest cascade holding it,
// looked up 1.5 texels off the surface along `normal` (zero for a point
// in the air): map uv (xy), the depth to test against the map's with half
// a texel of bias (z), and the cascade (w); w is -1 past the last cascade
// or past a map's far side (lit). Every cascade in use is placed and the
// finest holding p kept, with no loop and no array indexed per pixel:
// lavapipe runs a loop's exits under masks, and the shadows' pass of the
// default frame took 22 ms with a loop over the cascades, 14 ms this way.
// Only the `CASCADES` the pass was built for are placed (a constant its
// pass declares, so the others are compiled out: placing points in all 4
// slots when the default 2 were in use cost the shadows' pass 0.5-3 ms
// more on lavapipe).
fn shadow_place(p: vec3<f32>, normal: vec3<f32>) -> vec4<f32> {
    let right = shadow_table[0];
    let up = shadow_table[1];
    let toward = shadow_table[2];
    let count = right.w;
    let l = vec3<f32>(dot(p, right.xyz), dot(p, up.xyz), dot(p, toward.xyz));
    let ln = vec3<f32>(dot(normal, right.xyz), dot(normal, up.xyz), dot(normal, toward.xyz));
    let near = shadow_table[7];
    let depth_per_m = shadow_table[8];
    // Coarsest first, so a finer cascade holding p replaces it.
    var place = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    if CASCADES > 3u {
        place = finer_place(place, l, ln, shadow_table[6], near.w, depth_per_m.w, 3.0, count);
    }
    if CASCADES > 2u {
        place = finer_place(place, l, ln, shadow_table[5], near.z, depth_per_m.z, 2.0, count);
    }
    if CASCADES > 1u {
        place = finer_place(place, l, ln, shadow_table[4], near.y, depth_per_m.y, 1.0, count);
    }
    place = finer_place(place, l, ln, shadow_table[3], near.x, depth_per_m.x, 0.0, count);
    return place;
}

// `shadow_place`'s answer for cascade `i` (its box, near end and depth
// per metre) where it is in use and holds the point across its rays and
// in front of its near end (lit, w -1, past its far end), else `place`.
fn finer_place(
    place: vec4<f32>,
    l: vec3<f32>,
    ln: vec3<f32>,
    box: vec4<f32>,
    near: f32,
    depth_per_m: f32,
    i: f32,
    count: f32,
) -> vec4<f32> {
    let at = l + ln * (1.5 * box.w);
    let q = vec3<f32>((at.x - box.x) * box.z, (at.y - box.y) * box.z, (at.z - near) * depth_per_m);
    let holds = i < count && abs(q.x) <= 0.99 && abs(q.y) <= 0.99 && q.z >= 0.0;
    let bias = 0.5 * box.w * depth_per_m;
    let lit = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    let here = select(vec4<f32>(q.x * 0.5 + 0.5, 0.5 - q.y * 0.5, q.z + bias, i), lit, q.z >= 1.0);
    return select(place, here, holds);
}

// How much of the sun reaches eye-relative point p: 1 lit, 0 hidden,
// filtered over (2 radius + 1)^2 bilinear comparisons (one for radius 0,
// the sampling done once outside any loop).
fn sun_visible(p: vec3<f32>, normal: vec3<f32>, radius: i32) -> f32 {
    let at = shadow_place(p, normal);
    if at.w < 0.0 {
        return 1.0;
    }
    let layer = i32(at.w);
    if radius == 0 {
        return textureSampleCompareLevel(shadow_maps, shadow_test, at.xy, layer, at.z);
    }
    var sum = 0.0;
    var taps = 0.0;
    for (var dy = -radius; dy <= radius; dy = dy + 1) {
        for (var dx = -radius; dx <= radius; dx = dx + 1) {
            let uv = at.xy + vec2<f32>(f32(dx), f32(dy)) * shadow_table[1].w;
            sum += textureSampleCompareLevel(shadow_maps, shadow_test, uv, layer, at.z);
            taps += 1.0;
        }
    }
    return sum / taps;
}

// The same answer, 0 or 1, from the one texel under p, unfiltered: for
// many samples a pixel averages anyway (the air's in-scattering), a
// quarter of the filtered comparison's reads.
fn sun_visible_texel(p: vec3<f32>) -> f32 {
    let at = shadow_place(p, vec3<f32>(0.0));
    if at.w < 0.0 {
        return 1.0;
    }
    let side = i32(shadow_table[2].w);
    let texel = clamp(vec2<i32>(at.xy * f32(side)), vec2<i32>(0), vec2<i32>(side - 1));
    return select(0.0, 1.0, at.z >= textureLoad(shadow_maps, texel, i32(at.w), 0));
}
