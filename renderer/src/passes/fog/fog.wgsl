// Exponential height fog: a full-screen pass over the drawn frame. Each
// pixel's point (from the depth buffer, relative to the eye) or, for the
// sky, its ray to infinity, is seen through fog whose density falls off
// exponentially with height:
//   density(h) = d0 * exp(-(h - base) / H)
// Along the ray from the eye (height he) to a point dh higher at distance
// L, the optical depth is
//   tau = d0 * L * exp(-(he - base) / H) * (1 - exp(-dh / H)) / (dh / H)
// (the last factor 1 where dh / H is tiny); the fog's colour is laid over
// with alpha 1 - exp(-tau). Heights along the ray follow the eye's up: the
// fog of a weather study is local, the planet's curvature under it left out.

struct Fog {
    inv_view_proj: mat4x4<f32>,
    // Up at the eye (xyz), the eye's height (w), metres.
    up: vec4<f32>,
    // Density at the base height per metre (x), falloff height H (y),
    // base height (z).
    params: vec4<f32>,
    // Colour (rgb), lit by the daylight already.
    color: vec4<f32>,
}

@group(0) @binding(1) var<uniform> fog: Fog;
@group(0) @binding(2) var depth: texture_depth_2d;

@vertex
fn vs_fog(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // One triangle over the whole screen.
    let x = f32(i32(vi & 1u) * 4 - 1);
    let y = f32(i32(vi >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

// The point at `ndc` (xy) and depth `z`, relative to the eye.
fn unproject(ndc: vec2<f32>, z: f32) -> vec3<f32> {
    let p = fog.inv_view_proj * vec4<f32>(ndc, z, 1.0);
    return p.xyz / p.w;
}

// Optical depth along `l` metres of a ray rising `dh` metres.
fn optical_depth(l: f32, dh: f32) -> f32 {
    let d0 = fog.params.x;
    let h = fog.params.y;
    let at_eye = d0 * exp(-(fog.up.w - fog.params.z) / h);
    let k = dh / h;
    var spread = 1.0;
    if abs(k) > 1e-4 {
        spread = (1.0 - exp(-k)) / k;
    }
    return at_eye * l * spread;
}

@fragment
fn fs_fog(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let size = vec2<f32>(textureDimensions(depth));
    let pixel = vec2<i32>(frag.xy);
    let ndc = vec2<f32>(frag.x / size.x * 2.0 - 1.0, 1.0 - frag.y / size.y * 2.0);
    let z = textureLoad(depth, pixel, 0);
    let up = fog.up.xyz;
    var tau: f32;
    if z > 0.0 {
        let p = unproject(ndc, z);
        tau = optical_depth(length(p), dot(p, up));
    } else {
        // The sky (reversed-Z: 0 is infinitely far): rising rays leave the
        // fog, level or falling ones never do.
        let dir = normalize(unproject(ndc, 1.0));
        let rise = dot(dir, up);
        if rise > 1e-4 {
            let d0 = fog.params.x;
            let h = fog.params.y;
            tau = d0 * exp(-(fog.up.w - fog.params.z) / h) * h / rise;
        } else {
            tau = 1e4;
        }
    }
    let alpha = 1.0 - exp(-min(tau, 1e4));
    return vec4<f32>(fog.color.rgb, clamp(alpha, 0.0, 1.0));
}
