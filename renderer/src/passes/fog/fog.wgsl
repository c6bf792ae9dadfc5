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
    // Density at the base height per metre (x), falloff height H (y), the
    // eye's height above the base in falloff heights (z), and the density
    // at the eye (w; the eye's end of every ray, worked out once a frame).
    params: vec4<f32>,
    // Colour (rgb), lit by the daylight already.
    color: vec4<f32>,
}

// This pixel's Fog, from the overlay's flat inputs (`fs`).
var<private> fog: Fog;
@group(0) @binding(2) var depth: texture_depth_2d;

// Optical depth along `l` metres of a ray rising `dh` metres: the
// difference of the density at its two ends over the rise (the far end's
// exponent bounded, as the eye's was, so a ray from orbit does not
// overflow).
fn optical_depth(l: f32, dh: f32) -> f32 {
    let k = dh / fog.params.y;
    let end = fog.params.x * exp(-clamp(fog.params.z + k, -80.0, 80.0));
    return select(l * (fog.params.w - end) / k, l * fog.params.w, abs(k) < 1e-4);
}

// One point per pixel, unprojected once: what was drawn there, or for the
// sky (reversed-Z: 0 is infinitely far) a point along its ray. Every
// branch below only picks among values (lavapipe runs both sides of a
// branch its pixels disagree on).
@fragment
fn fs(input: OverlayIn) -> @location(0) vec4<f32> {
    let v = own_of(input);
    fog = Fog(eye_of(v[0], v[1], v[2], v[3], v[4]), v[5], v[6]);
    let frag = input.position;
    let size = vec2<f32>(textureDimensions(depth));
    let z = textureLoad(depth, vec2<i32>(frag.xy), 0);
    let surface = z > 0.0;
    let q = unproject(fog.eye.inv_view_proj, ndc_of(frag.xy, size), select(1.0, z, surface));
    let he = fog.eye.up.w;
    let length_q = length(q);
    let dh_q = dot(q, fog.eye.up.xyz);
    let rise = dh_q / length_q;
    // The sky: a ray that falls ends at the datum where nothing was drawn
    // (the planet beyond the data, seen from afar).
    var tau = optical_depth(select(he / max(-rise, 1e-4), length_q, surface), select(-he, dh_q, surface));
    if !surface {
        if rise > 1e-4 {
            // Rising rays leave the fog.
            tau = fog.params.w * fog.params.y / rise;
        } else if he <= 1.0 {
            // At or under the datum: as a level ray, into the fog for good.
            tau = 1e4;
        }
    }
    let alpha = 1.0 - exp(-min(tau, 1e4));
    return vec4<f32>(fog.color.rgb, clamp(alpha, 0.0, 1.0));
}
