// The cascades for a full-screen pass (the atmosphere's in-scattering):
// the table from the overlay's flat inputs, and any point of a view ray
// placed in the finest cascade holding it.

var<private> shadow_table: array<vec4<f32>, 9>;

// Takes this pixel's cascades from the overlay's flat inputs.
fn begin_shadows(input: OverlayIn) {
    shadow_table = table_of(input);
}

// Where eye-relative point p (in the air: no normal) falls in the finest
// cascade holding it. Only the `CASCADES` the pass was built for are
// placed (a constant its pass declares, so the others are compiled out:
// placing points in all 4 slots when the default 2 were in use cost
// 0.5-3 ms more on lavapipe).
fn shadow_place(p: vec3<f32>) -> vec4<f32> {
    return finest_place(cascade_places(shadow_table, p, vec3<f32>(0.0)));
}

// Whether the sun reaches eye-relative point p, 0 or 1, from the one
// texel under it, unfiltered: for many samples a pixel averages anyway
// (the air's in-scattering), a quarter of a filtered comparison's reads.
fn sun_visible_texel(p: vec3<f32>) -> f32 {
    let at = shadow_place(p);
    if at.w < 0.0 {
        return 1.0;
    }
    let side = i32(shadow_table[2].w);
    let texel = clamp(vec2<i32>(at.xy * f32(side)), vec2<i32>(0), vec2<i32>(side - 1));
    return select(0.0, 1.0, at.z >= textureLoad(shadow_maps, texel, i32(at.w), 0));
}
