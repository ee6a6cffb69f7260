// Scattering at a surface point, the GPU twin of crates/trace/src/{bsdf,microfacet,sampling}.rs.
// Same models, same lobe probabilities, same sampling procedures, so that the GPU tracer
// converges to the CPU tracer's image (the probe test compares them on identical inputs).
// Local shading frame: normal = +z pointing outside; wo towards the camera, wi towards the
// light; eval returns f in radiance form.
//
// WGSL leaves the results of arithmetic on infinities indeterminate, so where the CPU code
// lets a value become infinite (Smith's Lambda at grazing angles) this code branches instead.

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;
const FRAC_1_PI: f32 = 0.318309886183791;
const FLT_MAX: f32 = 3.40282e38;

// DIELECTRIC_F0 (glTF's dielectric base, IOR 1.5), MIN_OPAQUE_ALPHA (the opaque lobes'
// smallest alpha), MIN_ALPHA (GGX's smallest) and SMOOTH_ROUGHNESS (below which a dielectric
// is smooth) are the CPU tracer's, written before this file from Rust (`shared_constants`).

const DIELECTRIC_NONE: u32 = 0u;
const DIELECTRIC_SMOOTH: u32 = 1u;
const DIELECTRIC_ROUGH: u32 = 2u;
const DIELECTRIC_THIN_SMOOTH: u32 = 3u;
const DIELECTRIC_THIN_ROUGH: u32 = 4u;

fn is_finite_f32(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn is_finite_vec3(v: vec3f) -> bool {
    return is_finite_f32(v.x) && is_finite_f32(v.y) && is_finite_f32(v.z);
}

fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

fn max_element(v: vec3f) -> f32 {
    return max(v.x, max(v.y, v.z));
}

fn sign_nonzero(x: f32) -> f32 {
    return select(-1.0, 1.0, x > 0.0);
}

// ---- sampling (crates/trace/src/sampling.rs) ----

struct Frame {
    t: vec3f,
    b: vec3f,
    n: vec3f,
}

// Duff et al. 2017, "Building an Orthonormal Basis, Revisited".
fn frame_from_normal(n: vec3f) -> Frame {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return Frame(vec3f(1.0 + s * n.x * n.x * a, s * b, -s * n.x), vec3f(b, s + n.y * n.y * a, -n.y), n);
}

fn to_local(f: Frame, v: vec3f) -> vec3f {
    return vec3f(dot(v, f.t), dot(v, f.b), dot(v, f.n));
}

fn to_world(f: Frame, v: vec3f) -> vec3f {
    return f.t * v.x + f.b * v.y + f.n * v.z;
}

// Shirley & Chiu 1997.
fn concentric_disk(u: vec2f) -> vec2f {
    let p = 2.0 * u - vec2f(1.0);
    if p.x == 0.0 && p.y == 0.0 {
        return vec2f(0.0);
    }
    var r: f32;
    var theta: f32;
    if abs(p.x) > abs(p.y) {
        r = p.x;
        theta = 0.25 * PI * (p.y / p.x);
    } else {
        r = p.y;
        theta = 0.5 * PI - 0.25 * PI * (p.x / p.y);
    }
    return r * vec2f(cos(theta), sin(theta));
}

fn cosine_hemisphere(u: vec2f) -> vec3f {
    let d = concentric_disk(u);
    return vec3f(d.x, d.y, sqrt(max(1.0 - dot(d, d), 0.0)));
}

fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    return max(cos_theta, 0.0) * FRAC_1_PI;
}

fn uniform_triangle(u: vec2f) -> vec2f {
    let s = sqrt(u.x);
    return vec2f(1.0 - s, u.y * s);
}

// Veach's power heuristic, exponent 2; `other` may be "infinite" (a delta strategy), which
// callers pass as FLT_MAX.
fn power_heuristic(pdf_this: f32, pdf_other: f32) -> f32 {
    if pdf_this <= 0.0 {
        return 0.0;
    }
    if pdf_other >= 1e18 {
        return 0.0;
    }
    if pdf_this >= 1e18 {
        return 1.0;
    }
    let a = pdf_this * pdf_this;
    let b = pdf_other * pdf_other;
    return a / (a + b);
}

// ---- microfacet (crates/trace/src/microfacet.rs) ----

fn ggx_alpha(alpha: f32) -> f32 {
    return max(alpha, MIN_ALPHA);
}

// Walter et al. 2007, eq. 33.
fn ggx_d(alpha: f32, m: vec3f) -> f32 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = m.z * m.z * (a2 - 1.0) + 1.0;
    return a2 / (PI * t * t);
}

// Smith Lambda for GGX (Heitz 2014); only called with w.z != 0.
fn ggx_lambda(alpha: f32, w: vec3f) -> f32 {
    let cos2 = w.z * w.z;
    let tan2 = max(1.0 - cos2, 0.0) / cos2;
    return 0.5 * (-1.0 + sqrt(1.0 + alpha * alpha * tan2));
}

fn ggx_g1(alpha: f32, w: vec3f) -> f32 {
    if w.z == 0.0 {
        return 0.0;
    }
    return 1.0 / (1.0 + ggx_lambda(alpha, w));
}

// Height-correlated masking-shadowing (Heitz 2014, eq. 99).
fn ggx_g2(alpha: f32, wo: vec3f, wi: vec3f) -> f32 {
    if wo.z == 0.0 || wi.z == 0.0 {
        return 0.0;
    }
    return 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
}

fn ggx_visible_pdf(alpha: f32, wo: vec3f, m: vec3f) -> f32 {
    if wo.z == 0.0 {
        return 0.0;
    }
    return ggx_g1(alpha, wo) * abs(dot(wo, m)) * ggx_d(alpha, m) / abs(wo.z);
}

// Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4); wo.z > 0.
fn ggx_sample_visible(alpha: f32, wo: vec3f, u: vec2f) -> vec3f {
    let vh = normalize(vec3f(alpha * wo.x, alpha * wo.y, wo.z));
    let len2 = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3f(1.0, 0.0, 0.0);
    if len2 > 0.0 {
        t1 = vec3f(-vh.y, vh.x, 0.0) / sqrt(len2);
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = TAU * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return normalize(vec3f(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-6)));
}

fn schlick_factor(cos: f32) -> f32 {
    let m = 1.0 - clamp(cos, 0.0, 1.0);
    let m2 = m * m;
    return m2 * m2 * m;
}

// Schlick 1994 with a colour F0 (glTF metallic-roughness).
fn schlick(f0: vec3f, cos: f32) -> vec3f {
    return f0 + (vec3f(1.0) - f0) * schlick_factor(cos);
}

// fresnel_dielectric, thin_slab_reflectance, reflect_about and refract_through are the rays
// crate's shaders/optics.wgsl, prepended with this file.


// ---- the BSDF (crates/trace/src/bsdf.rs) ----

// Material parameters at a point, textures applied; transmission_weight 0 = no transmission.
struct SurfaceMaterial {
    base_color: vec3f,
    roughness: f32,
    metallic: f32,
    specular: f32,
    specular_color: vec3f,
    transmission_weight: f32,
    ior: f32,
    thin: bool,
}

struct Bsdf {
    frame: Frame,
    base_color: vec3f,
    alpha: f32,
    lambertian: bool,
    base_weight: f32,
    specular_f0: vec3f,
    specular_weight: f32,
    metal_weight: f32,
    glass_weight: f32,
    dielectric: u32,
    eta: f32,
    tint: vec3f,
    glass_alpha: f32,
}

fn make_bsdf(m: SurfaceMaterial, normal: vec3f, lambertian: bool) -> Bsdf {
    var bsdf: Bsdf;
    bsdf.frame = frame_from_normal(normal);
    bsdf.base_color = max(m.base_color, vec3f(0.0));
    let roughness = clamp(m.roughness, 0.0, 1.0);
    bsdf.alpha = ggx_alpha(max(roughness * roughness, MIN_OPAQUE_ALPHA));
    bsdf.lambertian = lambertian;
    bsdf.dielectric = DIELECTRIC_NONE;
    bsdf.eta = 1.5;
    bsdf.tint = bsdf.base_color;
    bsdf.glass_alpha = ggx_alpha(roughness * roughness);
    if lambertian {
        bsdf.base_weight = 1.0;
        bsdf.specular_f0 = vec3f(0.0);
        bsdf.specular_weight = 0.0;
        bsdf.metal_weight = 0.0;
        bsdf.glass_weight = 0.0;
        return bsdf;
    }
    let metallic = clamp(m.metallic, 0.0, 1.0);
    var transmission = 0.0;
    if m.transmission_weight > 0.0 {
        transmission = min(m.transmission_weight, 1.0);
        if m.ior > 0.0 && is_finite_f32(m.ior) {
            bsdf.eta = m.ior;
        }
        let smooth_surface = roughness < SMOOTH_ROUGHNESS;
        if m.thin {
            bsdf.dielectric = select(DIELECTRIC_THIN_ROUGH, DIELECTRIC_THIN_SMOOTH, smooth_surface);
        } else {
            bsdf.dielectric = select(DIELECTRIC_ROUGH, DIELECTRIC_SMOOTH, smooth_surface);
        }
    }
    bsdf.base_weight = (1.0 - metallic) * (1.0 - transmission);
    bsdf.specular_f0 = min(DIELECTRIC_F0 * max(m.specular_color, vec3f(0.0)), vec3f(1.0));
    bsdf.specular_weight = clamp(m.specular, 0.0, 1.0);
    bsdf.metal_weight = metallic;
    bsdf.glass_weight = (1.0 - metallic) * transmission;
    return bsdf;
}

fn dielectric_is_delta(d: u32) -> bool {
    return d == DIELECTRIC_SMOOTH || d == DIELECTRIC_THIN_SMOOTH;
}

fn bsdf_has_non_delta(b: Bsdf) -> bool {
    return b.base_weight > 0.0 || b.metal_weight > 0.0
        || (b.glass_weight > 0.0 && b.dielectric != DIELECTRIC_NONE && !dielectric_is_delta(b.dielectric));
}

// Probabilities of the diffuse, base specular, conductor and dielectric lobes.
fn lobe_probabilities(b: Bsdf, wo: vec3f) -> vec4f {
    if b.lambertian {
        return vec4f(1.0, 0.0, 0.0, 0.0);
    }
    let fresnel = b.specular_weight * max_element(schlick(b.specular_f0, abs(wo.z)));
    let diffuse = b.base_weight * (1.0 - fresnel) * luminance(b.base_color);
    let specular = b.base_weight * fresnel;
    let glass = select(b.glass_weight, 0.0, b.dielectric == DIELECTRIC_NONE);
    let p = vec4f(diffuse, specular, b.metal_weight, glass);
    let sum = p.x + p.y + p.z + p.w;
    if sum > 0.0 {
        return p / sum;
    }
    return vec4f(0.0);
}

// f and pdf of the non-delta lobes, local frame; .w of the result is the pdf.
fn bsdf_eval_pdf_local(b: Bsdf, wo: vec3f, wi: vec3f) -> vec4f {
    if wo.z == 0.0 || wi.z == 0.0 {
        return vec4f(0.0);
    }
    let p = lobe_probabilities(b, wo);
    var f = vec3f(0.0);
    var pdf = 0.0;
    if wo.z * wi.z > 0.0 {
        let o = vec3f(wo.x, wo.y, abs(wo.z));
        let i = vec3f(wi.x, wi.y, abs(wi.z));
        pdf += p.x * cosine_hemisphere_pdf(i.z);
        if b.lambertian {
            return vec4f(b.base_color * FRAC_1_PI, pdf);
        }
        let hsum = o + i;
        let hlen = length(hsum);
        let opaque = b.base_weight > 0.0 || b.metal_weight > 0.0;
        if hlen > 0.0 && (opaque || p.y + p.z > 0.0) {
            let h = hsum / hlen;
            let d = ggx_d(b.alpha, h);
            let cos_oh = dot(o, h);
            if opaque {
                let specular = d * ggx_g2(b.alpha, o, i) / (4.0 * o.z * i.z);
                if b.base_weight > 0.0 {
                    // The diffuse part is weighted by 1 - F(wo.n) (see bsdf.rs).
                    let diffuse_fresnel = b.specular_weight * max_element(schlick(b.specular_f0, o.z));
                    let specular_fresnel = schlick(b.specular_f0, cos_oh) * b.specular_weight;
                    f += b.base_weight * ((1.0 - diffuse_fresnel) * b.base_color * FRAC_1_PI + specular_fresnel * specular);
                }
                if b.metal_weight > 0.0 {
                    f += b.metal_weight * schlick(b.base_color, cos_oh) * specular;
                }
            }
            pdf += (p.y + p.z) * ggx_g1(b.alpha, o) * d / (4.0 * o.z);
        }
    }
    if b.glass_weight > 0.0 {
        let fd = eval_pdf_dielectric(b, wo, wi);
        f += b.glass_weight * fd.xyz;
        pdf += p.w * fd.w;
    }
    return vec4f(f, pdf);
}

fn eval_pdf_dielectric(b: Bsdf, wo: vec3f, wi: vec3f) -> vec4f {
    if b.dielectric == DIELECTRIC_ROUGH {
        // The microfacet normal that scatters wo into wi (dielectric_half_vector in bsdf.rs).
        let reflect_event = wo.z * wi.z > 0.0;
        var etap = 1.0;
        if !reflect_event {
            etap = select(1.0 / b.eta, b.eta, wo.z > 0.0);
        }
        var m = wi * etap + wo;
        if dot(m, m) == 0.0 {
            return vec4f(0.0);
        }
        m = normalize(m);
        if m.z < 0.0 {
            m = -m;
        }
        if dot(m, wi) * wi.z <= 0.0 || dot(m, wo) * wo.z <= 0.0 {
            return vec4f(0.0);
        }
        let reflectance = fresnel_dielectric(dot(wo, m), b.eta);
        let d = ggx_d(b.glass_alpha, m);
        let g = ggx_g2(b.glass_alpha, wo, wi);
        let visible = ggx_visible_pdf(b.glass_alpha, wo, m);
        if reflect_event {
            let value = d * g * reflectance / abs(4.0 * wi.z * wo.z);
            return vec4f(vec3f(value), visible / (4.0 * abs(dot(wo, m))) * reflectance);
        }
        // Walter et al. 2007, eq. 21 (radiance form) and the Jacobian of eq. 17.
        let denom = dot(wi, m) * etap + dot(wo, m);
        let value = d * g * (1.0 - reflectance) * abs(dot(wi, m) * dot(wo, m) / (wi.z * wo.z)) / (denom * denom);
        let pdf_denom = dot(wi, m) + dot(wo, m) / etap;
        let pdf = visible * abs(dot(wi, m)) / (pdf_denom * pdf_denom) * (1.0 - reflectance);
        return vec4f(b.tint * value, pdf);
    }
    if b.dielectric == DIELECTRIC_THIN_ROUGH {
        let side = sign_nonzero(wo.z);
        let o = vec3f(wo.x, wo.y, wo.z * side);
        let transmitted = wo.z * wi.z < 0.0;
        let i = vec3f(wi.x, wi.y, select(wi.z * side, -wi.z * side, transmitted));
        let hsum = o + i;
        let hlen = length(hsum);
        if hlen == 0.0 {
            return vec4f(0.0);
        }
        let h = hsum / hlen;
        let d = ggx_d(b.glass_alpha, h);
        let lobe = d * ggx_g2(b.glass_alpha, o, i) / (4.0 * o.z * i.z);
        let lobe_pdf = ggx_g1(b.glass_alpha, o) * d / (4.0 * o.z);
        let reflectance = thin_slab_reflectance(dot(o, h), b.eta);
        if transmitted {
            return vec4f(b.tint * (lobe * (1.0 - reflectance)), lobe_pdf * (1.0 - reflectance));
        }
        return vec4f(vec3f(lobe * reflectance), lobe_pdf * reflectance);
    }
    return vec4f(0.0);
}

fn bsdf_eval_pdf(b: Bsdf, wo: vec3f, wi: vec3f) -> vec4f {
    return bsdf_eval_pdf_local(b, to_local(b.frame, wo), to_local(b.frame, wi));
}

// Straight through a smooth thin pane: (attenuation rgb, probability that sampling picks
// it); probability < 0 when the surface is not such a pane.
fn bsdf_pass_through(b: Bsdf, wo: vec3f) -> vec4f {
    if b.dielectric != DIELECTRIC_THIN_SMOOTH || b.lambertian || b.glass_weight <= 0.0 {
        return vec4f(0.0, 0.0, 0.0, -1.0);
    }
    let wo_local = to_local(b.frame, wo);
    let transmitted = 1.0 - thin_slab_reflectance(wo_local.z, b.eta);
    let p = lobe_probabilities(b, wo_local).w;
    return vec4f(b.glass_weight * b.tint * transmitted, p * transmitted);
}

struct BsdfSample {
    valid: bool,
    wi: vec3f,
    weight: vec3f,
    pdf: f32,
    delta: bool,
    transmitted: bool,
    etap: f32,
    pass_through: bool,
}

fn no_sample() -> BsdfSample {
    return BsdfSample(false, vec3f(0.0), vec3f(0.0), 0.0, false, false, 1.0, false);
}

fn delta_sample(b: Bsdf, wo_z: f32, wi_local: vec3f, weight: vec3f, probability: f32, etap: f32, pass_through: bool) -> BsdfSample {
    return BsdfSample(true, normalize(to_world(b.frame, wi_local)), weight, probability, true, wi_local.z * wo_z < 0.0, etap, pass_through);
}

fn mirror_z(w: vec3f, side: f32) -> vec3f {
    return vec3f(w.x, w.y, w.z * side);
}

fn bsdf_sample(b: Bsdf, wo: vec3f, u_lobe: f32, u_event: f32, u: vec2f) -> BsdfSample {
    let wo_local = to_local(b.frame, wo);
    if wo_local.z == 0.0 {
        return no_sample();
    }
    let p = lobe_probabilities(b, wo_local);
    let side = sign_nonzero(wo_local.z);
    var wi_local: vec3f;
    if u_lobe < p.x {
        wi_local = mirror_z(cosine_hemisphere(u), side);
    } else if u_lobe < p.x + p.y + p.z {
        let o = mirror_z(wo_local, side);
        let m = ggx_sample_visible(b.alpha, o, u);
        let i = reflect_about(o, m);
        if i.z <= 0.0 {
            return no_sample();
        }
        wi_local = mirror_z(i, side);
    } else {
        switch b.dielectric {
            case DIELECTRIC_SMOOTH: {
                let reflectance = fresnel_dielectric(wo_local.z, b.eta);
                let scale = b.glass_weight / p.w;
                if u_event < reflectance {
                    let wi = vec3f(-wo_local.x, -wo_local.y, wo_local.z);
                    return delta_sample(b, wo_local.z, wi, vec3f(scale), p.w * reflectance, 1.0, false);
                }
                let r = refract_through(wo_local, vec3f(0.0, 0.0, 1.0), b.eta);
                if !r.valid {
                    return no_sample();
                }
                let weight = scale * b.tint / (r.etap * r.etap);
                return delta_sample(b, wo_local.z, r.wi, weight, p.w * (1.0 - reflectance), r.etap, false);
            }
            case DIELECTRIC_THIN_SMOOTH: {
                let reflectance = thin_slab_reflectance(wo_local.z, b.eta);
                let scale = b.glass_weight / p.w;
                if u_event < reflectance {
                    let wi = vec3f(-wo_local.x, -wo_local.y, wo_local.z);
                    return delta_sample(b, wo_local.z, wi, vec3f(scale), p.w * reflectance, 1.0, false);
                }
                return delta_sample(b, wo_local.z, -wo_local, scale * b.tint, p.w * (1.0 - reflectance), 1.0, true);
            }
            case DIELECTRIC_ROUGH: {
                let o = wo_local * side;
                let m = ggx_sample_visible(b.glass_alpha, o, u);
                let reflectance = fresnel_dielectric(dot(wo_local, m), b.eta);
                if u_event < reflectance {
                    let wi = reflect_about(wo_local, m);
                    if wi.z * wo_local.z <= 0.0 {
                        return no_sample();
                    }
                    wi_local = wi;
                } else {
                    let r = refract_through(wo_local, m, b.eta);
                    if !r.valid || r.wi.z * wo_local.z >= 0.0 {
                        return no_sample();
                    }
                    wi_local = r.wi;
                }
            }
            case DIELECTRIC_THIN_ROUGH: {
                let o = mirror_z(wo_local, side);
                let m = ggx_sample_visible(b.glass_alpha, o, u);
                let i = reflect_about(o, m);
                if i.z <= 0.0 {
                    return no_sample();
                }
                if u_event < thin_slab_reflectance(dot(o, m), b.eta) {
                    wi_local = mirror_z(i, side);
                } else {
                    wi_local = mirror_z(vec3f(i.x, i.y, -i.z), side);
                }
            }
            default: {
                return no_sample();
            }
        }
    }
    let fp = bsdf_eval_pdf_local(b, wo_local, wi_local);
    let pdf = fp.w;
    if !(pdf > 0.0) || !is_finite_f32(pdf) {
        return no_sample();
    }
    let transmitted = wi_local.z * wo_local.z < 0.0;
    var etap = 1.0;
    if b.dielectric == DIELECTRIC_ROUGH && transmitted {
        etap = select(1.0 / b.eta, b.eta, wo_local.z > 0.0);
    }
    return BsdfSample(true, normalize(to_world(b.frame, wi_local)), fp.xyz * abs(wi_local.z) / pdf, pdf, false, transmitted, etap, false);
}
