// What every pass reads (prepended to each pass's shader): the frame's
// uniform and the sun.

struct Frame {
    view_proj: mat4x4<f32>,
    // Direction towards the sun (world axes), w unused.
    sun: vec4<f32>,
    // x ambient, y diffuse, z 1 when the lighting effect is on.
    light: vec4<f32>,
    // The planet's centre from the eye (xyz; direction only, so f32 is
    // plenty), w 1 on the planet, 0 on a flat scene (up is +z).
    centre: vec4<f32>,
    // The eye as double-single parts (for meshes in world positions);
    // eye_low.w is how far the terrain's base is sunk below the levels, in
    // metres.
    eye_high: vec4<f32>,
    eye_low: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> frame: Frame;

fn safe_normalize(v: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    return select(vec3<f32>(0.0), v / l, l > 1e-20);
}

// Ambient plus diffuse sun on a surface facing `normal`, from the
// frame's `sun` and `light` as a vertex stage hands them to its fragments
// (flat inputs): a fragment that read them from the frame's buffer would
// load them in every pixel, and lavapipe loads a storage buffer one lane
// at a time.
fn sunlight(sun: vec4<f32>, light: vec4<f32>, normal: vec3<f32>) -> f32 {
    return light.x + light.y * max(dot(safe_normalize(normal), sun.xyz), 0.0);
}
