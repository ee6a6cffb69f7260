// The through pass as one compute kernel: the GPU twin of `through.rs` (same rays, same
// surfaces, same footprint and lobe points), one invocation per pixel of transparent object k. The BVHs of
// the opaque scene (with its lights) and of every transparent object alone share `nodes`
// and `triangles`, each from its root. `through_gpu.rs` prepends the constants shared with
// Rust, `bvh.wgsl`, `optics.wgsl` and `common.wgsl`, and writes the buffers.

struct Params {
    view_projection: mat4x4f,
    camera_position: vec4f,
    camera_forward: vec4f,
    // right * tan(fov_x / 2) and up * tan(fov_y / 2).
    camera_right: vec4f,
    camera_up: vec4f,
    // The scene's background radiance (xyz), which a ray leaving the scene brings.
    background: vec4f,
    width: u32,
    height: u32,
    opaque_root: u32,
    object_root: u32,
    ior: f32,
    thin: u32,
    rough: u32,
    alpha: f32,
    object: u32,
    texture_table: u32,
    // Where the planes start, in f32 elements of their bindings: the opaque G-buffer's L_d (3
    // planes), the object's coverage (1), the through buffer written (THROUGH_CHANNELS).
    ld_offset: u32,
    coverage_offset: u32,
    through_offset: u32,
    // The side of a pixel at distance 1 from the camera: 2 tan(fov_y / 2) / height.
    pixel_size: f32,
    light_count: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> nodes: array<vec4f>;
@group(0) @binding(2) var<storage, read> triangles: array<vec4f>;
// Per triangle: p0..p2 (w: material or light, flags, -), n0..n2, (uv0, uv1), (uv2, -).
@group(0) @binding(3) var<storage, read> attributes: array<vec4f>;
// Per material (base colour, base colour texture or NONE), (emission, diffuse share); then from
// params.texture_table one (offset, width, height, -) per texture.
@group(0) @binding(4) var<storage, read> materials: array<vec4f>;
@group(0) @binding(5) var<storage, read> texels: array<vec4f>;
// Per rectangle light: (normal, two-sided), (radiance, -), (corner, -), (edge u, -), (edge v, -).
@group(0) @binding(6) var<storage, read> lights: array<vec4f>;
// Planes of width x height: the opaque G-buffer's L_d from params.ld_offset on.
@group(0) @binding(7) var<storage, read> gbuffer: array<f32>;
// Planes of width x height: object k's coverage from params.coverage_offset on, and its
// through buffer written from params.through_offset on (in the real-time frame, the network's
// input tensor for the object, its transparency buffer followed by its through buffer).
@group(0) @binding(8) var<storage, read_write> object_planes: array<f32>;

// ---- triangles (triangle.rs) ----

fn face_normal(triangle: u32) -> vec3f {
    let base = triangle * ATTRIBUTE_VEC4S;
    let p0 = attributes[base].xyz;
    return normalize(cross(attributes[base + 1u].xyz - p0, attributes[base + 2u].xyz - p0));
}

fn shading_normal(hit: Hit) -> vec3f {
    let base = hit.triangle * ATTRIBUTE_VEC4S;
    let face = face_normal(hit.triangle);
    if (bitcast<u32>(attributes[base + 2u].w) & ATTR_HAS_NORMALS) == 0u {
        return face;
    }
    let b0 = 1.0 - hit.b1 - hit.b2;
    let n = attributes[base + 3u].xyz * b0 + attributes[base + 4u].xyz * hit.b1 + attributes[base + 5u].xyz * hit.b2;
    let len = length(n);
    if len > 0.0 && len < 3.0e38 {
        return n / len;
    }
    return face;
}

// ---- the path through object k (through.rs: trace_path) ----

struct PathEnd {
    valid: bool,
    position: vec3f,
    normal: vec3f,
    // The base colour; a texture, read over the footprint, multiplies it there.
    albedo: vec3f,
    // through.rs: ThroughHit::diffuse.
    diffuse: f32,
    // Where the end reads a texture: its material (NONE elsewhere) and UV.
    material: u32,
    uv: vec2f,
    emitted: vec3f,
    // A rectangle light or the background.
    is_light: bool,
    // The path left the scene (through.rs: ThroughHit::background).
    background: bool,
    transmittance: f32,
    length: f32,
    path_length: f32,
}

fn lost() -> PathEnd {
    return PathEnd(false, vec3f(0.0), vec3f(0.0), vec3f(0.0), 0.0, NONE, vec2f(0.0), vec3f(0.0), false, false, 0.0, 0.0, 0.0);
}

// through.rs: background_end.
fn background_end(origin: vec3f, direction: vec3f, transmittance: f32, length: f32, path_length: f32) -> PathEnd {
    return PathEnd(true, origin, -direction, vec3f(0.0), 0.0, NONE, vec2f(0.0), params.background.xyz, true, true, transmittance, length, path_length);
}

fn surface_end(hit: Hit, origin: vec3f, direction: vec3f, transmittance: f32, length: f32, path_length: f32) -> PathEnd {
    var end: PathEnd;
    end.valid = true;
    end.background = false;
    end.position = origin + direction * hit.t;
    let n = shading_normal(hit);
    end.normal = select(n, -n, dot(n, direction) > 0.0);
    end.transmittance = transmittance;
    end.length = length;
    end.path_length = path_length;
    let base = hit.triangle * ATTRIBUTE_VEC4S;
    let material_or_light = bitcast<u32>(attributes[base].w);
    end.material = NONE;
    if (bitcast<u32>(attributes[base + 2u].w) & ATTR_RECT_LIGHT) != 0u {
        let normal = lights[material_or_light * LIGHT_VEC4S];
        let front = dot(normal.xyz, direction) < 0.0;
        end.albedo = vec3f(0.0);
        end.diffuse = 0.0;
        end.emitted = select(vec3f(0.0), lights[material_or_light * LIGHT_VEC4S + 1u].xyz, front || normal.w != 0.0);
        end.is_light = true;
        return end;
    }
    let material = materials[material_or_light * MATERIAL_VEC4S];
    if bitcast<u32>(material.w) != NONE {
        let b0 = 1.0 - hit.b1 - hit.b2;
        let uv01 = attributes[base + 6u];
        end.material = material_or_light;
        end.uv = uv01.xy * b0 + uv01.zw * hit.b1 + attributes[base + 7u].xy * hit.b2;
    }
    end.albedo = material.xyz;
    let emission = materials[material_or_light * MATERIAL_VEC4S + 1u];
    end.emitted = emission.xyz;
    end.diffuse = emission.w;
    end.is_light = false;
    return end;
}

// through.rs: lobe_point.
fn lobe_point(s: u32, surface: u32, pixel: vec2u) -> vec2f {
    let shift = pcg4d(vec4u(pixel.x, pixel.y, params.object, surface));
    let unit = vec2f(f32(shift.x >> 8u), f32(shift.y >> 8u)) / 16777216.0;
    let u = vec2f((f32(s) + 0.5) / f32(LOBE_SAMPLES), f32(reverseBits(s)) / 4294967296.0);
    return fract(u + unit);
}

// through.rs: ggx_normal, with glam's any_orthonormal_pair (Duff et al. 2017).
fn ggx_normal(n: vec3f, alpha: f32, u: vec2f) -> vec3f {
    let tan2 = alpha * alpha * u.x / max(1.0 - u.x, 1e-6);
    let cos_theta = 1.0 / sqrt(1.0 + tan2);
    let sin_theta = sqrt(max(1.0 - cos_theta * cos_theta, 0.0));
    let phi = 6.2831855 * u.y;
    let sign = select(1.0, -1.0, n.z < 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = vec3f(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = vec3f(b, sign + n.y * n.y * a, -n.y);
    return normalize(t * (sin_theta * cos(phi)) + bt * (sin_theta * sin(phi)) + n * cos_theta);
}

// The mean direction's path with `sample` = NO_SAMPLE, else the path of lobe sample `sample`.
fn trace_path(origin_in: vec3f, direction_in: vec3f, pixel: vec2u, sample: u32) -> PathEnd {
    var origin = origin_in;
    var direction = direction_in;
    var inside = false;
    var transmittance = 1.0;
    var travelled = 0.0;
    var path_length = 0.0;
    var interfaces = 0u;
    var t_min = 0.0;
    loop {
        let glass = traverse(params.object_root, origin, direction, t_min, BVH_MISS, CONSIDER_ALL, 0u, false);
        let glass_t = select(BVH_MISS, glass.t, glass.valid);
        let opaque = traverse(params.opaque_root, origin, direction, t_min, glass_t, CONSIDER_ALL, 0u, false);
        if opaque.valid {
            if inside {
                travelled += opaque.t;
            }
            return surface_end(opaque, origin, direction, transmittance, travelled, path_length + opaque.t);
        }
        if !glass.valid {
            return background_end(origin, direction, transmittance, travelled, path_length);
        }
        if interfaces == MAX_INTERFACES {
            return lost();
        }
        if inside {
            travelled += glass.t;
        }
        path_length += glass.t;
        let position = origin + direction * glass.t;
        let n = shading_normal(glass);
        var m = n;
        if sample != NO_SAMPLE {
            m = ggx_normal(n, params.alpha, lobe_point(sample, interfaces, pixel));
        }
        interfaces += 1u;
        let wo = -direction;
        if params.thin != 0u {
            let reflected = reflect_about(wo, m);
            if (dot(reflected, n) < 0.0) != (dot(wo, n) < 0.0) {
                return lost();
            }
            transmittance *= 1.0 - thin_slab_reflectance(dot(m, wo), params.ior);
            direction = normalize(reflected - 2.0 * dot(reflected, n) * n);
        } else {
            // The normal on the outside: towards the ray's origin while it is outside.
            let outward = select(-m, m, (dot(n, wo) > 0.0) != inside);
            let refracted = refract_through(wo, outward, params.ior);
            if refracted.valid {
                transmittance *= 1.0 - fresnel_dielectric(dot(outward, wo), params.ior);
                direction = normalize(refracted.wi);
                inside = !inside;
            } else {
                direction = normalize(reflect_about(wo, outward));
            }
        }
        origin = position;
        t_min = SELF_HIT;
    }
    return lost();
}

// through.rs: on_screen. The pixel `position` projects to (xy), whether it is in the frame (z)
// and whether the camera sees it there (w).
fn on_screen(position: vec3f) -> vec4f {
    let clip = params.view_projection * vec4f(position, 1.0);
    if clip.w <= 0.0 {
        return vec4f(0.0);
    }
    let ndc = clip.xyz / clip.w;
    let px = (ndc.x + 1.0) * 0.5 * f32(params.width);
    let py = (1.0 - ndc.y) * 0.5 * f32(params.height);
    if !(px >= 0.0 && px < f32(params.width) && py >= 0.0 && py < f32(params.height)) {
        return vec4f(0.0);
    }
    let to_hit = position - params.camera_position.xyz;
    let distance = length(to_hit);
    let blocked = traverse(params.opaque_root, params.camera_position.xyz, to_hit / distance, 0.0, distance * (1.0 - VIEW_SLACK), CONSIDER_ALL, 0u, true).valid;
    return vec4f(floor(px), floor(py), 1.0, select(1.0, 0.0, blocked));
}

// through.rs: light_at.
fn light_at(end: PathEnd, view: vec4f) -> vec3f {
    if !end.is_light && view.z != 0.0 && view.w != 0.0 {
        let pixels = params.width * params.height;
        let j = params.ld_offset + u32(view.y) * params.width + u32(view.x);
        return vec3f(gbuffer[j], gbuffer[j + pixels], gbuffer[j + 2u * pixels]);
    }
    return end.emitted;
}

// direct.rs: unseen_direct_light, the shadow rays cast in the opaque scene.
fn unseen_direct_light(position: vec3f, normal: vec3f, diffuse_albedo: vec3f, point: u32) -> vec3f {
    if all(diffuse_albedo == vec3f(0.0)) {
        return vec3f(0.0);
    }
    let frame = frame_around(normal);
    var points = FOOTPRINT;
    // direct.rs: light_point.
    let on_light = points[point % FOOTPRINT_POINTS] + vec2f(0.5);
    var total = vec3f(0.0);
    for (var l = 0u; l < params.light_count; l++) {
        let base = l * LIGHT_VEC4S;
        let facing = lights[base];
        let corner = lights[base + 2u].xyz;
        let edge_u = lights[base + 3u].xyz;
        let edge_v = lights[base + 4u].xyz;
        let side = dot(position - corner, facing.xyz);
        if !(side > 0.0 || (facing.w != 0.0 && side < 0.0)) {
            continue;
        }
        let c = corner - position;
        let form_factor = polygon_form_factor(frame * c, frame * (c + edge_u), frame * (c + edge_u + edge_v), frame * (c + edge_v));
        if form_factor <= 0.0 {
            continue;
        }
        let to_light = c + edge_u * on_light.x + edge_v * on_light.y;
        let distance = length(to_light);
        if traverse(params.opaque_root, position, to_light / distance, SELF_HIT, distance * (1.0 - VIEW_SLACK), CONSIDER_ALL, 0u, true).valid {
            continue;
        }
        total += lights[base + 1u].xyz * diffuse_albedo * form_factor;
    }
    return total;
}

// core::camera: PrimaryRays::ray, through the point `offset` pixels from the centre of `pixel`.
fn pixel_ray(pixel: vec2u, offset: vec2f) -> vec3f {
    let ndc_x = 2.0 * (f32(pixel.x) + 0.5 + offset.x) / f32(params.width) - 1.0;
    let ndc_y = 1.0 - 2.0 * (f32(pixel.y) + 0.5 + offset.y) / f32(params.height);
    return normalize(params.camera_forward.xyz + params.camera_right.xyz * ndc_x + params.camera_up.xyz * ndc_y);
}

// What the footprint's mean needs of each path's end, kept for all of them before the albedo
// (a whole PathEnd each would be twice the registers).
struct FootprintEnd {
    position: vec3f,
    transmittance: f32,
    albedo: vec3f,
    material: u32,
    uv: vec2f,
    // light_at's: the G-buffer's L_d where the camera sees the end, else what it emits.
    light: vec3f,
    // The diffuse share where the camera does not see the end, whose lights' direct light is
    // added to `light` once its albedo is read; 0 where it does, on a light, the background.
    unseen_diffuse: f32,
    normal: vec3f,
}

// through.rs: light_at, for `end` of footprint path `point` with `albedo` read over its share.
fn end_light(end: FootprintEnd, albedo: vec3f, point: u32) -> vec3f {
    if end.unseen_diffuse == 0.0 {
        return end.light;
    }
    return end.light + unseen_direct_light(end.position, end.normal, albedo * end.unseen_diffuse, point);
}

// through.rs: footprint_lod, for the hit on `material` among the first `count` ends.
fn footprint_lod(ends: ptr<function, array<FootprintEnd, LOBE_SAMPLES>>, count: u32, material: u32, size: vec2f, paths: u32) -> f32 {
    var n = 0u;
    var mean = vec2f(0.0);
    for (var j = 0u; j < count; j++) {
        if (*ends)[j].material == material {
            mean += (*ends)[j].uv;
            n += 1u;
        }
    }
    if n < 2u {
        return 0.0;
    }
    mean /= f32(n);
    var squares = 0.0;
    for (var j = 0u; j < count; j++) {
        if (*ends)[j].material == material {
            let d = ((*ends)[j].uv - mean) * size;
            squares += dot(d, d);
        }
    }
    let rms = sqrt(squares / f32(n));
    let side = rms / (FOOTPRINT_RMS * sqrt(f32(paths)));
    return log2(max(side, 1.0));
}

// The size in texels of the texture of `material`, which has one.
fn texture_size(material: u32) -> vec2f {
    let texture = bitcast<u32>(materials[material * MATERIAL_VEC4S].w);
    let record = bitcast<vec4u>(materials[params.texture_table + texture]);
    return vec2f(f32(record.y), f32(record.z));
}

// through.rs: footprint_gradients, of the ends of all FOOTPRINT_POINTS rays, in their order.
fn footprint_gradients(ends: ptr<function, array<FootprintEnd, LOBE_SAMPLES>>, size: vec2f) -> mat2x2f {
    var points = FOOTPRINT;
    let n = f32(FOOTPRINT_POINTS);
    var mean_offset = vec2f(0.0);
    var mean_uv = vec2f(0.0);
    for (var j = 0u; j < FOOTPRINT_POINTS; j++) {
        mean_offset += points[j];
        mean_uv += (*ends)[j].uv;
    }
    mean_offset /= n;
    mean_uv /= n;
    var spread = mat2x2f(0.0, 0.0, 0.0, 0.0);
    var moved = mat2x2f(0.0, 0.0, 0.0, 0.0);
    for (var j = 0u; j < FOOTPRINT_POINTS; j++) {
        let d = points[j] - mean_offset;
        let uv = ((*ends)[j].uv - mean_uv) * size;
        spread += mat2x2f(d * d.x, d * d.y);
        moved += mat2x2f(uv * d.x, uv * d.y);
    }
    let det = spread[0].x * spread[1].y - spread[1].x * spread[0].y;
    let inverse = mat2x2f(vec2f(spread[1].y, -spread[0].y), vec2f(-spread[1].x, spread[0].x)) * (1.0 / det);
    return moved * inverse;
}

// through.rs: footprint_cell_sample, of `texture` over the quarter of the pixel that the ray
// through offset `ray` stands for.
fn footprint_cell_sample(texture: u32, uv: vec2f, ray: vec2f, gradients: mat2x2f, size: vec2f) -> vec4f {
    var taps = CELL_TAPS;
    let quarter = vec2f(select(-0.25, 0.25, ray.x >= 0.0), select(-0.25, 0.25, ray.y >= 0.0));
    let half_cell = 0.125 * max(length(gradients[0]), length(gradients[1]));
    let lod = log2(max(half_cell, 1.0));
    var sum = vec4f(0.0);
    for (var t = 0u; t < 4u; t++) {
        sum += sample_texture_lod(texture, uv + gradients * (quarter + taps[t] - ray) / size, lod);
    }
    return sum * 0.25;
}

// through.rs: footprint_albedo's point lookup, for `end` at mip level `lod` of its material's
// texture; an end without one keeps its base colour.
fn footprint_albedo(end: FootprintEnd, lod: f32) -> vec3f {
    if end.material == NONE {
        return end.albedo;
    }
    let texture = bitcast<u32>(materials[end.material * MATERIAL_VEC4S].w);
    return end.albedo * sample_texture_lod(texture, end.uv, lod).xyz;
}

// through.rs: footprint_albedo over the cells, for the end of the ray through `point`.
fn footprint_cell_albedo(end: FootprintEnd, point: u32, gradients: mat2x2f) -> vec3f {
    var points = FOOTPRINT;
    let texture = bitcast<u32>(materials[end.material * MATERIAL_VEC4S].w);
    return end.albedo * footprint_cell_sample(texture, end.uv, points[point], gradients, texture_size(end.material)).xyz;
}

// through.rs: footprint_spread, over the first `count` of `positions`.
fn footprint_spread(ends: ptr<function, array<FootprintEnd, LOBE_SAMPLES>>, count: u32, path_length: f32) -> f32 {
    if count == 0u || !(path_length > 0.0) {
        return 0.0;
    }
    var mean = vec3f(0.0);
    for (var j = 0u; j < count; j++) {
        mean += (*ends)[j].position;
    }
    mean /= f32(count);
    var squares = 0.0;
    for (var j = 0u; j < count; j++) {
        let d = (*ends)[j].position - mean;
        squares += dot(d, d);
    }
    let rms = sqrt(squares / f32(count));
    return log2(1.0 + rms / (FOOTPRINT_RMS * path_length * params.pixel_size));
}

@compute @workgroup_size(8, 8, 1)
fn through_pass(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let pixels = params.width * params.height;
    let i = id.y * params.width + id.x;
    for (var c = 0u; c < THROUGH_CHANNELS; c++) {
        object_planes[params.through_offset + c * pixels + i] = 0.0;
    }
    if object_planes[params.coverage_offset + i] <= 0.0 {
        return;
    }
    let end = trace_path(params.camera_position.xyz, pixel_ray(id.xy, vec2f(0.0)), id.xy, NO_SAMPLE);
    if !end.valid {
        return;
    }
    // The background is nowhere on screen.
    var view = vec4f(0.0);
    if !end.background {
        view = on_screen(end.position);
    }
    // What the pixel shows is the mean over its footprint: a path a ray loses adds nothing.
    var points = FOOTPRINT;
    var ends: array<FootprintEnd, LOBE_SAMPLES>;
    var hits = 0u;
    var albedo = vec3f(0.0);
    var light = vec3f(0.0);
    var transmittance = 0.0;
    let paths = select(FOOTPRINT_POINTS, LOBE_SAMPLES, params.rough != 0u);
    for (var s = 0u; s < paths; s++) {
        let direction = pixel_ray(id.xy, points[s % FOOTPRINT_POINTS]);
        let h = trace_path(params.camera_position.xyz, direction, id.xy, select(NO_SAMPLE, s, params.rough != 0u));
        if h.valid {
            var h_view = vec4f(0.0);
            if !h.is_light {
                h_view = on_screen(h.position);
            }
            let seen = !h.is_light && h_view.z != 0.0 && h_view.w != 0.0;
            transmittance += h.transmittance;
            ends[hits] = FootprintEnd(h.position, h.transmittance, h.albedo, h.material, h.uv, light_at(h, h_view), select(h.diffuse, 0.0, seen), h.normal);
            hits += 1u;
        }
    }
    // Where every footprint ray reached the same textured material, each reads it over its
    // quarter of the pixel; otherwise each material's level depends on all its ends, and is
    // computed once for a run of them.
    var one_material = paths == FOOTPRINT_POINTS && hits == paths && ends[0].material != NONE;
    for (var j = 1u; j < hits; j++) {
        one_material = one_material && ends[j].material == ends[0].material;
    }
    if one_material {
        let gradients = footprint_gradients(&ends, texture_size(ends[0].material));
        for (var j = 0u; j < hits; j++) {
            let a = footprint_cell_albedo(ends[j], j, gradients);
            albedo += a * ends[j].transmittance;
            light += end_light(ends[j], a, j) * ends[j].transmittance;
        }
    } else {
        var lod_material = NONE;
        var lod = 0.0;
        for (var j = 0u; j < hits; j++) {
            let e = ends[j];
            if e.material != NONE && e.material != lod_material {
                lod_material = e.material;
                lod = footprint_lod(&ends, hits, e.material, texture_size(e.material), paths);
            }
            let a = footprint_albedo(e, lod);
            albedo += a * e.transmittance;
            light += end_light(e, a, j) * e.transmittance;
        }
    }
    // Albedo and light as seen: weighted by what each path lets through.
    if transmittance > 0.0 {
        albedo /= transmittance;
        light /= transmittance;
    }
    transmittance /= f32(paths);
    if view.z != 0.0 {
        object_planes[params.through_offset + (THROUGH_SCREEN_OFFSET) * pixels + i] = view.x - f32(id.x);
        object_planes[params.through_offset + (THROUGH_SCREEN_OFFSET + 1u) * pixels + i] = view.y - f32(id.y);
        object_planes[params.through_offset + THROUGH_ON_SCREEN * pixels + i] = view.w;
    }
    for (var c = 0u; c < 3u; c++) {
        object_planes[params.through_offset + (THROUGH_POSITION + c) * pixels + i] = end.position[c];
        object_planes[params.through_offset + (THROUGH_NORMAL + c) * pixels + i] = end.normal[c];
        object_planes[params.through_offset + (THROUGH_ALBEDO + c) * pixels + i] = albedo[c];
        object_planes[params.through_offset + (THROUGH_LD + c) * pixels + i] = light[c];
    }
    object_planes[params.through_offset + THROUGH_TRANSMITTANCE * pixels + i] = transmittance;
    object_planes[params.through_offset + THROUGH_LENGTH * pixels + i] = end.length;
    object_planes[params.through_offset + THROUGH_SPREAD * pixels + i] = footprint_spread(&ends, hits, end.path_length);
}
