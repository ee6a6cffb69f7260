//! Running the GPU BSDF (`shaders/bsdf.wgsl`) and light sampler (`shaders/trace.wgsl`) on
//! chosen inputs, so that they can be checked against the CPU code they port, case by case.

use glam::{Vec2, Vec3};
use glassbake_core::Result;
use glassbake_trace::SurfaceMaterial;
use wgpu::util::DeviceExt;

use crate::tracer::{compute_pipeline, GpuTracer};
use crate::upload::material_vec4s;

const INPUT_VEC4S: usize = 7;
const OUTPUT_VEC4S: usize = 5;

/// One evaluation and one sample of a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct ProbeCase {
    pub material: SurfaceMaterial,
    /// Unit shading normal.
    pub normal: Vec3,
    pub lambertian: bool,
    pub wo: Vec3,
    /// Direction for eval/pdf.
    pub wi: Vec3,
    /// Random numbers for sampling.
    pub u_lobe: f32,
    pub u_event: f32,
    pub u: Vec2,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
    pub delta: bool,
    pub transmitted: bool,
    pub pass_through: bool,
    pub etap: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeResult {
    /// f(wo, wi) and its sampling density.
    pub eval: Vec3,
    pub pdf: f32,
    pub sample: Option<ProbeSample>,
    /// Attenuation and probability of passing straight through a smooth thin pane.
    pub pass_through: Option<(Vec3, f32)>,
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// Evaluate and sample the GPU BSDF for every case.
pub fn probe_bsdf(tracer: &GpuTracer, cases: &[ProbeCase]) -> Result<Vec<ProbeResult>> {
    if cases.is_empty() {
        return Ok(Vec::new());
    }
    let (device, _) = tracer.device();
    let constants = crate::tracer::shared_constants();
    let source =
        [constants.as_str(), glassbake_rays::gpu_bvh::OPTICS_WGSL, include_str!("../shaders/bsdf.wgsl"), include_str!("../shaders/probe.wgsl")].join("\n");
    let pipeline = compute_pipeline(device, "probe.wgsl", source, "bsdf_probe")?;
    let mut inputs: Vec<[f32; 4]> = Vec::with_capacity(cases.len() * INPUT_VEC4S);
    for c in cases {
        inputs.extend(material_vec4s(&c.material));
        inputs.push(v4(c.normal, if c.lambertian { 1.0 } else { 0.0 }));
        inputs.push(v4(c.wo, c.u_lobe));
        inputs.push(v4(c.wi, c.u_event));
        inputs.push([c.u.x, c.u.y, 0.0, 0.0]);
    }
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("probe inputs"),
        contents: bytemuck::cast_slice(&inputs),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let out = run_probe(tracer, &pipeline, "probe", &[(0, &input)], 1, cases.len(), OUTPUT_VEC4S)?;
    let xyz = |v: [f32; 4]| Vec3::new(v[0], v[1], v[2]);
    Ok(out
        .chunks_exact(OUTPUT_VEC4S)
        .map(|r| {
            let flags = r[2][3] as u32;
            ProbeResult {
                eval: xyz(r[0]),
                pdf: r[0][3],
                sample: (flags & 1 != 0).then(|| ProbeSample {
                    wi: xyz(r[1]),
                    weight: xyz(r[2]),
                    pdf: r[1][3],
                    delta: flags & 2 != 0,
                    transmitted: flags & 4 != 0,
                    pass_through: flags & 8 != 0,
                    etap: r[4][0],
                }),
                pass_through: (r[3][3] >= 0.0).then(|| (xyz(r[3]), r[3][3])),
            }
        })
        .collect())
}

/// One light sample from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightProbeCase {
    pub shading_point: Vec3,
    pub u_select: f32,
    pub u: Vec2,
}

/// What the GPU light sampler drew for a [`LightProbeCase`], and the density its `light_pdf`
/// gives the picked emitter at the drawn point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightProbeResult {
    /// `None` when no sample was drawn (the point faces away from the light, say).
    pub sample: Option<LightProbeSample>,
    /// The emitter picked (an index into the emitter table the CPU light sampler built).
    pub emitter: u32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightProbeSample {
    pub point: Vec3,
    pub wi: Vec3,
    pub radiance: Vec3,
    /// Solid-angle density of the sample, selection included.
    pub pdf: f32,
    /// `light_pdf(emitter, shading point, point)`: what MIS reads for a BSDF-sampled hit.
    pub pdf_at_point: f32,
}

/// Sample the GPU light sampler of `scene` (the kernel's own code and emitter table) for
/// every case.
pub fn probe_lights(tracer: &GpuTracer, scene: &glassbake_scene::Scene, cases: &[LightProbeCase]) -> Result<Vec<LightProbeResult>> {
    if cases.is_empty() {
        return Ok(Vec::new());
    }
    let buffers = crate::upload::SceneBuffers::build(scene)?;
    let (device, _) = tracer.device();
    let source = [crate::tracer::trace_source().as_str(), include_str!("../shaders/light_probe.wgsl")].join("\n");
    let pipeline = compute_pipeline(device, "light_probe.wgsl", source, "light_probe")?;
    let mut params: crate::tracer::Params = bytemuck::Zeroable::zeroed();
    params.emitter_count = buffers.emitter_count;
    let mut inputs: Vec<[f32; 4]> = Vec::with_capacity(cases.len() * 2);
    for c in cases {
        inputs.push(v4(c.shading_point, c.u_select));
        inputs.push([c.u.x, c.u.y, 0.0, 0.0]);
    }
    let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    let uniform = init("light probe params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM);
    // Bindings cannot be empty: an empty table travels as one unused vec4.
    let emitters: &[[f32; 4]] = if buffers.emitters.is_empty() { &[[0.0; 4]] } else { &buffers.emitters };
    let emitters = init("light probe emitters", bytemuck::cast_slice(emitters), wgpu::BufferUsages::STORAGE);
    let input = init("light probe inputs", bytemuck::cast_slice(&inputs), wgpu::BufferUsages::STORAGE);
    let out = run_probe(tracer, &pipeline, "light probe", &[(0, &uniform), (6, &emitters), (9, &input)], 10, cases.len(), 4)?;
    let xyz = |v: [f32; 4]| Vec3::new(v[0], v[1], v[2]);
    Ok(out
        .chunks_exact(4)
        .map(|r| LightProbeResult {
            sample: (r[1][3] != 0.0).then(|| LightProbeSample { point: xyz(r[0]), wi: xyz(r[1]), radiance: xyz(r[2]), pdf: r[0][3], pdf_at_point: r[2][3] }),
            emitter: r[3][0] as u32,
        })
        .collect())
}

/// Run `pipeline` once per case (workgroups of 64) with `inputs` bound at their bindings and an
/// output of `output_vec4s` vec4s per case at `output_binding`; the outputs, read back.
fn run_probe(
    tracer: &GpuTracer,
    pipeline: &wgpu::ComputePipeline,
    label: &str,
    inputs: &[(u32, &wgpu::Buffer)],
    output_binding: u32,
    cases: usize,
    output_vec4s: usize,
) -> Result<Vec<[f32; 4]>> {
    let (device, queue) = tracer.device();
    let output_bytes = (cases * output_vec4s * 16) as u64;
    let buffer =
        |usage: wgpu::BufferUsages| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: output_bytes, usage, mapped_at_creation: false });
    let output = buffer(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
    let readback = buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let mut entries: Vec<wgpu::BindGroupEntry> =
        inputs.iter().map(|(binding, buffer)| wgpu::BindGroupEntry { binding: *binding, resource: buffer.as_entire_binding() }).collect();
    entries.push(wgpu::BindGroupEntry { binding: output_binding, resource: output.as_entire_binding() });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout: &pipeline.get_bind_group_layout(0), entries: &entries });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups((cases as u32).div_ceil(64), 1, 1);
    }
    queue.submit([encoder.finish()]);
    Ok(bytemuck::pod_collect_to_vec(&tracer.read(&output, &readback, output_bytes)?))
}
