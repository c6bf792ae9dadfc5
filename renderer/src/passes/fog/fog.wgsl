// Exponential height fog: a full-screen pass over the drawn frame. Each
// pixel's point (from the depth buffer, relative to the eye) or, for the
// sky, its ray to infinity, is seen through fog whose density falls off
// exponentially with height:
//   density(h) = d0 * exp(-(h - base) / H)
// Along the ray from the eye (height he) to a point dh higher at distance
// L, the optical depth is
//   tau = d0 * L * (exp(-(he - base) / H) - exp(-(he + dh - base) / H)) / (dh / H)
// (d0 * L * exp(-(he - base) / H) where dh / H is tiny); the fog's colour is laid over
// with alpha 1 - exp(-tau). Heights along the ray follow the eye's up: the
// fog of a weather study is local, the planet's curvature under it left out.

struct Fog {
    eye: Eye,
    // Density at the base height per metre (x), falloff height H (y),
    // base height (z).
    params: vec4<f32>,
    // Colour (rgb), lit by the daylight already.
    color: vec4<f32>,
}

// This pixel's Fog, from the overlay's flat inputs (`fs`).
var<private> fog: Fog;
@group(0) @binding(2) var depth: texture_depth_2d;

// Optical depth along `l` metres of a ray rising `dh` metres: the
// difference of the density at its two ends over the rise (each end's
// exponent bounded, so a ray from orbit does not overflow).
fn optical_depth(l: f32, dh: f32) -> f32 {
    let d0 = fog.params.x;
    let h = fog.params.y;
    let eye = exp(-clamp((fog.eye.up.w - fog.params.z) / h, -80.0, 80.0));
    let k = dh / h;
    if abs(k) < 1e-4 {
        return d0 * l * eye;
    }
    let end = exp(-clamp((fog.eye.up.w + dh - fog.params.z) / h, -80.0, 80.0));
    return d0 * l * (eye - end) / k;
}

@fragment
fn fs(input: OverlayIn) -> @location(0) vec4<f32> {
    let v = own_of(input);
    fog = Fog(eye_of(v[0], v[1], v[2], v[3], v[4]), v[5], v[6]);
    let frag = input.position;
    let size = vec2<f32>(textureDimensions(depth));
    let pixel = vec2<i32>(frag.xy);
    let ndc = ndc_of(frag.xy, size);
    let z = textureLoad(depth, pixel, 0);
    let up = fog.eye.up.xyz;
    var tau: f32;
    if z > 0.0 {
        let p = unproject(fog.eye.inv_view_proj, ndc, z);
        tau = optical_depth(length(p), dot(p, up));
    } else {
        // The sky (reversed-Z: 0 is infinitely far): rising rays leave the
        // fog; level ones never do.
        let dir = normalize(unproject(fog.eye.inv_view_proj, ndc, 1.0));
        let rise = dot(dir, up);
        if rise > 1e-4 {
            let d0 = fog.params.x;
            let h = fog.params.y;
            tau = d0 * exp(-clamp((fog.eye.up.w - fog.params.z) / h, -80.0, 80.0)) * h / rise;
        } else {
            // Down to the datum where nothing was drawn (the planet beyond
            // the data, seen from afar).
            let he = fog.eye.up.w;
            if he > 1.0 {
                tau = optical_depth(he / max(-rise, 1e-4), -he);
            } else {
                // At or under the datum: as a level ray, into the fog for good.
                tau = 1e4;
            }
        }
    }
    let alpha = 1.0 - exp(-min(tau, 1e4));
    return vec4<f32>(fog.color.rgb, clamp(alpha, 0.0, 1.0));
}
