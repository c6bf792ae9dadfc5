// Geometry clipmap terrain and the coarse base under it. Positions reach
// the GPU as f32 offsets from a per-level anchor; the anchor's offset from
// the eye is computed in f64 on the CPU, so nothing here is absolute ECEF.

// Normals face up: a window folded over a pole runs its rows backwards.
// Where there is none (every sample of a pole row is the pole), up itself.
fn upward(normal: vec3<f32>, p: vec3<f32>, centre: vec4<f32>) -> vec3<f32> {
    var up = vec3<f32>(0.0, 0.0, 1.0);
    if centre.w > 0.5 {
        up = normalize(p - centre.xyz);
    }
    let n = safe_normalize(normal);
    if dot(n, n) < 0.5 {
        return up;
    }
    return select(n, -n, dot(n, up) < 0.0);
}

struct Level {
    // Anchor minus eye (xyz).
    offset: vec4<f32>,
    // Window origin (global samples), texture layer, n.
    window: vec4<i32>,
    // Coarser level: window origin, layer, 1 when it exists.
    coarse: vec4<i32>,
    // Camera in window samples (xy), transition width, 1 when outermost.
    blend: vec4<f32>,
}

// A level's draws read it, and its coarser level's place, as an
// instance-rate vertex record (the instance is the level's slot): a
// storage buffer would be loaded lane by lane for every vertex on
// lavapipe.
struct LevelIn {
    @location(0) offset: vec4<f32>,
    @location(1) window: vec4<i32>,
    @location(2) coarse: vec4<i32>,
    @location(3) blend: vec4<f32>,
    @location(4) coarse_offset: vec4<f32>,
    @location(5) coarse_window: vec4<i32>,
    // The frame's view-projection (or a shadow cascade's), centre, sun and
    // light (as `frame.wgsl`'s).
    @location(6) view_proj0: vec4<f32>,
    @location(7) view_proj1: vec4<f32>,
    @location(8) view_proj2: vec4<f32>,
    @location(9) view_proj3: vec4<f32>,
    @location(10) centre: vec4<f32>,
    @location(11) sun: vec4<f32>,
    @location(12) light: vec4<f32>,
}

fn view_proj_of(r: LevelIn) -> mat4x4<f32> {
    return mat4x4<f32>(r.view_proj0, r.view_proj1, r.view_proj2, r.view_proj3);
}

fn level_of(r: LevelIn) -> Level {
    return Level(r.offset, r.window, r.coarse, r.blend);
}

// The coarser level as far as `coarse_at` reads it.
fn coarser_of(r: LevelIn) -> Level {
    return Level(r.coarse_offset, r.coarse_window, vec4<i32>(0), vec4<f32>(0.0));
}
@group(0) @binding(2) var positions: texture_2d_array<f32>;
@group(0) @binding(3) var colors: texture_2d_array<f32>;
@group(0) @binding(4) var linear: sampler;
// Each level's normals, worked out on the CPU where samples change
// (`clipmap/normals.rs`): cross(south, east) of a sample's neighbours.
@group(0) @binding(5) var normals: texture_2d_array<f32>;

struct Out {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) uv_coarse: vec2<f32>,
    @location(3) alpha: f32,
    @location(4) valid: f32,
    @location(5) @interpolate(flat) layers: vec2<i32>,
    // The frame's sun and light terms (`sunlight`).
    @location(6) @interpolate(flat) sun: vec4<f32>,
    @location(7) @interpolate(flat) light: vec4<f32>,
    // Where the point is in each shadow cascade, when the frame casts shadows.
    #sun_at_fields 8
}

fn wrap(g: i32, n: i32) -> i32 {
    return ((g % n) + n) % n;
}

fn load(lv: Level, i: i32, j: i32) -> vec4<f32> {
    let n = lv.window.w;
    let ii = clamp(i, 0, n - 1);
    let jj = clamp(j, 0, n - 1);
    return textureLoad(positions, vec2<i32>(wrap(lv.window.x + ii, n), wrap(lv.window.y + jj, n)), lv.window.z, 0);
}

// The stored normal of a level's sample by its global index.
fn normal_of(lv: Level, gx: i32, gy: i32) -> vec3<f32> {
    let n = lv.window.w;
    return textureLoad(normals, vec2<i32>(wrap(gx, n), wrap(gy, n)), lv.window.z, 0).xyz;
}

// The coarser level's normal under fine sample (gx, gy), as `coarse_at`
// takes its surface: its own sample's where both indices are even, else
// the mean of the two ends of the coarse edge (or diagonal) it lies on.
fn coarse_normal(c: Level, gx: i32, gy: i32) -> vec3<f32> {
    let x0 = gx >> 1u;
    let y0 = gy >> 1u;
    let x1 = x0 + (gx & 1);
    let y1 = y0 + (gy & 1);
    return safe_normalize(normal_of(c, x0, y0) + normal_of(c, x1, y1));
}

// A sample of a level by its global index (storage is toroidal: the
// index modulo n), relative to the eye.
fn sample_at(lv: Level, gx: i32, gy: i32) -> vec3<f32> {
    let n = lv.window.w;
    return textureLoad(positions, vec2<i32>(wrap(gx, n), wrap(gy, n)), lv.window.z, 0).xyz + lv.offset.xyz;
}

// The coarser level's surface under fine sample (gx, gy): its own sample
// where both indices are even, else the midpoint of the coarse edge (or
// the north-west to south-east diagonal) the fine sample lies on.
fn coarse_at(c: Level, gx: i32, gy: i32) -> vec3<f32> {
    let x0 = gx >> 1u;
    let y0 = gy >> 1u;
    let odd_x = (gx & 1) == 1;
    let odd_y = (gy & 1) == 1;
    if odd_x && odd_y {
        return 0.5 * (sample_at(c, x0, y0) + sample_at(c, x0 + 1, y0 + 1));
    } else if odd_x {
        return 0.5 * (sample_at(c, x0, y0) + sample_at(c, x0 + 1, y0));
    } else if odd_y {
        return 0.5 * (sample_at(c, x0, y0) + sample_at(c, x0, y0 + 1));
    }
    return sample_at(c, x0, y0);
}

// A level's vertex: where it is drawn (relative to the eye) and how far
// it has blended onto the coarser level.
struct Placed {
    p: vec3<f32>,
    alpha: f32,
}

// Transition (Losasso & Hoppe): towards the coarser level's own surface
// near the window's edge, exactly onto it at the outer ring, so no cracks;
// alpha follows the camera continuously, so no popping.
fn place(lv: Level, c: Level, i: i32, j: i32) -> Placed {
    let n = lv.window.w;
    let half = f32(n - 1) * 0.5;
    let w = lv.blend.z;
    let d = max(abs(f32(i) - lv.blend.x), abs(f32(j) - lv.blend.y));
    var alpha = clamp((d - (half - w - 1.0)) / w, 0.0, 1.0);
    if i == 0 || j == 0 || i == n - 1 || j == n - 1 {
        alpha = 1.0;
    }
    let fine = load(lv, i, j).xyz + lv.offset.xyz;
    if lv.coarse.w != 1 {
        return Placed(fine, 0.0);
    }
    return Placed(mix(fine, coarse_at(c, lv.window.x + i, lv.window.y + j), alpha), alpha);
}

// Where a level's vertex is drawn, and nothing else: for shadow maps.
@vertex
fn vs_level_depth(@builtin(vertex_index) vi: u32, record: LevelIn) -> @builtin(position) vec4<f32> {
    let lv = level_of(record);
    let n = lv.window.w;
    return view_proj_of(record) * vec4<f32>(place(lv, coarser_of(record), i32(vi) % n, i32(vi) / n).p, 1.0);
}

@vertex
fn vs_level(@builtin(vertex_index) vi: u32, record: LevelIn) -> Out {
    let lv = level_of(record);
    let c = coarser_of(record);
    let n = lv.window.w;
    let i = i32(vi) % n;
    let j = i32(vi) / n;
    let gx = lv.window.x + i;
    let gy = lv.window.y + j;
    let here = load(lv, i, j);
    let placed = place(lv, c, i, j);
    let p = placed.p;
    let alpha = placed.alpha;
    var normal = normal_of(lv, gx, gy);
    if lv.coarse.w == 1 {
        normal = mix(normal, coarse_normal(c, gx, gy), alpha);
    }
    var out: Out;
    out.clip = view_proj_of(record) * vec4<f32>(p, 1.0);
    out.normal = upward(normal, p, record.centre);
    // Colour windows hold COLOR_DETAIL (d) samples per geometry sample,
    // from origin d x the window's, in textures dn a side (toroidal too).
    let d = COLOR_DETAIL;
    let cn = d * n;
    let u = f32(wrap(d * lv.window.x, cn) + d * i) + 0.5;
    let v = f32(wrap(d * lv.window.y, cn) + d * j) + 0.5;
    out.uv = vec2<f32>(u, v) / f32(cn);
    // This vertex in the coarser level's colour samples, which are d / 2
    // to each of this level's geometry samples: index (gx, gy) d / 2.
    let half = f32(d) * 0.5;
    let cu = f32(wrap(d * lv.coarse.x, cn)) + f32(gx) * half - f32(d * lv.coarse.x) + 0.5;
    let cv = f32(wrap(d * lv.coarse.y, cn)) + f32(gy) * half - f32(d * lv.coarse.y) + 0.5;
    out.uv_coarse = vec2<f32>(cu, cv) / f32(cn);
    out.alpha = alpha;
    out.valid = here.w;
    out.layers = vec2<i32>(lv.window.z, select(lv.window.z, lv.coarse.z, lv.coarse.w == 1));
    out.sun = record.sun;
    out.light = record.light;
    #sun_at_out p out.normal
    return out;
}

// `at`: where the point is in the shadow cascades (`sunlit`).
fn shade(base: vec4<f32>, normal: vec3<f32>, sun: vec4<f32>, light_terms: vec4<f32>, at: array<vec4<f32>, 4>) -> vec4<f32> {
    // Colour (premultiplied) over the light grey of samples without any:
    // a texel partly covered, beside nodata or at a polygon's edge, is
    // drawn partly grey, never darkened towards its neighbour's black.
    let albedo = base.rgb + (1.0 - base.a) * vec3<f32>(0.78, 0.78, 0.76);
    var light = 1.0;
    if light_terms.z > 0.5 {
        light = sunlit(sun, light_terms, normal, at);
    }
    return vec4<f32>(albedo * light, 1.0);
}

@fragment
fn fs_level(in: Out) -> @location(0) vec4<f32> {
    if in.valid < 0.5 {
        discard;
    }
    let fine = textureSampleLevel(colors, linear, in.uv, in.layers.x, 0.0);
    let coarse = textureSampleLevel(colors, linear, in.uv_coarse, in.layers.y, 0.0);
    #sun_at_in
    return shade(mix(fine, coarse, in.alpha), in.normal, in.sun, in.light, at);
}

struct BaseOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) valid: f32,
    @location(3) @interpolate(flat) sun: vec4<f32>,
    @location(4) @interpolate(flat) light: vec4<f32>,
    // Where the point is in each shadow cascade, when the frame casts shadows.
    #sun_at_fields 5
}

// The base: a coarse grid of the whole scene with double-single positions
// (Cozzi & Ring's GPU relative-to-eye), the eye subtracted in two steps. A
// reference mesh comes already relative to the eye (eye parts zero).
@vertex
fn vs_base(
    @location(0) high: vec4<f32>,
    @location(1) low: vec4<f32>,
    @location(2) normal: vec4<f32>,
    @location(3) color: vec4<f32>,
) -> BaseOut {
    var out: BaseOut;
    let p = (high.xyz - frame.eye_high.xyz) + (low.xyz - frame.eye_low.xyz) - normal.xyz * frame.eye_low.w;
    out.clip = frame.view_proj * vec4<f32>(p, 1.0);
    out.normal = normal.xyz;
    out.color = color;
    out.valid = high.w;
    out.sun = frame.sun;
    out.light = frame.light;
    #sun_at_out p normal.xyz
    return out;
}

@fragment
fn fs_base(in: BaseOut) -> @location(0) vec4<f32> {
    if in.valid < 0.5 {
        discard;
    }
    #sun_at_in
    return shade(in.color, in.normal, in.sun, in.light, at);
}
