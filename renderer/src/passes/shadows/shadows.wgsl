// The shadows' overlay: each drawn pixel's point from the depth, its
// facet normal from the point's screen derivatives (one depth read a
// pixel), and the sunlight the cascades say is hidden taken away from it:
// the frame multiplied by (ambient + diffuse x visible) / (ambient +
// diffuse), the lighting's own terms. Where the sun is seen the factor is
// 1 whatever the normal, so a wrong one at a silhouette changes little.

struct ShadowView {
    eye: Eye,
    // Filter radius in texels (x).
    params: vec4<f32>,
}

@group(0) @binding(1) var<storage, read> shade: ShadowView;
@group(0) @binding(2) var depth: texture_depth_2d;

@fragment
fn fs(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let size = textureDimensions(depth);
    let z = textureLoad(depth, vec2<i32>(frag.xy), 0);
    let p = unproject(shade.eye.inv_view_proj, ndc_of(frag.xy, vec2<f32>(size)), max(z, 1e-30));
    // Derivatives before any branch (the quad's pixels run together).
    var n = safe_normalize(cross(dpdx(p), dpdy(p)));
    if z <= 0.0 {
        return vec4<f32>(1.0);
    }
    if dot(n, p) > 0.0 {
        n = -n;
    }
    let ambient = frame.light.x;
    let diffuse = frame.light.y * max(dot(n, frame.sun.xyz), 0.0);
    if diffuse <= 0.0 {
        return vec4<f32>(1.0);
    }
    let seen = sun_visible(p, n, i32(shade.params.x));
    let f = (ambient + diffuse * seen) / (ambient + diffuse);
    return vec4<f32>(f, f, f, 1.0);
}
