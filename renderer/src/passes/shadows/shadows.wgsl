// The shadows' overlay: each drawn pixel's point from the depth, its
// facet normal from the point's screen derivatives (one depth read a
// pixel), and the sunlight the cascades say is hidden taken away from it:
// the frame multiplied by (ambient + diffuse x visible) / (ambient +
// diffuse), the lighting's own terms. Where the sun is seen the factor is
// 1 whatever the normal, so a wrong one at a silhouette changes little.

struct ShadowView {
    inv_view_proj: mat4x4<f32>,
    // Towards the sun (xyz, world axes), the filter radius in texels (w).
    sun: vec4<f32>,
    // The lighting's ambient (x) and diffuse (y) terms.
    light: vec4<f32>,
}

// This pixel's ShadowView, from the overlay's flat inputs (`fs`).
var<private> shade: ShadowView;
@group(0) @binding(2) var depth: texture_depth_2d;

@fragment
fn fs(input: OverlayIn) -> @location(0) vec4<f32> {
    let v = own_of(input);
    shade = ShadowView(mat4x4<f32>(v[0], v[1], v[2], v[3]), v[4], v[5]);
    begin_shadows(input);
    let frag = input.position;
    let size = textureDimensions(depth);
    let z = textureLoad(depth, vec2<i32>(frag.xy), 0);
    let p = unproject(shade.inv_view_proj, ndc_of(frag.xy, vec2<f32>(size)), max(z, 1e-30));
    // Derivatives before any branch (the quad's pixels run together).
    var n = safe_normalize(cross(dpdx(p), dpdy(p)));
    // The sky, and ground facing away from the sun, keep what was drawn:
    // discarded, not multiplied by 1, so lavapipe skips the lookup for a
    // block of pixels that all leave (it runs both sides of a branch its
    // pixels disagree on, and everything after one they all return from).
    if z <= 0.0 {
        discard;
    }
    if dot(n, p) > 0.0 {
        n = -n;
    }
    let ambient = shade.light.x;
    let diffuse = shade.light.y * max(dot(n, shade.sun.xyz), 0.0);
    if diffuse <= 0.0 {
        discard;
    }
    let seen = sun_visible(p, n, i32(shade.sun.w));
    let f = (ambient + diffuse * seen) / (ambient + diffuse);
    return vec4<f32>(f, f, f, 1.0);
}
