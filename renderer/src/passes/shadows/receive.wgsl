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
// was built for (`cascade_coords`); the slots past `CASCADES` are unused,
// never read by the fragments and so compiled out.
fn sun_coords(p: vec3<f32>, n: vec3<f32>) -> array<vec4<f32>, 4> {
    let count = sun_table[0].w;
    let axes = mat3x3<f32>(sun_table[0].xyz, sun_table[1].xyz, sun_table[2].xyz);
    let l = p * axes;
    let ln = n * axes;
    let near = sun_table[7];
    let depth_per_m = sun_table[8];
    var c = array<vec4<f32>, 4>();
    c[0] = cascade_coords(l, ln, sun_table[3], near.x, depth_per_m.x, 0.0, count);
    if CASCADES > 1u {
        c[1] = cascade_coords(l, ln, sun_table[4], near.y, depth_per_m.y, 1.0, count);
    }
    if CASCADES > 2u {
        c[2] = cascade_coords(l, ln, sun_table[5], near.z, depth_per_m.z, 2.0, count);
    }
    if CASCADES > 3u {
        c[3] = cascade_coords(l, ln, sun_table[6], near.w, depth_per_m.w, 3.0, count);
    }
    return c;
}

// How much of the sun reaches the pixel whose cascade places are `c`:
// 1 lit, 0 hidden, from the comparison sampler's 2 x 2 filter.
fn sun_seen(c: array<vec4<f32>, 4>) -> f32 {
    var place = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    if CASCADES > 3u {
        place = finer_place(place, c[3], 3.0);
    }
    if CASCADES > 2u {
        place = finer_place(place, c[2], 2.0);
    }
    if CASCADES > 1u {
        place = finer_place(place, c[1], 1.0);
    }
    place = finer_place(place, c[0], 0.0);
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
