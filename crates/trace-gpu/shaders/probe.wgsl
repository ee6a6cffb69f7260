// Evaluates and samples the GPU BSDF on given inputs, so tests can compare it with the CPU
// BSDF case by case (src/probe.rs writes the records; bsdf.wgsl is prepended).

const PROBE_INPUT_VEC4S: u32 = 7u;
const PROBE_OUTPUT_VEC4S: u32 = 5u;

// Per case: (base colour, roughness), (specular colour, specular), (metallic, transmission
// weight, ior, thin), (normal, lambertian), (wo, u_lobe), (wi, u_event), (u, -, -).
@group(0) @binding(0) var<storage, read> probe_inputs: array<vec4f>;
// Per case: (f, pdf) of eval at (wo, wi); (sample wi, sample pdf); (sample weight, flags:
// 1 valid, 2 delta, 4 transmitted, 8 pass-through); (pass-through rgb, probability or -1);
// (sample etap, -, -, -).
@group(0) @binding(1) var<storage, read_write> probe_outputs: array<vec4f>;

@compute @workgroup_size(64)
fn bsdf_probe(@builtin(global_invocation_id) id: vec3u) {
    let cases = arrayLength(&probe_inputs) / PROBE_INPUT_VEC4S;
    if id.x >= cases {
        return;
    }
    let i = id.x * PROBE_INPUT_VEC4S;
    var m: SurfaceMaterial;
    m.base_color = probe_inputs[i].xyz;
    m.roughness = probe_inputs[i].w;
    m.specular_color = probe_inputs[i + 1u].xyz;
    m.specular = probe_inputs[i + 1u].w;
    m.metallic = probe_inputs[i + 2u].x;
    m.transmission_weight = probe_inputs[i + 2u].y;
    m.ior = probe_inputs[i + 2u].z;
    m.thin = probe_inputs[i + 2u].w != 0.0;
    let normal = probe_inputs[i + 3u].xyz;
    let lambertian = probe_inputs[i + 3u].w != 0.0;
    let wo = probe_inputs[i + 4u].xyz;
    let u_lobe = probe_inputs[i + 4u].w;
    let wi = probe_inputs[i + 5u].xyz;
    let u_event = probe_inputs[i + 5u].w;
    let u = probe_inputs[i + 6u].xy;

    let bsdf = make_bsdf(m, normal, lambertian);
    let o = id.x * PROBE_OUTPUT_VEC4S;
    probe_outputs[o] = bsdf_eval_pdf(bsdf, wo, wi);
    let s = bsdf_sample(bsdf, wo, u_lobe, u_event, u);
    var flags = 0u;
    if s.valid {
        flags |= 1u;
    }
    if s.delta {
        flags |= 2u;
    }
    if s.transmitted {
        flags |= 4u;
    }
    if s.pass_through {
        flags |= 8u;
    }
    probe_outputs[o + 1u] = vec4f(s.wi, s.pdf);
    probe_outputs[o + 2u] = vec4f(s.weight, f32(flags));
    probe_outputs[o + 3u] = bsdf_pass_through(bsdf, wo);
    probe_outputs[o + 4u] = vec4f(s.etap, 0.0, 0.0, 0.0);
}
