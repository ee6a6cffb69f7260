//! Rendering an image on the GPU: one device and pipeline for many images, passes of a few
//! samples per pixel accumulated in a storage buffer, the mean read back at the end.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use glassbake_core::layout::GROUND_TRUTH_CHANNELS;
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_raster::RasterizerOptions;
use glassbake_scene::Scene;
use glassbake_trace::{unlit_warning, Estimator, MaterialModel, Progress, TraceOutput, TraceSettings};
use wgpu::util::DeviceExt;

use glassbake_rays::gpu_bvh::{GpuBvhs, COMMON_WGSL, OPTICS_WGSL};

use crate::upload::SceneBuffers;

/// Threads a pass aims for: a pixel gets several threads (slots) when the image alone has
/// too few pixels to fill a large GPU.
const TARGET_THREADS: u64 = 1 << 18;
/// Most threads per pixel (each slot holds a vec4 and a u32 per pixel).
const MAX_SLOTS: u64 = 64;
/// Samples one thread traces in one pass on a GPU: few enough for steady progress and no
/// driver time-outs.
pub const SAMPLES_PER_THREAD: u32 = 16;
/// The same on a CPU adapter (lavapipe): llvmpipe ends a shader invocation's loops once they
/// have run 65535 iterations in all (measured: with 256 samples per invocation 29-91% of
/// the samples never ran), and one sample's BVH traversals take a few hundred.
pub const SAMPLES_PER_THREAD_LAVAPIPE: u32 = 4;

const WORKGROUP_SIDE: u32 = 8;
const FLAG_LAMBERTIAN: u32 = 1;

/// The kernel's uniform block (`Params` in trace.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct Params {
    camera_position: [f32; 4],
    camera_forward: [f32; 4],
    camera_right: [f32; 4],
    camera_up: [f32; 4],
    background: [f32; 4],
    width: u32,
    height: u32,
    sample_start: u32,
    sample_count: u32,
    seed_lo: u32,
    seed_hi: u32,
    max_depth: u32,
    rr_depth: u32,
    flags: u32,
    pub(crate) emitter_count: u32,
    texture_table: u32,
    has_panes: u32,
    slots: u32,
    _pad: [u32; 3],
}

/// The trace kernel, compiled for one device. Create once, render many images.
pub struct GpuTracer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    adapter: String,
    samples_per_thread: u32,
}

/// The WGSL constants the kernel shares with Rust, written from the Rust constants
/// themselves so that the two cannot drift: the uniform block's flags, the buffer layouts
/// `upload.rs` writes, and the CPU tracer's path-length guard.
pub(crate) fn shared_constants() -> String {
    use crate::upload::*;
    use glassbake_core::wgsl::{constants, Value};
    glassbake_rays::gpu_scene::wgsl_constants()
        + &constants(&[
            ("FLAG_LAMBERTIAN", Value::U32(FLAG_LAMBERTIAN)),
            ("MATERIAL_VEC4S", Value::U32(MATERIAL_VEC4S as u32)),
            ("EMITTER_VEC4S", Value::U32(EMITTER_VEC4S as u32)),
            ("MAX_VERTICES", Value::U32(glassbake_trace::prepared::MAX_VERTICES)),
            // The BSDF's: the CPU tracer's values.
            ("DIELECTRIC_F0", Value::F32(glassbake_trace::bsdf::DIELECTRIC_F0)),
            ("MIN_OPAQUE_ALPHA", Value::F32(glassbake_trace::bsdf::MIN_OPAQUE_ALPHA)),
            ("MIN_ALPHA", Value::F32(glassbake_trace::microfacet::MIN_ALPHA)),
            ("SMOOTH_ROUGHNESS", Value::F32(glassbake_scene::model::SMOOTH_ROUGHNESS)),
        ])
}

/// The WGSL source of the trace kernel: the constants it shares with Rust, the optics and the
/// BSDF, the BVH traversal, the hash and texture sampling (the rays crate's but the BSDF), then
/// the integrator.
pub(crate) fn trace_source() -> String {
    [shared_constants().as_str(), OPTICS_WGSL, include_str!("../shaders/bsdf.wgsl"), &GpuBvhs::wgsl(), COMMON_WGSL, include_str!("../shaders/trace.wgsl")]
        .join("\n")
}

/// Compile `source` into a compute pipeline with the layout its bindings imply.
pub(crate) fn compute_pipeline(device: &wgpu::Device, label: &str, source: String, entry: &str) -> Result<wgpu::ComputePipeline> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(Error::Internal(format!("compiling {label}: {e}")));
    }
    Ok(pipeline)
}

impl GpuTracer {
    /// Open the Vulkan adapter the options choose (as the rasterizer does) and compile the
    /// kernel.
    pub fn new(options: &RasterizerOptions) -> Result<Self> {
        let (_, adapter, device, queue) = glassbake_raster::device::open(options)?;
        let pipeline = compute_pipeline(&device, "trace.wgsl", trace_source(), "trace_pass")?;
        let info = adapter.get_info();
        let samples_per_thread = if info.device_type == wgpu::DeviceType::Cpu { SAMPLES_PER_THREAD_LAVAPIPE } else { SAMPLES_PER_THREAD };
        Ok(GpuTracer { device, queue, pipeline, adapter: info.name, samples_per_thread })
    }

    pub fn adapter_name(&self) -> &str {
        &self.adapter
    }

    pub(crate) fn device(&self) -> (&wgpu::Device, &wgpu::Queue) {
        (&self.device, &self.queue)
    }

    /// Path trace `scene` as seen by `camera`. `settings.threads` has no meaning here; the
    /// GPU runs [`Estimator::PLAIN`] only, and refuses any other.
    pub fn render(&self, scene: &Scene, camera: &Camera, settings: &TraceSettings, progress: Option<Progress>) -> Result<TraceOutput> {
        let start = Instant::now();
        check_settings(settings)?;
        camera.check()?;
        let (width, height) = (settings.width, settings.height);
        let pixels = width as u64 * height as u64;
        let samples = pixels * settings.spp as u64;
        let mut image = PlanarImage::new(width, height, GROUND_TRUTH_CHANNELS.iter().map(|c| c.to_string()).collect());
        let buffers = SceneBuffers::build(scene)?;
        if let Some(warning) = unlit_warning(scene, buffers.emitter_count == 0) {
            if let Some(p) = progress {
                p(samples, samples);
            }
            return Ok(TraceOutput::plain(image, samples, vec![warning], start.elapsed()));
        }
        let slots = (TARGET_THREADS / pixels).clamp(1, MAX_SLOTS);
        let limits = self.device.limits();
        let binding_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        check_sizes(&scene.name, &buffers, pixels * slots, binding_limit, &self.adapter)?;

        let storage = |label: &str, data: &Vec<[f32; 4]>| {
            // Bindings cannot be empty: an empty array travels as one unused vec4.
            let padded: &[[f32; 4]] = if data.is_empty() { &[[0.0; 4]] } else { data };
            self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(padded),
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let arrays: Vec<wgpu::Buffer> = buffers.arrays().iter().map(|(label, data)| storage(label, data)).collect();
        let accumulation_bytes = pixels * slots * 16;
        let discarded_bytes = pixels * slots * 4;
        let result_buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            self.device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
        };
        let results = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let readback = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let accumulation = result_buffer("accumulation", accumulation_bytes, results);
        let discarded = result_buffer("discarded", discarded_bytes, results);
        let accumulation_readback = result_buffer("accumulation readback", accumulation_bytes, readback);
        let discarded_readback = result_buffer("discarded readback", discarded_bytes, readback);
        let uniform = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("trace params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() }];
        for (i, buffer) in arrays.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry { binding: i as u32 + 1, resource: buffer.as_entire_binding() });
        }
        entries.push(wgpu::BindGroupEntry { binding: 7, resource: accumulation.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 8, resource: discarded.as_entire_binding() });
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });

        let mut params = trace_params(scene, camera, settings, &buffers, slots as u32);

        let per_pass = (slots as u32 * self.samples_per_thread).min(settings.spp);
        let mut done = 0u32;
        while done < settings.spp {
            params.sample_start = done;
            params.sample_count = per_pass.min(settings.spp - done);
            self.queue.write_buffer(&uniform, 0, bytemuck::bytes_of(&params));
            let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("trace pass") });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("trace pass"), timestamp_writes: None });
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(width.div_ceil(WORKGROUP_SIDE), height.div_ceil(WORKGROUP_SIDE), slots as u32);
            }
            self.queue.submit([encoder.finish()]);
            self.wait()?;
            done += params.sample_count;
            if let Some(p) = progress {
                p(pixels * done as u64, samples);
            }
        }

        let sums: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&self.read(&accumulation, &accumulation_readback, accumulation_bytes)?);
        let not_finite: Vec<u32> = bytemuck::pod_collect_to_vec(&self.read(&discarded, &discarded_readback, discarded_bytes)?);
        let (finite_samples, discarded_samples) = mean_of_slots(&mut image, &sums, &not_finite, slots as usize);
        if finite_samples + discarded_samples != samples {
            return Err(Error::Internal(format!(
                "the GPU ({}) traced {} of {samples} samples: the driver ended shader loops early \
                 (llvmpipe stops an invocation after 65535 loop iterations in all)",
                self.adapter,
                finite_samples + discarded_samples
            )));
        }
        let mut warnings = Vec::new();
        if discarded_samples > 0 {
            let warning = format!("{discarded_samples} of {samples} samples were NaN or infinite and were discarded");
            tracing::warn!("{warning}");
            warnings.push(warning);
        }
        Ok(TraceOutput { discarded_samples, ..TraceOutput::plain(image, samples, warnings, start.elapsed()) })
    }

    pub(crate) fn wait(&self) -> Result<()> {
        self.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| Error::Internal(format!("waiting for the GPU: {e}")))
    }

    /// Copy `source` into `readback` and read its bytes.
    pub(crate) fn read(&self, source: &wgpu::Buffer, readback: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
        glassbake_rays::gpu_readback::read_back(&self.device, &self.queue, source, 0, readback, bytes)
    }
}

/// A clear error, before anything is allocated, when the scene or the image's sums do not fit
/// the device's storage buffer limit.
fn check_sizes(scene: &str, buffers: &SceneBuffers, pixel_slots: u64, binding_limit: u64, adapter: &str) -> Result<()> {
    for (name, data) in buffers.arrays() {
        let bytes = data.len() as u64 * 16;
        if bytes > binding_limit {
            return Err(Error::bad_input(
                scene,
                name,
                format!(
                    "{bytes} bytes exceed the GPU's storage buffer limit of {binding_limit} bytes \
                     (max_storage_buffer_binding_size on {adapter}); trace it on the CPU"
                ),
            ));
        }
    }
    if pixel_slots * 16 > binding_limit {
        return Err(Error::bad_input(
            "trace settings",
            "resolution",
            format!("the image's sums need {} bytes, over the GPU's storage buffer limit of {binding_limit} bytes on {adapter}", pixel_slots * 16),
        ));
    }
    Ok(())
}

/// Refuses what the GPU tracer does not do: any estimator but [`Estimator::PLAIN`], path
/// filters, more samples on glass pixels.
fn check_settings(settings: &TraceSettings) -> Result<()> {
    settings.validate()?;
    if settings.estimator != Estimator::PLAIN {
        return Err(Error::bad_input(
            "--estimator",
            settings.estimator.name(),
            "the GPU tracer runs the plain estimator only (no light tracer, uniform pixels, independent values); the others run on the CPU only",
        ));
    }
    if settings.path_filter != glassbake_trace::PathFilter::All {
        return Err(Error::bad_input("trace settings", "path_filter", "the GPU tracer renders every path; path filters run on the CPU only"));
    }
    if settings.glass_spp.is_some_and(|glass_spp| glass_spp > settings.spp) {
        return Err(Error::bad_input("trace settings", "glass_spp", "the GPU tracer renders every pixel at one spp: trace at the glass pixels' spp instead"));
    }
    Ok(())
}

/// The kernel's parameters for a frame (its sample range is set per pass).
fn trace_params(scene: &Scene, camera: &Camera, settings: &TraceSettings, buffers: &SceneBuffers, slots: u32) -> Params {
    let (width, height) = (settings.width, settings.height);
    let frame = camera.frame();
    let (tx, ty) = camera.tan_half_fov(width, height);
    let mut flags = 0;
    if settings.material_model == MaterialModel::Lambertian {
        flags |= FLAG_LAMBERTIAN;
    }
    let v4 = |v: Vec3| [v.x, v.y, v.z, 0.0];
    Params {
        camera_position: v4(camera.position),
        camera_forward: v4(frame.forward),
        camera_right: v4(frame.right * tx),
        camera_up: v4(frame.up * ty),
        background: v4(scene.background),
        width,
        height,
        sample_start: 0,
        sample_count: 0,
        seed_lo: settings.seed as u32,
        seed_hi: (settings.seed >> 32) as u32,
        max_depth: settings.max_depth,
        rr_depth: settings.rr_depth,
        flags,
        emitter_count: buffers.emitter_count,
        texture_table: buffers.texture_table,
        has_panes: buffers.has_panes as u32,
        slots,
        _pad: [0; 3],
    }
}

/// Fills `image` with each pixel's mean over the finite samples of every slot, summed in slot
/// order in f64 so that the mean does not depend on how the GPU scheduled them. Returns the
/// finite and the discarded samples.
fn mean_of_slots(image: &mut PlanarImage, sums: &[[f32; 4]], not_finite: &[u32], slots: usize) -> (u64, u64) {
    let (width, height) = (image.width(), image.height());
    let pixels = width as u64 * height as u64;
    let (mut finite_samples, mut discarded_samples) = (0u64, 0u64);
    for y in 0..height {
        for x in 0..width {
            let pixel = (y as u64 * width as u64 + x as u64) as usize;
            let (mut sum, mut count) = ([0.0f64; 3], 0.0f64);
            for slot in 0..slots {
                let [r, g, b, n] = sums[slot * pixels as usize + pixel];
                sum = [sum[0] + r as f64, sum[1] + g as f64, sum[2] + b as f64];
                count += n as f64;
                discarded_samples += not_finite[slot * pixels as usize + pixel] as u64;
            }
            finite_samples += count as u64;
            let mean = if count > 0.0 { sum.map(|c| (c / count) as f32) } else { [0.0; 3] };
            for (channel, value) in mean.into_iter().enumerate() {
                image.set(channel, x, y, value);
            }
        }
    }
    (finite_samples, discarded_samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glassbake_scene::builtin::builtin;

    #[test]
    fn the_kernels_take_the_cpu_tracers_constants_from_rust() {
        use glassbake_core::wgsl::declarations;
        let source = trace_source();
        for (name, value) in [
            ("DIELECTRIC_F0", glassbake_trace::bsdf::DIELECTRIC_F0),
            ("MIN_OPAQUE_ALPHA", glassbake_trace::bsdf::MIN_OPAQUE_ALPHA),
            ("MIN_ALPHA", glassbake_trace::microfacet::MIN_ALPHA),
            ("SMOOTH_ROUGHNESS", glassbake_scene::model::SMOOTH_ROUGHNESS),
        ] {
            assert_eq!(declarations(include_str!("../shaders/bsdf.wgsl"), name), 0, "bsdf.wgsl declares {name} itself");
            assert_eq!(declarations(&source, name), 1, "{name}");
            assert!(source.contains(&format!("const {name}: f32 = {value:?};")), "{name}");
        }
    }

    #[test]
    fn scenes_and_images_over_the_buffer_limit_are_refused_by_name() {
        let scene = builtin("desk").unwrap();
        let buffers = SceneBuffers::build(&scene).unwrap();
        let largest = buffers.arrays().iter().map(|(_, a)| a.len() as u64 * 16).max().unwrap();
        check_sizes("desk", &buffers, 64, largest, "test GPU").unwrap();
        let err = check_sizes("desk", &buffers, 64, largest - 16, "test GPU").unwrap_err();
        assert!(err.is_user_error(), "{err}");
        let text = err.to_string();
        assert!(text.starts_with("desk: ") && text.contains("storage buffer limit") && text.contains("test GPU"), "{text}");
        let err = check_sizes("desk", &buffers, largest, largest, "test GPU").unwrap_err().to_string();
        assert!(err.contains("resolution"), "{err}");
    }
}
