// Shadows received where they fall: the lit passes (terrain, buildings,
// instances) place each vertex in the cascades (`sun_coords`, linear in
// the point, so the triangle's setup interpolates it exactly) and each
// pixel takes the sunlight the maps hide from the lighting's diffuse
// term (`sunlit`). One lookup a lit pixel inside the passes that draw it,
// where a full-screen pass over the frame had first to find the point
// again from the depth.

// The table is read by the vertex stage alone (lavapipe loads a storage
// buffer one lane at a time; the fragments get what it says as inputs).
@group(1) @binding(0) var<storage, read> sun_table: array<vec4<f32>, 9>;

// Eye-relative point p, its surface facing `n`, in each cascade the pass
// was built for (`cascade_places`): for the vertex stage.
fn sun_coords(p: vec3<f32>, n: vec3<f32>) -> array<vec4<f32>, 4> {
    return cascade_places(sun_table, p, n);
}

// How much of the sun reaches the pixel whose cascade places are `c`:
// 1 lit, 0 hidden, from the comparison sampler's 2 x 2 filter.
fn sun_seen(c: array<vec4<f32>, 4>) -> f32 {
    let place = finest_place(c);
    if place.w < 0.0 {
        return 1.0;
    }
    return textureSampleCompareLevel(shadow_maps, shadow_test, place.xy, i32(place.w), place.z);
}

// The lighting (`sunlight`) with the diffuse term's hidden part taken
// away; ground facing away from the sun looks nothing up.
fn sunlit(sun: vec4<f32>, light: vec4<f32>, normal: vec3<f32>, c: array<vec4<f32>, 4>) -> f32 {
    let diffuse = light.y * max(dot(safe_normalize(normal), sun.xyz), 0.0);
    if diffuse <= 0.0 {
        return light.x;
    }
    return light.x + diffuse * sun_seen(c);
}
