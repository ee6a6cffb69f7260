//! Render targets -> planar f32 channels in a caller's storage buffer, on the GPU: the path by
//! which the real-time stage hands buffers to a network running on the same wgpu device
//! without reading them back to the host (`Frame::opaque_to_buffer`,
//! `Frame::transparent_to_buffer`).

use glassbake_core::{Error, Result};
use glassbake_rays::gpu_cache::Recent;
use glassbake_rays::gpu_stats::{created, GpuObject};

/// Most entries a channel map has (the transparency buffer's 10 attributes; the length of
/// `map` in unpack.wgsl, which takes it from here).
const MAX_ENTRIES: usize = 10;

/// `shaders/unpack.wgsl` after the constant it takes from Rust.
fn unpack_source() -> String {
    use glassbake_core::wgsl::{constants, Value};
    constants(&[("MAX_ENTRIES", Value::U32(MAX_ENTRIES as u32))]) + include_str!("../shaders/unpack.wgsl")
}
/// Colour targets bound (the transparency pass's 6; sets with fewer bind their first one
/// again). Bindings 0-4 and 7: 5 and 6 are the output buffer and the parameters.
const BOUND_TARGETS: usize = 6;

fn target_binding(target: usize) -> u32 {
    if target < 5 {
        target as u32
    } else {
        target as u32 + 2
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    width: u32,
    height: u32,
    base: u32,
    entries: u32,
    map: [[u32; 4]; MAX_ENTRIES],
}

pub(crate) struct Unpacker {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Bind groups by what they bind: the first target, the output buffer and where in it.
    groups: Recent<(wgpu::TextureView, wgpu::Buffer, u64, [u32; 2]), wgpu::BindGroup>,
}

/// Bind groups kept: the opaque G-buffer and the transparency buffer, each into a few
/// tensors of burn's pool.
const KEPT_GROUPS: usize = 8;

impl Unpacker {
    pub fn new(device: &wgpu::Device) -> Unpacker {
        let module =
            device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("unpack.wgsl"), source: wgpu::ShaderSource::Wgsl(unpack_source().into()) });
        let mut entries: Vec<wgpu::BindGroupLayoutEntry> = (0..BOUND_TARGETS)
            .map(|target| wgpu::BindGroupLayoutEntry {
                binding: target_binding(target),
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            })
            .collect();
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: 5,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only: false }, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        });
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: 6,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("unpack"), entries: &entries });
        let pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("unpack"), bind_group_layouts: &[Some(&layout)], immediate_size: 0 });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("unpack"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("unpack"),
            compilation_options: Default::default(),
            cache: None,
        });
        Unpacker { pipeline: created(GpuObject::Pipeline, pipeline), layout, groups: Recent::new(KEPT_GROUPS) }
    }

    /// Encodes the scatter of `views` (per `map`) into `out` from `byte_offset` on.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        views: &[wgpu::TextureView],
        map: &[(usize, usize, u32, u32)],
        channels: usize,
        width: u32,
        height: u32,
        out: &wgpu::Buffer,
        byte_offset: u64,
    ) -> Result<()> {
        use wgpu::util::DeviceExt;
        if map.len() > MAX_ENTRIES {
            return Err(Error::Internal(format!("a channel map of {} entries; the unpack shader takes at most {MAX_ENTRIES}", map.len())));
        }
        let needed = byte_offset + (channels as u64) * (width as u64) * (height as u64) * 4;
        if !byte_offset.is_multiple_of(4) || needed > out.size() {
            return Err(Error::Internal(format!(
                "unpacking {channels} planes of {width}x{height} at byte {byte_offset} into a buffer of {} bytes",
                out.size()
            )));
        }
        if !out.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(Error::Internal("the destination buffer has no STORAGE usage".into()));
        }
        // Bind only the range written (pool buffers can exceed the largest storage binding),
        // starting at the closest aligned offset below `byte_offset`.
        let alignment = device.limits().min_storage_buffer_offset_alignment as u64;
        let bind_offset = byte_offset / alignment * alignment;
        let bind_size = std::num::NonZeroU64::new(needed - bind_offset).expect("at least one plane");
        let key = (views[0].clone(), out.clone(), byte_offset, [width, height]);
        let group = self.groups.get_or_make(key, || {
            let mut params = Params { width, height, base: ((byte_offset - bind_offset) / 4) as u32, entries: map.len() as u32, map: [[0; 4]; MAX_ENTRIES] };
            for (slot, &(first, count, target, component)) in params.map.iter_mut().zip(map) {
                *slot = [first as u32, count as u32, target, component];
            }
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("unpack params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let uniform = created(GpuObject::Buffer, uniform);
            let mut bindings: Vec<wgpu::BindGroupEntry> = (0..BOUND_TARGETS)
                .map(|i| wgpu::BindGroupEntry { binding: target_binding(i), resource: wgpu::BindingResource::TextureView(views.get(i).unwrap_or(&views[0])) })
                .collect();
            bindings.push(wgpu::BindGroupEntry {
                binding: 5,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: out, offset: bind_offset, size: Some(bind_size) }),
            });
            bindings.push(wgpu::BindGroupEntry { binding: 6, resource: uniform.as_entire_binding() });
            created(
                GpuObject::BindGroup,
                device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some("unpack"), layout: &self.layout, entries: &bindings }),
            )
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("unpack"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        Ok(())
    }
}
