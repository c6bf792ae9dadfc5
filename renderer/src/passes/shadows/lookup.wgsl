// The sun's visibility from the shadow cascades (group 1): what every
// pass that asks whether the sun reaches a point shares. The lit passes
// (`receive.wgsl`) place their vertices in the cascades and look each
// pixel up; the atmosphere (`air.wgsl`) places each sample of its rays.
//
// The cascades' table (`CascadeTable`, 9 vec4s): the sun's axes across its
// rays, right (0) and up (1), and towards it (2), with the cascades in use
// (0.w), one texel in map units (1.w) and texels to a side (2.w); then
// for each cascade its box's centre across (x, y), one over its half side
// (z) and its metres per texel (w) (3 + i); the box's near end along the
// sun's axis (7[i]) and map depth per metre (8[i]).

@group(1) @binding(1) var shadow_maps: texture_depth_2d_array;
@group(1) @binding(2) var shadow_test: sampler_comparison;

// Where a point whose place along the sun's axes is `l` (`ln` its normal's,
// zero for a point in the air) falls in cascade `i` (of `count` in use),
// looked up 1.5 texels off the surface along the normal: map units across
// (xy, -1..1 inside the box), map depth (z, 0..1 between the box's ends)
// and the half texel of bias the depth is tested with (w). A cascade not
// in use places nothing inside.
fn cascade_coords(l: vec3<f32>, ln: vec3<f32>, box: vec4<f32>, near: f32, depth_per_m: f32, i: f32, count: f32) -> vec4<f32> {
    let at = l + ln * (1.5 * box.w);
    let q = vec3<f32>((at.x - box.x) * box.z, (at.y - box.y) * box.z, (at.z - near) * depth_per_m);
    return select(vec4<f32>(9.0, 9.0, -1.0, 0.0), vec4<f32>(q, 0.5 * box.w * depth_per_m), i < count);
}

// Eye-relative point p, its surface facing `n` (zero for a point in the
// air), in each cascade of table `t` the pass was built for
// (`cascade_coords`); the slots past `CASCADES` stay zero, are never read
// (`finest_place`) and so are compiled out.
fn cascade_places(t: array<vec4<f32>, 9>, p: vec3<f32>, n: vec3<f32>) -> array<vec4<f32>, 4> {
    let count = t[0].w;
    let axes = mat3x3<f32>(t[0].xyz, t[1].xyz, t[2].xyz);
    let l = p * axes;
    let ln = n * axes;
    var c = array<vec4<f32>, 4>();
    c[0] = cascade_coords(l, ln, t[3], t[7].x, t[8].x, 0.0, count);
    if CASCADES > 1u {
        c[1] = cascade_coords(l, ln, t[4], t[7].y, t[8].y, 1.0, count);
    }
    if CASCADES > 2u {
        c[2] = cascade_coords(l, ln, t[5], t[7].z, t[8].z, 2.0, count);
    }
    if CASCADES > 3u {
        c[3] = cascade_coords(l, ln, t[6], t[7].w, t[8].w, 3.0, count);
    }
    return c;
}

// The finest cascade holding the point placed at `c` (`cascade_places`):
// map uv (xy), the depth to test (z) and the cascade (w); w -1 (lit)
// where none holds it or it is past a map's far end.
fn finest_place(c: array<vec4<f32>, 4>) -> vec4<f32> {
    var place = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    if CASCADES > 3u {
        place = finer_place(place, c[3], 3.0);
    }
    if CASCADES > 2u {
        place = finer_place(place, c[2], 2.0);
    }
    if CASCADES > 1u {
        place = finer_place(place, c[1], 1.0);
    }
    return finer_place(place, c[0], 0.0);
}

// `place` replaced by cascade `i`'s where it holds the point `q`
// (`cascade_coords`) across its rays and in front of its near end: map
// uv (xy), the depth to test against the map's (z) and the cascade (w);
// w -1 (lit) past its far end. Called coarsest first, so the finest
// holding the point is kept, with no loop and no array indexed per pixel:
// lavapipe runs a loop's exits under masks (the shadows' pass of the
// default frame took 22 ms with a loop over the cascades, 14 ms this way).
fn finer_place(place: vec4<f32>, q: vec4<f32>, i: f32) -> vec4<f32> {
    let holds = abs(q.x) <= 0.99 && abs(q.y) <= 0.99 && q.z >= 0.0;
    let lit = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    let here = select(vec4<f32>(q.x * 0.5 + 0.5, 0.5 - q.y * 0.5, q.z + q.w, i), lit, q.z >= 1.0);
    return select(place, here, holds);
}
