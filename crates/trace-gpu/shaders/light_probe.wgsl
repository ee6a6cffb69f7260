// Samples the GPU light sampler (trace.wgsl's `sample_light`) and evaluates its density
// (`light_pdf`) on given inputs, so tests can compare them with the CPU light sampler case by
// case. Appended to the trace kernel's source; uses its `params.emitter_count` and `emitters`.

// Per case: (shading point, u_select), (u, -, -).
@group(0) @binding(9) var<storage, read> light_probe_inputs: array<vec4f>;
// Per case: (point, pdf of the sample), (wi, 1 if a sample was drawn else 0), (radiance,
// light_pdf of the picked emitter at the point), (picked emitter, -, -, -).
@group(0) @binding(10) var<storage, read_write> light_probe_outputs: array<vec4f>;

@compute @workgroup_size(64)
fn light_probe(@builtin(global_invocation_id) id: vec3u) {
    let cases = arrayLength(&light_probe_inputs) / 2u;
    if id.x >= cases || params.emitter_count == 0u {
        return;
    }
    let shading_point = light_probe_inputs[2u * id.x].xyz;
    let u_select = light_probe_inputs[2u * id.x].w;
    let u = light_probe_inputs[2u * id.x + 1u].xy;
    let index = select_emitter(u_select);
    let s = sample_light(shading_point, u_select, u);
    let o = 4u * id.x;
    light_probe_outputs[o] = vec4f(s.point, s.pdf);
    light_probe_outputs[o + 1u] = vec4f(s.wi, select(0.0, 1.0, s.valid));
    light_probe_outputs[o + 2u] = vec4f(s.radiance, light_pdf(index, shading_point, s.point));
    light_probe_outputs[o + 3u] = vec4f(f32(index), 0.0, 0.0, 0.0);
}
