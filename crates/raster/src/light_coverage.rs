//! Light coverage: how much of each pixel sees a light directly, and the light it sees there.
//!
//! The ground truth averages every pixel over its area (the path tracer jitters its camera
//! rays across the pixel), and a light is so much brighter than 1 that a pixel it covers by a
//! few percent is white after the tone map's clamp. The G-buffer samples only the pixel's
//! centre, so at a light's edge nothing tells a network how much of the pixel the light covers:
//! in the default cornellbox bake that one-pixel ring (0.5% of the pixels) held 87% of
//! GlassNet's squared error over the whole frame before the networks were given the coverage
//! (docs/history/benchmarks-2026-11.md).
//!
//! [`light_coverage`] rasterizes the opaque and naive G-buffers at `factor` x `factor` the
//! resolution and reduces each per pixel, on the GPU (shaders/light_coverage.wgsl): `coverage` is the share of sub-samples whose L_d
//! alone reaches 1 in every channel (a light seen directly, or a surface lit so strongly that
//! the clamp makes it white), and `light` the L_d of
//! those sub-samples summed and divided by all `factor^2`. An image p of everything else then
//! becomes [`composite`]: min(1, light + (1 - coverage) p), the box-filtered pixel the ground
//! truth holds.

use glassbake_core::layout;
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_rays::gpu_stats::{created, GpuObject};
use glassbake_scene::Scene;

use crate::{Frame, Rasterizer};

/// Sub-samples per pixel side that the frame's buffers ([`Rasterizer::render`]) and the
/// real-time frame take their light coverage from: 16 per pixel, the coverage in steps of
/// 1/16 (tests/light_coverage.rs measures the error against the exact area).
pub const LIGHT_COVERAGE_FACTOR: u32 = 4;

/// The light coverage of one frame's opaque and naive G-buffers (layers
/// `layout::OPAQUE_LIGHT_COVERAGE_LAYER` and `layout::NAIVE_LIGHT_COVERAGE_LAYER`): the naive
/// one sees glass where glass is in front of a light, as the naive G-buffer does.
#[derive(Clone, Debug)]
pub struct LightCoverage {
    pub opaque: PlanarImage,
    pub naive: PlanarImage,
}

/// Per pixel of a `width` x `height` frame: the share of it that sees a light, and the
/// light seen, from the opaque and naive G-buffers rasterized at `factor` times the resolution.
pub fn light_coverage(rasterizer: &mut Rasterizer, scene: &Scene, camera: &Camera, width: u32, height: u32, factor: u32) -> Result<LightCoverage> {
    let mut frame = fine_frame(rasterizer, scene, camera, width, height, factor)?;
    let opaque = frame.light_coverage(false, factor, layout::opaque_light_coverage_channel_names())?;
    let naive = frame.light_coverage(true, factor, layout::naive_light_coverage_channel_names())?;
    Ok(LightCoverage { opaque, naive })
}

/// [`light_coverage`] of one G-buffer only, the naive one if `naive`: what a real-time frame,
/// which runs one model, needs.
pub fn light_coverage_of(
    rasterizer: &mut Rasterizer,
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    factor: u32,
    naive: bool,
) -> Result<PlanarImage> {
    let mut frame = fine_frame(rasterizer, scene, camera, width, height, factor)?;
    let names = if naive { layout::naive_light_coverage_channel_names() } else { layout::opaque_light_coverage_channel_names() };
    frame.light_coverage(naive, factor, names)
}

/// [`light_coverage_of`] written into `out` from `byte_offset` on (a network input tensor's
/// storage on the rasterizer's device), on the GPU: nothing is read back or waited for.
#[allow(clippy::too_many_arguments)]
pub fn light_coverage_into(
    rasterizer: &mut Rasterizer,
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    factor: u32,
    naive: bool,
    out: &wgpu::Buffer,
    byte_offset: u64,
) -> Result<()> {
    fine_frame(rasterizer, scene, camera, width, height, factor)?.light_coverage_to_buffer(naive, factor, out, byte_offset)
}

/// The frame at `factor` x `factor` the resolution that the coverage is reduced from.
fn fine_frame<'r>(rasterizer: &'r mut Rasterizer, scene: &Scene, camera: &Camera, width: u32, height: u32, factor: u32) -> Result<Frame<'r>> {
    if factor == 0 {
        return Err(Error::bad_input(&scene.name, "light coverage factor", "must be at least 1"));
    }
    let (fine_width, fine_height) = (width.checked_mul(factor), height.checked_mul(factor));
    let (Some(fine_width), Some(fine_height)) = (fine_width, fine_height) else {
        return Err(Error::bad_input(&scene.name, "light coverage factor", format!("{width}x{height} times {factor} overflows")));
    };
    rasterizer.begin_frame(scene, camera, fine_width, fine_height)
}

/// The largest factor up to [`LIGHT_COVERAGE_FACTOR`] at which `rasterizer` can draw a
/// `width` x `height` frame (a large real-time frame may not fit the device's limits 4x over).
pub fn coverage_factor(rasterizer: &Rasterizer, width: u32, height: u32) -> u32 {
    (1..=LIGHT_COVERAGE_FACTOR).rev().find(|&k| rasterizer.fits(width.saturating_mul(k), height.saturating_mul(k))).unwrap_or(1)
}

/// The pixel the ground truth holds, from a pixel's light coverage and light and the value
/// `rest` of everything else in it (all linear RGB, the result clamped to [0, 1]).
pub fn composite(coverage: f32, light: [f32; 3], rest: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|c| (light[c] + (1.0 - coverage) * rest[c]).clamp(0.0, 1.0))
}

/// The compute pass behind [`light_coverage`]: it reduces the fine G-buffer's L_d target on
/// the GPU, so that 4 planes at the frame's resolution are read back instead of the 17
/// planes of the G-buffer at `factor^2` times as many pixels (on a discrete GPU that
/// readback and the host's reduction were most of a real-time frame).
pub(crate) struct CoverageReducer {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ReduceParams {
    width: u32,
    height: u32,
    factor: u32,
    coverage_plane: u32,
    light_plane: u32,
    _pad: [u32; 3],
}

impl CoverageReducer {
    pub fn new(device: &wgpu::Device) -> CoverageReducer {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("light_coverage.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../shaders/light_coverage.wgsl").into()),
        });
        let compute = wgpu::ShaderStages::COMPUTE;
        let entries = [
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: compute,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: compute,
                ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only: false }, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: compute,
                ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            },
        ];
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("light coverage"), entries: &entries });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("light coverage"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("light coverage"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("reduce"),
            compilation_options: Default::default(),
            cache: None,
        });
        CoverageReducer { pipeline: created(GpuObject::Pipeline, pipeline), layout }
    }

    /// The bind group that reduces `direct_light` (the L_d target of a G-buffer drawn at
    /// `factor` x `factor` the resolution) into `out`: `layout::LIGHT_COVERAGE_CHANNELS` f32
    /// planes of `width` x `height`. Made once per target and kept (see [`Self::encode`]).
    pub fn bind(&self, device: &wgpu::Device, direct_light: &wgpu::TextureView, width: u32, height: u32, factor: u32, out: &wgpu::Buffer) -> wgpu::BindGroup {
        use wgpu::util::DeviceExt;
        let params = ReduceParams {
            width,
            height,
            factor,
            coverage_plane: layout::light_coverage::COVERAGE as u32,
            light_plane: layout::light_coverage::LIGHT as u32,
            _pad: [0; 3],
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("light coverage params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let uniform = created(GpuObject::Buffer, uniform);
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("light coverage"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(direct_light) },
                wgpu::BindGroupEntry { binding: 1, resource: out.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: uniform.as_entire_binding() },
            ],
        });
        created(GpuObject::BindGroup, group)
    }

    /// Encodes the reduction `group` (from [`Self::bind`]) describes, to a `width` x `height`
    /// coverage.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, group: &wgpu::BindGroup, width: u32, height: u32) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("light coverage"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
    }
}
