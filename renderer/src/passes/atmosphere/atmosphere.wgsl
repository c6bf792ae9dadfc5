// Rayleigh and Mie single scattering (Clasen section 7.2, after O'Neil),
// a full-screen pass over the drawn frame. Each pixel's view ray is
// marched in `steps` samples from the eye (or where it enters the
// atmosphere) to the drawn surface (the depth buffer) or to the top of the
// atmosphere. At each sample the sunlight reaching it is attenuated along
// the sun's ray in a single step (the sample's density times its scale
// height and the Chapman function's approximation), none where the planet
// hides the sun. The pixel becomes
//   in-scattered light + transmittance x what was drawn
// (sky and aerial perspective alike), computed for one frame pixel in
// `downsample` to a side and laid over the frame smoothly (`composite`).
// Where the scene casts shadows, air the cascades say the sun does not
// reach scatters none of its light (`sun_visible_texel`).
// Heights come from scalar distances
// and cosines (no f32 positions at planet scale). Over flat ground the
// same model runs over a plane.

struct Atmosphere {
    eye: Eye,
    // Towards the sun (xyz), its intensity (w).
    sun: vec4<f32>,
    // Ground radius (x; 0 over flat ground), top height (y), steps (z),
    // exposure (w).
    params: vec4<f32>,
    // Frame pixels to a side of each texel computed (x), the frame's
    // width and height (yz).
    frame_size: vec4<f32>,
}

// This pixel's Atmosphere, from the overlay's flat inputs (`fs`).
var<private> atmo: Atmosphere;
@group(0) @binding(2) var depth: texture_depth_2d;

const BETA_R = vec3<f32>(5.8e-6, 13.5e-6, 33.1e-6);
const BETA_M = 21.0e-6;
const MIE_EXTINCTION = 1.1;
const H_R = 8000.0;
const H_M = 1200.0;
const G = 0.76;
const PI = 3.14159265;
const FAR = 1.0e9;
// The longest stretch of a view ray marched, metres.
const MAX_MARCH = 400000.0;

// Height at distance t along a ray leaving height h0 with cosine mu to
// the local up.
fn height_at(h0: f32, mu: f32, t: f32) -> f32 {
    let r0 = atmo.params.x;
    if r0 <= 0.0 {
        return h0 + t * mu;
    }
    let r = r0 + h0;
    return sqrt(max(r * r + t * t + 2.0 * r * t * mu, 0.0)) - r0;
}

// Cosine of the angle between the local up and direction `cos_d` (its
// cosine at the ray's origin, height h0) at distance t along a ray with
// cosine mu: directions do not turn over flat ground.
fn cos_at(h0: f32, mu: f32, cos_d0: f32, along: f32, t: f32) -> f32 {
    let r0 = atmo.params.x;
    if r0 <= 0.0 {
        return cos_d0;
    }
    let r = r0 + h0;
    return (r * cos_d0 + t * along) / (height_at(h0, mu, t) + r0);
}

// The Chapman function's grazing-aware approximation: the optical depth
// of an exponential atmosphere (scale height `scale`) from radius-over-
// scale `x` along cosine mu, in units of the vertical depth. Exact at the
// zenith (1) and at the horizon (sqrt(pi x / 2)); 1 / mu over flat ground.
fn chapman(scale: f32, h: f32, mu: f32) -> f32 {
    let r0 = atmo.params.x;
    if r0 <= 0.0 {
        return 1.0 / max(mu, 1e-4);
    }
    let x = (r0 + h) / scale;
    return 1.0 / (0.5 * mu + sqrt(0.25 * mu * mu + 2.0 / (PI * x)));
}

// Whether the ground hides a direction of cosine mu from height h.
fn below_horizon(h: f32, mu: f32) -> bool {
    let r0 = atmo.params.x;
    if r0 <= 0.0 {
        return mu <= 0.0;
    }
    let hh = max(h, 0.0);
    return mu < -sqrt(hh * (2.0 * r0 + hh)) / (r0 + hh);
}

// Where a ray from the eye runs inside the atmosphere, to the ground
// when `to_ground` (nothing drawn there): (start, end), or end < start
// when it never does.
fn inside(h0: f32, mu: f32, to_ground: bool) -> vec2<f32> {
    let top = atmo.params.y;
    let r0 = atmo.params.x;
    if r0 <= 0.0 {
        var span = vec2<f32>(0.0, FAR);
        if h0 > top {
            if mu >= -1e-6 {
                return vec2<f32>(1.0, 0.0);
            }
            span.x = (h0 - top) / -mu;
        } else if mu > 1e-6 {
            span.y = (top - h0) / mu;
        }
        if to_ground && h0 > 0.0 && mu < -1e-6 {
            span.y = min(span.y, h0 / -mu);
        }
        return span;
    }
    let r = r0 + h0;
    let disc = r * r * mu * mu - (h0 - top) * (2.0 * r0 + h0 + top);
    if disc < 0.0 {
        return vec2<f32>(1.0, 0.0);
    }
    let far = -r * mu + sqrt(disc);
    let near = max(-r * mu - sqrt(disc), 0.0);
    if far <= 0.0 {
        return vec2<f32>(1.0, 0.0);
    }
    var end = far;
    let ground = r * r * mu * mu - h0 * (2.0 * r0 + h0);
    if to_ground && h0 > 0.0 && mu < 0.0 && ground > 0.0 {
        end = min(end, -r * mu - sqrt(ground));
    }
    return vec2<f32>(near, end);
}

// One texel of the scattering, computed at the frame pixel under its
// centre: in-scattered light (rgb) and one less the transmittance (a).
// The ray goes through that pixel's own centre, where its depth was
// drawn (with an even downsample the texel's centre is a pixel corner).
@fragment
fn fs(input: OverlayIn) -> @location(0) vec4<f32> {
    let v = own_of(input);
    atmo = Atmosphere(eye_of(v[0], v[1], v[2], v[3], v[4]), v[5], v[6], v[7]);
    begin_shadows(input);
    let frag = input.position;
    let size = atmo.frame_size.yz;
    let at = min(floor(frag.xy * atmo.frame_size.x) + vec2<f32>(0.5), size - vec2<f32>(0.5));
    let ndc = ndc_of(at, size);
    let z = textureLoad(depth, vec2<i32>(at), 0);
    let up = atmo.eye.up.xyz;
    let h0 = atmo.eye.up.w;
    let s = atmo.sun.xyz;
    let ray = view_ray(atmo.eye.inv_view_proj, ndc, z, FAR);
    let dir = ray.xyz;
    let surface = ray.w;
    let mu = dot(dir, up);
    let mu_sun = dot(s, up);
    let along = dot(dir, s);
    var span = inside(h0, mu, z <= 0.0);
    // Past a few hundred kilometres of air nothing more of the sky or the
    // ground shows (a level ray over flat ground never leaves it).
    span.y = min(min(span.y, surface), span.x + MAX_MARCH);
    if span.y <= span.x {
        // Outside the atmosphere all the way: nothing added, nothing dimmed.
        return vec4<f32>(0.0, 0.0, 0.0, 0.0);
    }
    let steps = max(i32(atmo.params.z), 1);
    let ds = (span.y - span.x) / f32(steps);
    var od_r = 0.0;
    var od_m = 0.0;
    var sum_r = vec3<f32>(0.0);
    var sum_m = vec3<f32>(0.0);
    for (var i = 0; i < steps; i = i + 1) {
        let t = span.x + (f32(i) + 0.5) * ds;
        let h = max(height_at(h0, mu, t), 0.0);
        let dens_r = exp(-h / H_R);
        let dens_m = exp(-h / H_M);
        let rho_r = dens_r * ds;
        let rho_m = dens_m * ds;
        // The camera's side: this sample sits halfway through its segment.
        let cam_r = od_r + 0.5 * rho_r;
        let cam_m = od_m + 0.5 * rho_m;
        od_r += rho_r;
        od_m += rho_m;
        let mu_s = cos_at(h0, mu, mu_sun, along, t);
        if below_horizon(h, mu_s) {
            continue;
        }
        // The sun's ray out of the atmosphere in one step (Chapman).
        let sun_r = dens_r * H_R * chapman(H_R, h, mu_s);
        let sun_m = dens_m * H_M * chapman(H_M, h, mu_s);
        let tau = BETA_R * (cam_r + sun_r) + BETA_M * MIE_EXTINCTION * (cam_m + sun_m);
        // Air in the shadow of the terrain (when shadows are cast) gets no
        // sunlight to scatter: one unfiltered texel a sample, the march's
        // samples averaging the shadow's edge.
        let attenuation = exp(-tau) * sun_visible_texel(dir * t);
        sum_r += attenuation * rho_r;
        sum_m += attenuation * rho_m;
    }
    let c = along;
    let phase_r = 3.0 / (16.0 * PI) * (1.0 + c * c);
    let g2 = G * G;
    let phase_m = 3.0 / (8.0 * PI) * ((1.0 - g2) * (1.0 + c * c)) / ((2.0 + g2) * pow(1.0 + g2 - 2.0 * G * c, 1.5));
    let light = atmo.sun.w * (sum_r * BETA_R * phase_r + sum_m * BETA_M * phase_m);
    let shown = vec3<f32>(1.0) - exp(-light * atmo.params.w);
    let transmittance = exp(-(BETA_R * od_r + BETA_M * MIE_EXTINCTION * od_m));
    let through = clamp(dot(transmittance, vec3<f32>(1.0 / 3.0)), 0.0, 1.0);
    // Laid over the frame as light + (1 - alpha) x what was drawn.
    return vec4<f32>(clamp(shown, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0 - through);
}
