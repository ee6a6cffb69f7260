// The path tracer as one compute kernel per pass: every invocation owns a pixel and traces
// `sample_count` camera paths into it. The GPU twin of the CPU tracer's plain estimator
// (crates/trace/src/{integrator,lights,render}.rs: lights sampled by area and picked by power,
// uniform pixels, independent values); src/tracer.rs prepends the constants shared with Rust
// and bsdf.wgsl. Buffer layouts are written by src/upload.rs.

struct Params {
    camera_position: vec4f,
    camera_forward: vec4f,
    // right * tan(fov_x / 2) and up * tan(fov_y / 2).
    camera_right: vec4f,
    camera_up: vec4f,
    background: vec4f,
    width: u32,
    height: u32,
    sample_start: u32,
    sample_count: u32,
    seed_lo: u32,
    seed_hi: u32,
    max_depth: u32,
    rr_depth: u32,
    flags: u32,
    emitter_count: u32,
    texture_table: u32,
    has_panes: u32,
    // Threads per pixel: thread z of a pixel traces samples z, z + slots, ... of the pass.
    slots: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// FLAG_LAMBERTIAN, the record sizes (`*_VEC4S`), the attribute flags (`ATTR_*`), NONE
// and MAX_VERTICES come from Rust: `shared_constants` in src/tracer.rs prepends
// them from the constants src/upload.rs writes the buffers with and the CPU tracer's own.

@group(0) @binding(0) var<uniform> params: Params;
// Binary BVH: (min, first child or first triangle), (max, triangle count; 0 = inner node).
@group(0) @binding(1) var<storage, read> nodes: array<vec4f>;
// In BVH leaf order: (v0, attribute index), (edge1, flags), (edge2, 0).
@group(0) @binding(2) var<storage, read> triangles: array<vec4f>;
// Per triangle: p0..p2 (w: material or light, emitter, flags), n0..n2, (uv0, uv1), (uv2, -).
@group(0) @binding(3) var<storage, read> attributes: array<vec4f>;
// Materials, then from params.texture_table one (offset, width, height, -) per texture.
@group(0) @binding(4) var<storage, read> materials: array<vec4f>;
@group(0) @binding(5) var<storage, read> texels: array<vec4f>;
@group(0) @binding(6) var<storage, read> emitters: array<vec4f>;
// Per slot and pixel (slot-major): sum of finite samples (rgb) and their count (w),
// accumulated over passes; and the count of non-finite samples left out.
@group(0) @binding(7) var<storage, read_write> accumulation: array<vec4f>;
@group(0) @binding(8) var<storage, read_write> discarded: array<u32>;

// ---- random numbers: a counter-based hash per (pixel, sample, dimension) ----

var<private> rng_key: vec4u;
var<private> rng_counter: u32;

// pcg4d is the rays crate's shaders/common.wgsl.

fn rng_start(pixel: u32, sample: u32) {
    rng_key = pcg4d(vec4u(pixel, sample, params.seed_lo, params.seed_hi));
    rng_counter = 0u;
}

// One number per two rounds of the hash, from its first lane. Cheaper variants were measured
// against the CPU tracer (cornellbox, 32x32, 4096 spp, two seeds each, mean radiance):
// using all four lanes of one hash for consecutive numbers raised the variance by 30%, and
// one lane of one hash made the image 0.3% darker (long paths through smooth glass, where
// u < Fresnel picks reflection, are sensitive to weak correlations); with two rounds the
// means agree to 0.05%.
fn rng_u32() -> u32 {
    let v = pcg4d(pcg4d(rng_key ^ vec4u(0u, 0u, rng_counter, rng_counter * 0x9e3779b9u)));
    rng_counter += 1u;
    return v.x;
}

// Uniform in [0, 1): the top 24 bits, as the CPU tracer.
fn rng_f32() -> f32 {
    return f32(rng_u32() >> 8u) * (1.0 / 16777216.0);
}

fn rng_vec2() -> vec2f {
    let x = rng_f32();
    return vec2f(x, rng_f32());
}

// ---- geometry ----

// The BVH traversal (Hit, traverse) is the rays crate's shaders/bvh.wgsl, prepended by
// src/tracer.rs; the scene's BVH is the only one in `nodes`, at root 0.
const CONSIDER_PANES: u32 = CONSIDER_FLAGGED;
const CONSIDER_OPAQUE: u32 = CONSIDER_UNFLAGGED;

// The closest considered triangle with t in (t_min, t_max); with `any_hit`, the first found.
fn traverse_scene(origin: vec3f, direction: vec3f, t_min: f32, t_max: f32, consider: u32, any_hit: bool) -> Hit {
    return traverse(0u, origin, direction, t_min, t_max, consider, ATTR_PASS_THROUGH, any_hit);
}

struct SurfaceHit {
    position: vec3f,
    geometric_normal: vec3f,
    shading_normal: vec3f,
    uv: vec2f,
    rect_light: bool,
    material: u32,
    emitter: u32,
}

fn surface_hit(hit: Hit) -> SurfaceHit {
    let base = hit.triangle * ATTRIBUTE_VEC4S;
    let a0 = attributes[base];
    let a1 = attributes[base + 1u];
    let a2 = attributes[base + 2u];
    let flags = bitcast<u32>(a2.w);
    let b0 = 1.0 - hit.b1 - hit.b2;
    var s: SurfaceHit;
    s.position = a0.xyz * b0 + a1.xyz * hit.b1 + a2.xyz * hit.b2;
    var geometric = normalize(cross(a1.xyz - a0.xyz, a2.xyz - a0.xyz));
    var shading = geometric;
    if (flags & ATTR_HAS_NORMALS) != 0u {
        let n = attributes[base + 3u].xyz * b0 + attributes[base + 4u].xyz * hit.b1 + attributes[base + 5u].xyz * hit.b2;
        let len = length(n);
        if len > 0.0 && is_finite_f32(len) {
            shading = n / len;
        }
    }
    if dot(geometric, shading) < 0.0 {
        geometric = -geometric;
    }
    s.geometric_normal = geometric;
    s.shading_normal = shading;
    let uv01 = attributes[base + 6u];
    let uv2 = attributes[base + 7u].xy;
    s.uv = uv01.xy * b0 + uv01.zw * hit.b1 + uv2 * hit.b2;
    s.rect_light = (flags & ATTR_RECT_LIGHT) != 0u;
    s.material = bitcast<u32>(a0.w);
    s.emitter = bitcast<u32>(a1.w);
    return s;
}

// ---- materials and textures ----

// texel and sample_texture are the rays crate's shaders/common.wgsl.

fn surface_material(material: u32, uv: vec2f) -> SurfaceMaterial {
    let base = material * MATERIAL_VEC4S;
    let r0 = materials[base];
    let r1 = materials[base + 1u];
    let r2 = materials[base + 2u];
    let textures = bitcast<vec4u>(materials[base + 3u]);
    var m: SurfaceMaterial;
    m.base_color = r0.xyz;
    m.roughness = r0.w;
    m.specular_color = r1.xyz;
    m.specular = r1.w;
    m.metallic = r2.x;
    m.transmission_weight = r2.y;
    m.ior = r2.z;
    m.thin = r2.w != 0.0;
    if textures.x != NONE {
        m.base_color *= sample_texture(textures.x, uv).xyz;
    }
    if textures.y != NONE {
        m.roughness *= sample_texture(textures.y, uv).y;
    }
    if textures.z != NONE {
        m.specular *= sample_texture(textures.z, uv).w;
    }
    if textures.w != NONE {
        m.specular_color *= sample_texture(textures.w, uv).xyz;
    }
    return m;
}

// ---- lights (crates/trace/src/lights.rs, spherical_rect.rs) ----

struct Emitter {
    triangle: bool,
    p0: vec3f,
    edge1: vec3f,
    edge2: vec3f,
    area: f32,
    two_sided: bool,
    normal: vec3f,
    pmf: f32,
    radiance: vec3f,
    rectangle: bool,
}

fn load_emitter(i: u32) -> Emitter {
    let base = i * EMITTER_VEC4S;
    let r0 = emitters[base];
    let r1 = emitters[base + 1u];
    let r2 = emitters[base + 2u];
    let r3 = emitters[base + 3u];
    let r4 = emitters[base + 4u];
    return Emitter(bitcast<u32>(r0.w) != 0u, r0.xyz, r1.xyz, r2.xyz, r1.w, bitcast<u32>(r2.w) != 0u, r3.xyz, r3.w, r4.xyz, bitcast<u32>(r4.w) != 0u);
}

fn emitter_cdf(i: u32) -> f32 {
    return emitters[i * EMITTER_VEC4S + 5u].x;
}

fn emitted(e: Emitter, w: vec3f) -> vec3f {
    if e.two_sided || dot(e.normal, w) > 0.0 {
        return e.radiance;
    }
    return vec3f(0.0);
}

struct LightSample {
    valid: bool,
    point: vec3f,
    wi: vec3f,
    radiance: vec3f,
    pdf: f32,
}

fn no_light() -> LightSample {
    return LightSample(false, vec3f(0.0), vec3f(0.0), vec3f(0.0), 0.0);
}

fn select_emitter(u: f32) -> u32 {
    // The first emitter whose cumulative probability exceeds u.
    var lo = 0u;
    var hi = params.emitter_count;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if emitter_cdf(mid) <= u {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return min(lo, params.emitter_count - 1u);
}

fn sample_light(shading_point: vec3f, u_select: f32, u: vec2f) -> LightSample {
    if params.emitter_count == 0u {
        return no_light();
    }
    let index = select_emitter(u_select);
    let e = load_emitter(index);
    var point: vec3f;
    if e.triangle {
        let b = uniform_triangle(u);
        point = e.p0 + b.x * e.edge1 + b.y * e.edge2;
    } else {
        point = e.p0 + u.x * e.edge1 + u.y * e.edge2;
    }
    let to_light = point - shading_point;
    let distance2 = dot(to_light, to_light);
    if distance2 <= 0.0 {
        return no_light();
    }
    let wi = to_light / sqrt(distance2);
    let radiance = emitted(e, -wi);
    let cos_light = abs(dot(e.normal, -wi));
    if all(radiance == vec3f(0.0)) || cos_light <= 0.0 {
        return no_light();
    }
    let pdf = e.pmf * distance2 / (cos_light * e.area);
    if !(pdf > 0.0) || !is_finite_f32(pdf) {
        return no_light();
    }
    return LightSample(true, point, wi, radiance, pdf);
}

// Density with which sample_light from `shading_point` picks `point` on emitter `index`.
fn light_pdf(index: u32, shading_point: vec3f, point: vec3f) -> f32 {
    let e = load_emitter(index);
    let to_light = point - shading_point;
    let distance2 = dot(to_light, to_light);
    let cos_light = abs(dot(e.normal, to_light)) / sqrt(distance2);
    if !(cos_light > 0.0) || e.area <= 0.0 {
        return 0.0;
    }
    return e.pmf * distance2 / (cos_light * e.area);
}

// ---- the integrator (crates/trace/src/integrator.rs) ----

fn ray_epsilon(p: vec3f) -> f32 {
    return 1e-4 * max(max_element(abs(p)), 1.0);
}

fn offset_origin(p: vec3f, geometric_normal: vec3f, direction: vec3f) -> vec3f {
    let side = select(-1.0, 1.0, dot(direction, geometric_normal) >= 0.0);
    return p + geometric_normal * (side * ray_epsilon(p));
}

// Light transport along a shadow segment through smooth thin panes: (transmittance rgb,
// probability that BSDF sampling crosses them all); w < 0 when blocked.
fn shadow_transmittance(origin: vec3f, direction: vec3f, t_max: f32, max_crossings: u32) -> vec4f {
    let blocked = vec4f(0.0, 0.0, 0.0, -1.0);
    if t_max <= 0.0 {
        return blocked;
    }
    let consider = select(CONSIDER_ALL, CONSIDER_OPAQUE, params.has_panes != 0u);
    if traverse_scene(origin, direction, 0.0, t_max, consider, true).valid {
        return blocked;
    }
    var result = vec4f(1.0);
    if params.has_panes == 0u {
        return result;
    }
    // Panes in distance order; a second triangle at (almost) the same distance is the other
    // half of a pane crossed through a shared edge.
    var t0 = 0.0;
    var crossings = 0u;
    for (var guard = 0u; guard < MAX_VERTICES; guard++) {
        let hit = traverse_scene(origin, direction, t0, t_max, CONSIDER_PANES, false);
        if !hit.valid {
            break;
        }
        crossings += 1u;
        if crossings > max_crossings {
            return blocked;
        }
        let s = surface_hit(hit);
        if s.rect_light {
            return blocked;
        }
        let bsdf = make_bsdf(surface_material(s.material, s.uv), s.shading_normal, (params.flags & FLAG_LAMBERTIAN) != 0u);
        let crossing = bsdf_pass_through(bsdf, -direction);
        if crossing.w < 0.0 {
            return blocked;
        }
        result *= crossing;
        t0 = hit.t + 1e-6 * max(hit.t, 1.0);
    }
    return result;
}

fn trace_path(origin_in: vec3f, direction_in: vec3f) -> vec3f {
    let lambertian = (params.flags & FLAG_LAMBERTIAN) != 0u;
    var radiance = vec3f(0.0);
    var throughput = vec3f(1.0);
    var origin = origin_in;
    var direction = direction_in;
    var depth = 1u;
    var eta_scale = 1.0;
    var specular = true;
    var mis_origin = origin;
    var mis_pdf = 0.0;

    for (var vertex = 0u; vertex < MAX_VERTICES; vertex++) {
        let hit = traverse_scene(origin, direction, 0.0, FLT_MAX, CONSIDER_ALL, false);
        if !hit.valid {
            radiance += throughput * params.background.xyz;
            break;
        }
        let s = surface_hit(hit);
        let wo = -direction;
        if s.emitter != NONE {
            let e = load_emitter(s.emitter);
            let light = emitted(e, wo);
            if any(light != vec3f(0.0)) {
                var weight = 1.0;
                if !specular {
                    weight = power_heuristic(mis_pdf, light_pdf(s.emitter, mis_origin, s.position));
                }
                radiance += throughput * light * weight;
            }
        }
        if s.rect_light {
            break;
        }
        let bsdf = make_bsdf(surface_material(s.material, s.uv), s.shading_normal, lambertian);
        if depth >= params.max_depth {
            break;
        }
        let crossings_allowed = params.max_depth - depth - 1u;
        let ng = s.geometric_normal;
        let wo_side = dot(wo, ng);

        // Next-event estimation.
        if bsdf_has_non_delta(bsdf) {
            let u_select = rng_f32();
            let u_light = rng_vec2();
            let light = sample_light(s.position, u_select, u_light);
            if light.valid {
                let wi = light.wi;
                let reflection = dot(wi, ng) * wo_side > 0.0;
                let fp = bsdf_eval_pdf(bsdf, wo, wi);
                let shading_reflection = dot(wi, s.shading_normal) * dot(wo, s.shading_normal) > 0.0;
                if any(fp.xyz != vec3f(0.0)) && reflection == shading_reflection {
                    let shadow_origin = offset_origin(s.position, ng, wi);
                    let to_light = light.point - shadow_origin;
                    let shadow_distance = length(to_light);
                    let t_max = shadow_distance * (1.0 - 1e-4) - ray_epsilon(light.point);
                    let transmittance = shadow_transmittance(shadow_origin, to_light / shadow_distance, t_max, crossings_allowed);
                    if transmittance.w >= 0.0 {
                        let weight = power_heuristic(light.pdf, fp.w * transmittance.w);
                        let cos = abs(dot(wi, s.shading_normal));
                        radiance += throughput * fp.xyz * cos * transmittance.xyz * light.radiance * (weight / light.pdf);
                    }
                }
            }
        }

        // Continue the path.
        let u_lobe = rng_f32();
        let u_event = rng_f32();
        let u = rng_vec2();
        let sample = bsdf_sample(bsdf, wo, u_lobe, u_event, u);
        if !sample.valid {
            break;
        }
        let reflection = dot(sample.wi, ng) * wo_side > 0.0;
        if reflection == sample.transmitted && !sample.delta {
            break;
        }
        throughput *= sample.weight;
        if sample.transmitted && sample.etap != 1.0 {
            eta_scale *= sample.etap * sample.etap;
        }
        depth += 1u;
        if sample.pass_through {
            mis_pdf *= sample.pdf;
        } else {
            specular = sample.delta;
            mis_pdf = sample.pdf;
            mis_origin = s.position;
        }
        origin = offset_origin(s.position, ng, sample.wi);
        direction = sample.wi;
        if all(throughput == vec3f(0.0)) {
            break;
        }
        if depth > params.rr_depth {
            let survival = min(max_element(throughput) * eta_scale, 0.95);
            if rng_f32() >= survival {
                break;
            }
            throughput /= survival;
        }
    }
    return radiance;
}

@compute @workgroup_size(8, 8)
fn trace_pass(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let pixel = id.y * params.width + id.x;
    var sum = vec3f(0.0);
    var finite = 0.0;
    var not_finite = 0u;
    for (var s = id.z; s < params.sample_count; s += params.slots) {
        rng_start(pixel, params.sample_start + s);
        let jitter = rng_vec2();
        let ndc_x = 2.0 * (f32(id.x) + jitter.x) / f32(params.width) - 1.0;
        let ndc_y = 1.0 - 2.0 * (f32(id.y) + jitter.y) / f32(params.height);
        let direction = normalize(params.camera_forward.xyz + params.camera_right.xyz * ndc_x + params.camera_up.xyz * ndc_y);
        let radiance = trace_path(params.camera_position.xyz, direction);
        if is_finite_vec3(radiance) {
            sum += radiance;
            finite += 1.0;
        } else {
            not_finite += 1u;
        }
    }
    let index = id.z * params.width * params.height + pixel;
    accumulation[index] += vec4f(sum, finite);
    discarded[index] += not_finite;
}
