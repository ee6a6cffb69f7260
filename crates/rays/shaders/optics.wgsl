// Light at a smooth dielectric interface (the rays crate's optics.rs), for the GPU kernels:
// the path tracer's BSDFs (trace-gpu's bsdf.wgsl) and the through pass.

// Unpolarised Fresnel reflectance; cos_i < 0 means from inside (eta = n_inside / n_outside).
fn fresnel_dielectric(cos_in: f32, eta_in: f32) -> f32 {
    var cos_i = cos_in;
    var eta = eta_in;
    if cos_i < 0.0 {
        cos_i = -cos_i;
        eta = 1.0 / eta;
    }
    let sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    let r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular);
}

// Thin slab, all internal reflections: 2R / (1 + R).
fn thin_slab_reflectance(cos_i: f32, eta: f32) -> f32 {
    let r = fresnel_dielectric(abs(cos_i), eta);
    if r >= 1.0 {
        return 1.0;
    }
    return 2.0 * r / (1.0 + r);
}

fn reflect_about(w: vec3f, m: vec3f) -> vec3f {
    return 2.0 * dot(w, m) * m - w;
}

struct Refraction {
    valid: bool,
    wi: vec3f,
    // eta_t / eta_i crossed.
    etap: f32,
}

fn refract_through(w: vec3f, n_in: vec3f, eta_in: f32) -> Refraction {
    var cos_i = dot(n_in, w);
    var n = n_in;
    var eta = eta_in;
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return Refraction(false, vec3f(0.0), 1.0);
    }
    let cos_t = sqrt(1.0 - sin2_t);
    return Refraction(true, -w / eta + (cos_i / eta - cos_t) * n, eta);
}
