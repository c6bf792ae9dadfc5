// The shadows' overlay: each drawn pixel's point and facet normal from the
// depth, and the sunlight the cascades say is hidden taken away from it
// (the frame multiplied by (ambient + diffuse x visible) / (ambient +
// diffuse), the lighting's own terms).

struct ShadowView {
    eye: Eye,
    // Filter radius in texels (x).
    params: vec4<f32>,
}

@group(0) @binding(1) var<uniform> shade: ShadowView;
@group(0) @binding(2) var depth: texture_depth_2d;

// The drawn point at pixel `px` relative to the eye (xyz), w 1 where
// something was drawn.
fn drawn_at(px: vec2<i32>, size: vec2<i32>) -> vec4<f32> {
    let at = clamp(px, vec2<i32>(0), size - vec2<i32>(1));
    let z = textureLoad(depth, at, 0);
    let ndc = ndc_of(vec2<f32>(at) + vec2<f32>(0.5), vec2<f32>(size));
    return vec4<f32>(unproject(shade.eye.inv_view_proj, ndc, max(z, 1e-30)), select(0.0, 1.0, z > 0.0));
}

// The side of a pixel towards a neighbour: the nearer of the two (so a
// silhouette does not bend the normal).
fn side(c: vec4<f32>, before: vec4<f32>, after: vec4<f32>) -> vec3<f32> {
    let forward = after.xyz - c.xyz;
    let back = c.xyz - before.xyz;
    if after.w < 0.5 || (before.w > 0.5 && length(back) < length(forward)) {
        return back;
    }
    return forward;
}

@fragment
fn fs(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let size = vec2<i32>(textureDimensions(depth));
    let px = vec2<i32>(frag.xy);
    let c = drawn_at(px, size);
    if c.w < 0.5 {
        return vec4<f32>(1.0);
    }
    let dx = side(c, drawn_at(px - vec2<i32>(1, 0), size), drawn_at(px + vec2<i32>(1, 0), size));
    let dy = side(c, drawn_at(px - vec2<i32>(0, 1), size), drawn_at(px + vec2<i32>(0, 1), size));
    var n = safe_normalize(cross(dx, dy));
    if dot(n, c.xyz) > 0.0 {
        n = -n;
    }
    let ambient = frame.light.x;
    let diffuse = frame.light.y * max(dot(n, frame.sun.xyz), 0.0);
    if diffuse <= 0.0 {
        return vec4<f32>(1.0);
    }
    let seen = sun_visible(c.xyz, n, i32(shade.params.x));
    let f = (ambient + diffuse * seen) / (ambient + diffuse);
    return vec4<f32>(f, f, f, 1.0);
}
