// G-buffer, transparency-buffer and shadow-map passes of glassbake-raster.
//
// Render targets (all Rgba32Float, no blending):
//   0: normal.xyz (world, unit, facing the camera), roughness
//   1: position.xyz (world), depth (Euclidean distance to the camera)
//   2: albedo.rgb (linear, textured), coverage (1 where drawn)
//   3: w_o.xyz (unit, towards the camera), relative depth (transparency pass only, else 0)
//   4: L_d.rgb (direct light incl. emission; in the transparency pass the light the
//      transparent surface reflects), 0
// and in the transparency pass's second ("far") pass, which keeps each pixel's farthest
// surface of the object in front of the opaque scene:
//   5: L_d.rgb of that far surface (the inside of a globe's far wall), 0
// The host unpacks these into the planar channel order of glassbake_core::layout.

// LTC_SIZE (the LTC tables' cells per axis) and DIELECTRIC_F0 (glTF's dielectric base, IOR
// 1.5) are written before this file from Rust (`rasterizer::gbuffer_source`).

struct View {
    view_proj: mat4x4<f32>,
    // xyz: camera position
    camera_pos: vec4<f32>,
    // x: number of rectangle lights, y: shadows enabled (1/0)
    params: vec4<u32>,
};

struct ObjectData {
    model: mat4x4<f32>,
    // Inverse transpose of the model matrix (upper 3x3 used).
    normal_matrix: mat4x4<f32>,
    // rgb: base colour (the tint for glass), w: roughness (perceptual, alpha = r^2)
    base_color: vec4<f32>,
    // rgb: emitted radiance, w: metallic
    emission: vec4<f32>,
    // x: transmission weight, y: 1 for a rectangle light's own quad, z: 1 if that light is two-sided
    params: vec4<f32>,
};

struct Light {
    // Corners, counter-clockwise seen from the emitting side (RectLight::corners).
    p0: vec4<f32>,
    p1: vec4<f32>,
    p2: vec4<f32>,
    p3: vec4<f32>,
    // rgb: radiance, w: two-sided (1/0)
    radiance: vec4<f32>,
    // Shadow hemicube of each side: 5 layers (and view-projections in `shadow_matrices`)
    // looking from the light's centre along s, t, -t, b, -b, where s is the side's normal,
    // t = normalize(edge_u) and b = s x t.
    // x: first layer of the front (emitting) side, y: of the back side (-1: none);
    // z: normal offset (world units per unit distance to the light) against shadow acne.
    shadow: vec4<f32>,
};

@group(0) @binding(0) var<uniform> view: View;

@group(1) @binding(0) var<uniform> object: ObjectData;
@group(1) @binding(1) var base_color_texture: texture_2d<f32>;
@group(1) @binding(2) var roughness_texture: texture_2d<f32>;
@group(1) @binding(3) var material_sampler: sampler;

@group(2) @binding(0) var<storage, read> lights: array<Light>;
@group(2) @binding(1) var shadow_maps: texture_depth_2d_array;
@group(2) @binding(2) var shadow_sampler: sampler_comparison;
// LTC tables (Heitz et al. 2016), LTC_SIZE^2, indexed by (roughness, sqrt(1 - cos theta_v)):
// ltc_matrix = the inverse matrix entries (m00, m02, m11, m20) with m22 = 1,
// ltc_amplitude = (A, B): the GGX lobe's integral is F0 * A + B (Schlick Fresnel split).
@group(2) @binding(3) var ltc_matrix: texture_2d<f32>;
@group(2) @binding(4) var ltc_amplitude: texture_2d<f32>;
// Target 1 of the opaque pass (position, depth), read by the transparency pass.
@group(2) @binding(5) var opaque_position_depth: texture_2d<f32>;
@group(2) @binding(6) var<storage, read> shadow_matrices: array<mat4x4<f32>>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
};

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>, @location(2) uv: vec2<f32>) -> VsOut {
    var out: VsOut;
    let world = object.model * vec4<f32>(position, 1.0);
    out.clip = view.view_proj * world;
    out.world_pos = world.xyz;
    out.normal = (object.normal_matrix * vec4<f32>(normal, 0.0)).xyz;
    out.uv = uv;
    return out;
}

@vertex
fn vs_shadow(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    return view.view_proj * (object.model * vec4<f32>(position, 1.0));
}

struct Surface {
    position: vec3<f32>,
    // Shading normal, flipped to the camera's side of the surface.
    normal: vec3<f32>,
    // Unflipped shading normal (the side the mesh declares as front).
    declared_normal: vec3<f32>,
    // Geometric (face) normal, on the camera's side.
    face_normal: vec3<f32>,
    wo: vec3<f32>,
    depth: f32,
    albedo: vec3<f32>,
    roughness: f32,
    // Screen-space derivatives of the position and of the interpolated (unnormalised,
    // declared-side) normal, for shading over the pixel's footprint.
    dp_dx: vec3<f32>,
    dp_dy: vec3<f32>,
    dn_dx: vec3<f32>,
    dn_dy: vec3<f32>,
    raw_normal: vec3<f32>,
};

// A texture's mean over the pixel's footprint: what the path tracer's pixel (a box) averages.
// One trilinear lookup at the centre blurs over about twice the footprint (its mip level is
// chosen for the footprint's longer side, then blended bilinearly and with the next level),
// and a device's anisotropic filter is its own. On desk's page at 96 px that turned the
// print's rows into an even grey: 28.4 dB against the box mean of 16x16 sub-pixels, where
// these 4x4 lookups score 42.5 (docs/benchmarks.md). Each reads its cell of the footprint
// with half the cell's gradients: a trilinear lookup's tent is about twice as wide as its
// gradients, so the 16 tents tile the pixel instead of overlapping.
const FOOTPRINT_TAPS: u32 = 4u;

fn footprint_sample(t: texture_2d<f32>, uv: vec2<f32>) -> vec4<f32> {
    let du_dx = dpdx(uv);
    let du_dy = dpdy(uv);
    let n = f32(FOOTPRINT_TAPS);
    let tap_dx = du_dx / (2.0 * n);
    let tap_dy = du_dy / (2.0 * n);
    var sum = vec4<f32>(0.0);
    for (var i = 0u; i < FOOTPRINT_TAPS * FOOTPRINT_TAPS; i = i + 1u) {
        let cell = vec2<f32>(f32(i % FOOTPRINT_TAPS), f32(i / FOOTPRINT_TAPS));
        let offset = (cell + 0.5) / n - 0.5;
        sum = sum + textureSampleGrad(t, material_sampler, uv + offset.x * du_dx + offset.y * du_dy, tap_dx, tap_dy);
    }
    return sum / (n * n);
}

fn surface(in: VsOut) -> Surface {
    var s: Surface;
    s.position = in.world_pos;
    let to_camera = view.camera_pos.xyz - in.world_pos;
    s.depth = length(to_camera);
    s.wo = to_camera / s.depth;
    s.dp_dx = dpdx(in.world_pos);
    s.dp_dy = dpdy(in.world_pos);
    s.dn_dx = dpdx(in.normal);
    s.dn_dy = dpdy(in.normal);
    s.raw_normal = in.normal;
    // Face normal from screen-space derivatives: independent of the mesh's winding order.
    var ng = cross(s.dp_dx, s.dp_dy);
    let ng_len = length(ng);
    if ng_len > 0.0 {
        ng = ng / ng_len;
    } else {
        ng = s.wo;
    }
    if dot(ng, s.wo) < 0.0 {
        ng = -ng;
    }
    s.face_normal = ng;
    var n = in.normal;
    let n_len = length(n);
    if n_len > 0.0 {
        n = n / n_len;
    } else {
        n = ng;
    }
    s.declared_normal = n;
    if dot(n, ng) < 0.0 {
        n = -n;
    }
    s.normal = n;
    let tex = footprint_sample(base_color_texture, in.uv);
    let rough_tex = footprint_sample(roughness_texture, in.uv);
    s.albedo = object.base_color.rgb * tex.rgb;
    s.roughness = clamp(object.base_color.w * rough_tex.g, 0.0, 1.0);
    return s;
}

// ---------------------------------------------------------------------------------------
// Polygon integrals of the clamped cosine (Lambert / Arvo's formula) and LTC; `integrate_edge`,
// `polygon_form_factor` and `frame_around` come before this file (glassbake-rays' polygon.wgsl).

fn ltc_fetch(tex: texture_2d<f32>, x: i32, y: i32) -> vec4<f32> {
    return textureLoad(tex, vec2<i32>(clamp(x, 0, LTC_SIZE - 1), clamp(y, 0, LTC_SIZE - 1)), 0);
}

// Bilinear lookup in an LTC table at continuous coordinates in [0, 1]^2 (texel centres at
// the ends), done by hand because Rgba32Float is not filterable everywhere.
fn ltc_lookup(tex: texture_2d<f32>, uv: vec2<f32>) -> vec4<f32> {
    let f = clamp(uv, vec2<f32>(0.0), vec2<f32>(1.0)) * f32(LTC_SIZE - 1);
    let i = vec2<i32>(floor(f));
    let t = f - floor(f);
    let a = ltc_fetch(tex, i.x, i.y);
    let b = ltc_fetch(tex, i.x + 1, i.y);
    let c = ltc_fetch(tex, i.x, i.y + 1);
    let d = ltc_fetch(tex, i.x + 1, i.y + 1);
    return mix(mix(a, b, t.x), mix(c, d, t.x), t.y);
}

fn shadow_visibility(light: Light, p: vec3<f32>, n: vec3<f32>, back: bool) -> f32 {
    var first = light.shadow.x;
    if back {
        first = light.shadow.y;
    }
    if view.params.y == 0u || first < 0.0 {
        return 1.0;
    }
    let centre = 0.25 * (light.p0.xyz + light.p1.xyz + light.p2.xyz + light.p3.xyz);
    let t = normalize(light.p1.xyz - light.p0.xyz);
    var side = normalize(cross(light.p1.xyz - light.p0.xyz, light.p3.xyz - light.p0.xyz));
    if back {
        side = -side;
    }
    let b = cross(side, t);
    // Normal offset proportional to the shadow texel footprint at this distance.
    let q = p + n * (light.shadow.z * length(centre - p));
    let d = q - centre;
    let local = vec3<f32>(dot(d, t), dot(d, b), dot(d, side));
    if local.z <= 0.0 && abs(local.z) >= max(abs(local.x), abs(local.y)) {
        return 1.0;
    }
    // The hemicube face of the dominant axis.
    var face = 0;
    if local.z < max(abs(local.x), abs(local.y)) {
        if abs(local.x) >= abs(local.y) {
            face = select(2, 1, local.x > 0.0);
        } else {
            face = select(4, 3, local.y > 0.0);
        }
    }
    let layer = i32(first) + face;
    let clip = shadow_matrices[layer] * vec4<f32>(q, 1.0);
    if clip.w <= 0.0 {
        return 1.0;
    }
    let ndc = clip.xyz / clip.w;
    if ndc.z > 1.0 || ndc.z < 0.0 {
        return 1.0;
    }
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    let dims = vec2<f32>(textureDimensions(shadow_maps));
    let texel = 1.0 / dims;
    var sum = 0.0;
    for (var dy = -1; dy <= 1; dy = dy + 1) {
        for (var dx = -1; dx <= 1; dx = dx + 1) {
            let o = vec2<f32>(f32(dx), f32(dy)) * texel;
            sum = sum + textureSampleCompareLevel(shadow_maps, shadow_sampler, uv + o, layer, ndc.z);
        }
    }
    return sum / 9.0;
}

// Direct light from the rectangle lights at a surface point (diffuse: exact polygon
// form factor; specular: GGX by LTC), plus nothing else (emission is added by the caller).
// The LTC specular lobe of one light at a point with normal n seen from direction v:
// the lobe's integral over the light's polygon times F0 * A + B.
fn ltc_specular(light: Light, p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, roughness: f32, f0: vec3<f32>) -> vec3<f32> {
    // Frame: z = n, x towards v.
    var t1 = v - n * dot(v, n);
    if dot(t1, t1) < 1e-12 {
        t1 = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(n.x) > 0.9);
        t1 = t1 - n * dot(t1, n);
    }
    t1 = normalize(t1);
    let t2 = cross(n, t1);
    let cos_v = clamp(dot(n, v), 0.0, 1.0);
    let uv = vec2<f32>(roughness, sqrt(1.0 - cos_v));
    let m = ltc_lookup(ltc_matrix, uv);
    let amp = ltc_lookup(ltc_amplitude, uv).xy;
    // Inverse LTC matrix in the (t1, t2, n) frame; columns of a WGSL matrix.
    let minv = mat3x3<f32>(vec3<f32>(m.x, 0.0, m.w), vec3<f32>(0.0, m.z, 0.0), vec3<f32>(m.y, 0.0, 1.0));
    let frame = transpose(mat3x3<f32>(t1, t2, n));
    let l0 = frame * (light.p0.xyz - p);
    let l1 = frame * (light.p1.xyz - p);
    let l2 = frame * (light.p2.xyz - p);
    let l3 = frame * (light.p3.xyz - p);
    let form = polygon_form_factor(minv * l0, minv * l1, minv * l2, minv * l3);
    return (f0 * amp.x + vec3<f32>(amp.y)) * max(form, 0.0);
}

// Sharper lobes than this are averaged over the pixel's footprint.
const FOOTPRINT_MAX_ROUGHNESS: f32 = 0.5;

// Direct light from the rectangle lights at a surface point (diffuse: exact polygon
// form factor; specular: GGX by LTC), plus nothing else (emission is added by the caller).
// The specular term of smooth surfaces is the mean of a 3 x 3 grid over the pixel (position
// and normal moved along their screen-space derivatives), as the path-traced ground truth
// box-filters its pixels: a light reflected in a glass ball is a pixel or two wide, and one
// sample at the pixel centre either misses it or draws it as a single too-bright dot.
fn direct_light(s: Surface, metallic: f32, transmission: f32) -> vec3<f32> {
    let n = s.normal;
    let diffuse_color = s.albedo * (1.0 - metallic) * (1.0 - transmission);
    let f0 = mix(vec3<f32>(DIELECTRIC_F0), s.albedo, metallic);
    let taps = select(1, 3, s.roughness < FOOTPRINT_MAX_ROUGHNESS);

    var total = vec3<f32>(0.0);
    let count = view.params.x;
    for (var i = 0u; i < count; i = i + 1u) {
        let light = lights[i];
        let ln = cross(light.p1.xyz - light.p0.xyz, light.p3.xyz - light.p0.xyz);
        let side = dot(s.position - light.p0.xyz, ln);
        let two_sided = light.radiance.w > 0.5;
        if !(side > 0.0 || (two_sided && side < 0.0)) {
            continue;
        }
        let c0 = light.p0.xyz - s.position;
        let c1 = light.p1.xyz - s.position;
        let c2 = light.p2.xyz - s.position;
        let c3 = light.p3.xyz - s.position;
        let frame = frame_around(n);
        let diffuse = polygon_form_factor(frame * c0, frame * c1, frame * c2, frame * c3);
        var specular = vec3<f32>(0.0);
        for (var j = 0; j < taps * taps; j = j + 1) {
            var p = s.position;
            var sn = n;
            if taps > 1 {
                let o = (vec2<f32>(f32(j % taps), f32(j / taps)) + 0.5) / f32(taps) - 0.5;
                p = s.position + o.x * s.dp_dx + o.y * s.dp_dy;
                let moved = s.raw_normal + o.x * s.dn_dx + o.y * s.dn_dy;
                if dot(moved, moved) > 0.0 {
                    sn = normalize(moved);
                    if dot(sn, s.face_normal) < 0.0 {
                        sn = -sn;
                    }
                }
            }
            let v = normalize(view.camera_pos.xyz - p);
            specular = specular + ltc_specular(light, p, sn, v, s.roughness, f0);
        }
        specular = specular / f32(taps * taps);
        if diffuse <= 0.0 && all(specular <= vec3<f32>(0.0)) {
            continue;
        }
        let visibility = shadow_visibility(light, s.position, s.face_normal, side < 0.0);
        total = total + light.radiance.rgb * visibility * (diffuse_color * diffuse + specular);
    }
    return total;
}

// L_d of a drawn surface of the current object: the lights it reflects plus its emission
// (emissive meshes emit from both sides). One function for the G-buffer and transparency
// passes, so a transparency buffer's L_d is the naive G-buffer's at the same surface.
fn surface_light(s: Surface) -> vec3<f32> {
    return direct_light(s, object.emission.w, object.params.x) + object.emission.rgb;
}

struct GBufferOut {
    @location(0) normal_roughness: vec4<f32>,
    @location(1) position_depth: vec4<f32>,
    @location(2) albedo_coverage: vec4<f32>,
    @location(3) wo_relative_depth: vec4<f32>,
    @location(4) direct_light: vec4<f32>,
};

@fragment
fn fs_gbuffer(in: VsOut) -> GBufferOut {
    let s = surface(in);
    var ld = vec3<f32>(0.0);
    if object.params.y > 0.5 {
        // A rectangle light's own quad: its radiance, seen from the emitting side (or both).
        if object.params.z > 0.5 || dot(s.declared_normal, s.wo) > 0.0 {
            ld = object.emission.rgb;
        }
    } else {
        ld = surface_light(s);
    }
    var out: GBufferOut;
    out.normal_roughness = vec4<f32>(s.normal, s.roughness);
    out.position_depth = vec4<f32>(s.position, s.depth);
    out.albedo_coverage = vec4<f32>(s.albedo, 1.0);
    out.wo_relative_depth = vec4<f32>(s.wo, 0.0);
    out.direct_light = vec4<f32>(ld, 0.0);
    return out;
}

struct TransparencyOut {
    @location(0) normal_roughness: vec4<f32>,
    @location(1) position_depth: vec4<f32>,
    @location(2) albedo_coverage: vec4<f32>,
    @location(3) wo_relative_depth: vec4<f32>,
    @location(4) direct_light: vec4<f32>,
};

@fragment
fn fs_transparency(in: VsOut) -> TransparencyOut {
    let s = surface(in);
    let opaque_depth = textureLoad(opaque_position_depth, vec2<i32>(in.clip.xy), 0).w;
    // Hidden behind opaque geometry: not visible, not drawn (coverage stays 0).
    if opaque_depth > 0.0 && s.depth >= opaque_depth {
        discard;
    }
    var relative = 0.0;
    if opaque_depth > 0.0 {
        relative = opaque_depth - s.depth;
    }
    var out: TransparencyOut;
    out.normal_roughness = vec4<f32>(s.normal, s.roughness);
    out.position_depth = vec4<f32>(s.position, s.depth);
    out.albedo_coverage = vec4<f32>(s.albedo, 1.0);
    out.wo_relative_depth = vec4<f32>(s.wo, relative);
    out.direct_light = vec4<f32>(surface_light(s), 0.0);
    return out;
}

// The far pass of a transparency buffer (depth test "greater", cleared to 0): the light the
// object's farthest visible surface reflects. A thin-walled globe or box shows the lights
// twice, in its near wall and, seen through it, in the inside of its far wall; the near
// pass holds only the first.
@fragment
fn fs_transparency_far(in: VsOut) -> @location(0) vec4<f32> {
    let s = surface(in);
    let opaque_depth = textureLoad(opaque_position_depth, vec2<i32>(in.clip.xy), 0).w;
    if opaque_depth > 0.0 && s.depth >= opaque_depth {
        discard;
    }
    return vec4<f32>(surface_light(s), 0.0);
}
