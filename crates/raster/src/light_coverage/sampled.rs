//! The sampled light coverage: the G-buffer rasterized at `factor` x `factor` the frame's
//! resolution and reduced per pixel on the GPU (shaders/light_coverage.wgsl): the share of
//! sub-samples whose L_d alone reaches 1 in every channel, and their L_d summed over all
//! `factor^2`. It finds any emitter, emissive meshes included, to within 1/factor^2.

use glassbake_core::layout;
use glassbake_rays::gpu_stats::{created, GpuObject};

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
            source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/light_coverage.wgsl").into()),
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
