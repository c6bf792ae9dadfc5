// Instances: models and camera-facing billboards, one draw per model and
// one for every billboard, positions relative to the eye (an instance is
// never drawn farther than a few kilometres, so f32 keeps millimetres).

// Per instance. pos: position from the eye (xyz), scale (w). east: the
// model's x axis on the ground (rotated), w: where its dither range
// starts. up: the local vertical, w: where it ends. A fragment is kept
// where the pixel's dither value falls in [start, end): a model and its
// billboard cross-fade without gaps or overlap, and a thinned instance
// fades out instead of popping. billboard: half width, bottom and top
// (metres, scaled) and the atlas layer.
struct Instance {
    @location(4) pos: vec4<f32>,
    @location(5) east: vec4<f32>,
    @location(6) up: vec4<f32>,
    @location(7) billboard: vec4<f32>,
}

// Each model's billboard: its colours, and its normals (model axes, as
// 0..1), both with coverage in alpha and premultiplied by it.
@group(0) @binding(1) var atlas: texture_2d_array<f32>;
@group(0) @binding(2) var atlas_sampler: sampler;
@group(0) @binding(3) var normals: texture_2d_array<f32>;

// A 4 x 4 ordered dither, 0..1.
fn dither(pixel: vec4<f32>) -> f32 {
    let m = array<f32, 16>(0.0, 8.0, 2.0, 10.0, 12.0, 4.0, 14.0, 6.0, 3.0, 11.0, 1.0, 9.0, 15.0, 7.0, 13.0, 5.0);
    let x = u32(pixel.x) % 4u;
    let y = u32(pixel.y) % 4u;
    return (m[y * 4u + x] + 0.5) / 16.0;
}

fn kept(pixel: vec4<f32>, start: f32, end: f32) -> bool {
    let d = dither(pixel);
    return d >= start && d < end;
}

struct ModelOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) range: vec2<f32>,
    // The frame's sun and light terms (`sunlight`).
    @location(3) @interpolate(flat) sun: vec4<f32>,
    @location(4) @interpolate(flat) light: vec4<f32>,
    // Where the point is in each shadow cascade, when the frame casts shadows.
    #sun_at_fields 5
}

// glTF axes: x east, y up, z south.
@vertex
fn vs_model(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    inst: Instance,
) -> ModelOut {
    let east = inst.east.xyz;
    let up = inst.up.xyz;
    let south = cross(east, up);
    let local = position.x * east + position.y * up + position.z * south;
    var out: ModelOut;
    let p = inst.pos.xyz + inst.pos.w * local;
    out.clip = frame.view_proj * vec4<f32>(p, 1.0);
    out.normal = normal.x * east + normal.y * up + normal.z * south;
    out.color = color;
    out.range = vec2<f32>(inst.east.w, inst.up.w);
    out.sun = frame.sun;
    out.light = frame.light;
    #sun_at_out p out.normal
    return out;
}

@fragment
fn fs_model(in: ModelOut) -> @location(0) vec4<f32> {
    if !kept(in.clip, in.range.x, in.range.y) {
        discard;
    }
    var light = 1.0;
    if in.light.z > 0.5 {
        #sun_at_in
        light = sunlit(in.sun, in.light, in.normal, at);
    }
    return vec4<f32>(in.color.rgb * light, in.color.a);
}

// The billboard bake's second image: the model's normals, as colours.
@fragment
fn fs_model_normal(in: ModelOut) -> @location(0) vec4<f32> {
    return vec4<f32>(safe_normalize(in.normal) * 0.5 + 0.5, 1.0);
}

struct BillboardOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) layer: u32,
    @location(2) right: vec3<f32>,
    @location(3) up: vec3<f32>,
    @location(4) facing: vec3<f32>,
    @location(5) range: vec2<f32>,
    @location(6) @interpolate(flat) sun: vec4<f32>,
    @location(7) @interpolate(flat) light: vec4<f32>,
    // Where the point is in each shadow cascade, when the frame casts shadows.
    #sun_at_fields 8
}

// Two triangles turning about the local vertical to face the eye.
@vertex
fn vs_billboard(@builtin(vertex_index) vertex: u32, inst: Instance) -> BillboardOut {
    let corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, 0.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let c = corners[vertex];
    let up = inst.up.xyz;
    let to_eye = -inst.pos.xyz;
    var right = cross(up, to_eye);
    if length(right) < 1e-3 * length(to_eye) {
        // Seen from straight above: any horizontal axis will do.
        right = inst.east.xyz;
    }
    right = normalize(right);
    let b = inst.billboard;
    let local = right * (c.x * b.x) + up * mix(b.y, b.z, c.y);
    var out: BillboardOut;
    let p = inst.pos.xyz + local;
    out.clip = frame.view_proj * vec4<f32>(p, 1.0);
    out.uv = vec2<f32>(c.x * 0.5 + 0.5, 1.0 - c.y);
    out.layer = u32(b.w);
    // The model's axes as the billboard shows it: x to the right, y up, z
    // towards the eye (it was rendered looking down its -z).
    out.right = right;
    out.up = up;
    out.facing = normalize(cross(right, up));
    out.range = vec2<f32>(inst.east.w, inst.up.w);
    out.sun = frame.sun;
    out.light = frame.light;
    // The billboard stands in for the model's volume: the point is
    // looked up off its plane, towards the eye.
    #sun_at_out p out.facing
    return out;
}

@fragment
fn fs_billboard(in: BillboardOut) -> @location(0) vec4<f32> {
    let texel = textureSample(atlas, atlas_sampler, in.uv, in.layer);
    if texel.a < 0.5 || !kept(in.clip, in.range.x, in.range.y) {
        discard;
    }
    var light = 1.0;
    if in.light.z > 0.5 {
        // Lit per texel as the model is, from the normals it was baked with.
        let baked = textureSample(normals, atlas_sampler, in.uv, in.layer);
        let n = baked.xyz / max(baked.a, 1e-3) * 2.0 - 1.0;
        #sun_at_in
        light = sunlit(in.sun, in.light, n.x * in.right + n.y * in.up + n.z * in.facing, at);
    }
    return vec4<f32>(texel.rgb / texel.a * light, 1.0);
}
