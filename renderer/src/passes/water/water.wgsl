// Water: a full-screen pass over the drawn frame. Each pixel's view ray
// meets the water surface (a given level above the datum, over the planet
// or flat ground, or else the drawn terrain itself); where the water mask
// (a window of coverage round the camera) holds water there, the pixel
// becomes
//   Fresnel x (sky + sun glint) + (1 - Fresnel) x (body x (1 - T) + bottom x T)
// with the surface normal from a tiling wave normal map at two scales,
// Schlick's Fresnel (water's 0.02 at normal incidence), and T = exp(-d /
// clarity) for the d metres of water the ray crosses to the known terrain
// below (none when the water lies on the terrain). The bottom is what was
// drawn, kept through the blend. The shore is where the level meets the
// terrain: computed per pixel, faded over its first 0.3 m, so it never
// z-fights. An eye under the surface sees everything through the water.

struct Water {
    eye: Eye,
    // The window's east axis (xyz) and half its side (w, metres).
    east: vec4<f32>,
    // Its north axis (xyz); w 1 when the water has a level.
    north: vec4<f32>,
    // The eye's east and north metres from the window's centre (xy), the
    // eye's height above the water's level (z, worked out in f64: below
    // zero under the surface), the ground's radius under the eye (w; 0
    // over flat ground).
    place: vec4<f32>,
    // The water's colour (rgb), its clarity in metres (w).
    body: vec4<f32>,
    // The frame's sun and light terms (as `frame.wgsl`'s).
    sun: vec4<f32>,
    light: vec4<f32>,
}

// This pixel's Water, from the overlay's flat inputs (`fs`).
var<private> water: Water;
@group(0) @binding(2) var depth: texture_depth_2d;
@group(1) @binding(0) var mask: texture_2d<f32>;
@group(1) @binding(1) var waves: texture_2d<f32>;
@group(1) @binding(2) var clamped: sampler;
@group(1) @binding(3) var tiled: sampler;

const SHORE_M = 0.3;

// The eye-relative point p's east and north metres from the window's centre.
fn en_of(p: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(dot(p, water.east.xyz), dot(p, water.north.xyz)) + water.place.xy;
}

// Water coverage at p: 0 to 1, 0 outside the window.
fn mask_at(p: vec3<f32>) -> f32 {
    let en = en_of(p);
    let uv = vec2<f32>(en.x, -en.y) / (2.0 * water.east.w) + vec2<f32>(0.5);
    if any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0)) {
        return 0.0;
    }
    return textureSampleLevel(mask, clamped, uv, 0.0).r;
}

// Distance along a ray of cosine mu to the local up to the water's
// surface, from an eye `dh` above it (below when negative); negative when
// the ray never gets there. On the planet the roots are taken in the
// stable form c / (-r mu +- sqrt(disc)), c = dh (r + R): no difference of
// squares of planet radii in f32.
fn surface_t(dh: f32, mu: f32) -> f32 {
    let r0 = water.place.w;
    if r0 <= 0.0 {
        if abs(mu) < 1e-6 {
            return -1.0;
        }
        return -dh / mu;
    }
    let h0 = water.eye.up.w;
    let r = r0 + h0;
    let c = dh * (2.0 * r0 + 2.0 * h0 - dh);
    let disc = r * r * mu * mu - c;
    if disc < 0.0 {
        return -1.0;
    }
    if dh > 0.0 {
        // From above: only rays going down meet it, the nearer root.
        if mu >= 0.0 {
            return -1.0;
        }
        return c / (-r * mu + sqrt(disc));
    }
    return c / (-r * mu - sqrt(disc));
}

// The sky a reflected ray sees: horizon to zenith, by the daylight.
fn sky(r: vec3<f32>, up: vec3<f32>) -> vec3<f32> {
    let el = sqrt(max(dot(r, up), 0.0));
    let day = water.light.y / 0.75;
    return mix(vec3<f32>(0.75, 0.82, 0.90), vec3<f32>(0.22, 0.42, 0.78), el) * (0.08 + 0.92 * day);
}

@fragment
fn fs(input: OverlayIn) -> @location(0) vec4<f32> {
    let v = own_of(input);
    water = Water(eye_of(v[0], v[1], v[2], v[3], v[4]), v[5], v[6], v[7], v[8], v[9], v[10]);
    let frag = input.position;
    let size = vec2<f32>(textureDimensions(depth));
    let z = textureLoad(depth, vec2<i32>(frag.xy), 0);
    let ndc = ndc_of(frag.xy, size);
    let ray = view_ray(water.eye.inv_view_proj, ndc, z, 1.0e30);
    let dir = ray.xyz;
    let ground_t = ray.w;
    let up = water.eye.up.xyz;
    let dh = water.place.z;
    let has_level = water.north.w > 0.5;
    let mu = dot(dir, up);
    let lit = water.light.x + water.light.y * max(dot(water.sun.xyz, up), 0.0);
    let body = water.body.rgb * lit;
    let clarity = water.body.w;
    if has_level && dh < 0.0 && mask_at(vec3<f32>(0.0)) > 0.5 {
        // Under the surface: everything through the water, up to the
        // surface or the ground.
        var through = ground_t;
        let to_surface = surface_t(dh, mu);
        if to_surface > 0.0 {
            through = min(through, to_surface);
        }
        let t = exp(-min(through, 1.0e6) / clarity);
        return vec4<f32>(body * (1.0 - t), 1.0 - t);
    }
    var t_water = ground_t;
    if has_level {
        t_water = surface_t(dh, mu);
        if t_water <= 0.0 || t_water >= ground_t {
            discard;
        }
    } else if z <= 0.0 {
        discard;
    }
    let w = dir * t_water;
    var coverage = mask_at(w);
    if coverage <= 0.004 {
        discard;
    }
    // Waves: slopes from the normal map at two scales.
    let en = en_of(w);
    let s1 = textureSampleLevel(waves, tiled, en / 37.0, 0.0).xy * 2.0 - vec2<f32>(1.0);
    let s2 = textureSampleLevel(waves, tiled, en / 11.0 + vec2<f32>(0.37, 0.61), 0.0).xy * 2.0 - vec2<f32>(1.0);
    let slope = (s1 + 0.5 * s2) * 0.06;
    let n = normalize(up + water.east.xyz * slope.x + water.north.xyz * slope.y);
    let cos_i = clamp(dot(-dir, n), 0.0, 1.0);
    let fresnel = 0.02 + 0.98 * pow(1.0 - cos_i, 5.0);
    let r = reflect(dir, n);
    let glint = pow(max(dot(r, water.sun.xyz), 0.0), 400.0) * 3.0 * (water.light.y / 0.75);
    var bottom = 0.0;
    var shore = 1.0;
    if has_level && z > 0.0 {
        let d = ground_t - t_water;
        bottom = exp(-d / clarity);
        shore = smoothstep(0.0, SHORE_M, d);
    }
    let rgb = fresnel * (sky(r, up) + vec3<f32>(glint)) + (1.0 - fresnel) * (1.0 - bottom) * body;
    let alpha = 1.0 - (1.0 - fresnel) * bottom;
    let a = clamp(coverage * shore, 0.0, 1.0);
    return vec4<f32>(clamp(rgb, vec3<f32>(0.0), vec3<f32>(1.0)) * a, alpha * a);
}
