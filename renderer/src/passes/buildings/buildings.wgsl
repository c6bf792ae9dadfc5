// Buildings: meshes in world positions as double-single parts (the eye
// subtracted in two steps, as for the terrain's base), each building
// lifted onto the terrain as the frame draws it.

// Per building: the lift onto the drawn terrain (xyz, along the local up)
// and how far its walls reach below their base (xyz).
struct Lift {
    offset: vec4<f32>,
    skirt: vec4<f32>,
}

struct Lifts {
    items: array<Lift>,
}

@group(0) @binding(1) var<storage, read> lifts: Lifts;

struct Out {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    // The frame's sun and light terms (`sunlight`), and its centre.
    @location(2) @interpolate(flat) sun: vec4<f32>,
    @location(3) @interpolate(flat) light: vec4<f32>,
    @location(4) @interpolate(flat) centre: vec4<f32>,
    // The point relative to the eye: surfaces are lit on the side seen.
    @location(5) from_eye: vec3<f32>,
    // Where the point is in each shadow cascade, when the frame casts shadows.
    #sun_at_fields 6
}

// high.w: the building's index in its tile; low.w: 1 at the foot of a wall.
@vertex
fn vs_building(
    @location(0) high: vec4<f32>,
    @location(1) low: vec4<f32>,
    @location(2) normal: vec4<f32>,
    @location(3) color: vec4<f32>,
    @builtin(instance_index) first: u32,
) -> Out {
    let lift = lifts.items[first + u32(high.w)];
    let p = (high.xyz - frame.eye_high.xyz) + (low.xyz - frame.eye_low.xyz) + lift.offset.xyz - lift.skirt.xyz * low.w;
    var out: Out;
    out.clip = frame.view_proj * vec4<f32>(p, 1.0);
    out.normal = normal.xyz;
    out.from_eye = p;
    out.color = color;
    out.sun = frame.sun;
    out.light = frame.light;
    out.centre = frame.centre;
    #sun_at_out p normal.xyz
    return out;
}

@fragment
fn fs_building(in: Out) -> @location(0) vec4<f32> {
    // The side seen: an extruded building's outside, either side of a
    // MultiPatch surface whatever its rings' winding.
    let normal = select(in.normal, -in.normal, dot(in.normal, in.from_eye) > 0.0);
    var light = 1.0;
    if in.light.z > 0.5 {
        #sun_at_in
        light = sunlit(in.sun, in.light, normal, at);
    } else {
        // Unlit scenes still tell walls from roofs: a fixed sky light.
        light = 0.55 + 0.45 * abs(dot(normalize(normal), normalize(-in.centre.xyz * in.centre.w + vec3<f32>(0.0, 0.0, 1.0 - in.centre.w))));
    }
    return vec4<f32>(in.color.rgb * light, 1.0);
}
