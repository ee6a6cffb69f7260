// The form factor of a rectangle light seen from a surface point (direct.rs:
// polygon_form_factor), shared by the through pass and the rasterizer's G-buffer shader.

// z component of the integral of the edge (a, b) of a polygon projected on the unit sphere:
// theta * normalize(a x b).z with theta the angle between a and b.
fn integrate_edge(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let c = cross(a, b);
    let s = length(c);
    if s < 1e-12 {
        return 0.0;
    }
    let theta = atan2(s, dot(a, b));
    return theta * c.z / s;
}

// Form factor (integral of cos/pi over the polygon's solid angle) of the quadrilateral `q`
// in a frame whose +z is the surface normal. Clipped to the upper hemisphere; the sign of
// the winding is removed (the caller decides which side emits).
fn polygon_form_factor(q0: vec3<f32>, q1: vec3<f32>, q2: vec3<f32>, q3: vec3<f32>) -> f32 {
    var q = array<vec3<f32>, 4>(q0, q1, q2, q3);
    var p: array<vec3<f32>, 5>;
    var count = 0u;
    for (var i = 0u; i < 4u; i = i + 1u) {
        let a = q[i];
        let b = q[(i + 1u) % 4u];
        if a.z >= 0.0 {
            p[count] = a;
            count = count + 1u;
        }
        if (a.z >= 0.0) != (b.z >= 0.0) {
            let t = a.z / (a.z - b.z);
            var x = mix(a, b, t);
            x.z = 0.0;
            p[count] = x;
            count = count + 1u;
        }
    }
    if count < 3u {
        return 0.0;
    }
    var sum = 0.0;
    for (var i = 0u; i < count; i = i + 1u) {
        let a = p[i];
        let b = p[(i + 1u) % count];
        let la = length(a);
        let lb = length(b);
        if la > 0.0 && lb > 0.0 {
            sum = sum + integrate_edge(a / la, b / lb);
        }
    }
    // 2 pi
    return abs(sum) / 6.28318530717958;
}

// Rows t1, t2, n: an orthonormal frame with n as its z axis (the clamped-cosine form factor
// does not depend on the rotation about n).
fn frame_around(n: vec3<f32>) -> mat3x3<f32> {
    let a = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(n.x) > 0.9);
    let t1 = normalize(a - n * dot(a, n));
    return transpose(mat3x3<f32>(t1, cross(n, t1), n));
}
