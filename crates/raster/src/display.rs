//! A network's image into a texture on the GPU, for a window to show without reading the
//! image back: the viewer's path when the network runs on the rasterizer's device.

use glassbake_core::{Error, Result};
use glassbake_rays::gpu_cache::Recent;
use glassbake_rays::gpu_stats::{created, GpuObject};

/// The texture's format: sRGB-encoded bytes in a plain unorm texture, what egui's renderer
/// takes for a native texture (it blends in gamma space) and the bytes a PNG of the frame holds.
pub const DISPLAY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    width: u32,
    height: u32,
    base: u32,
    unused: u32,
}

/// Bind groups kept: the network's output is one of a few buffers of burn's pool.
const KEPT_GROUPS: usize = 8;

/// The display pass and the texture it writes, kept while the size stays.
pub struct DisplayTexture {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    texture: Option<(wgpu::Texture, wgpu::TextureView)>,
    /// Bind groups by the planes' buffer, where in it, and the texture they write.
    groups: Recent<(wgpu::Buffer, u64, wgpu::TextureView), wgpu::BindGroup>,
}

impl DisplayTexture {
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> DisplayTexture {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("display.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../shaders/display.wgsl").into()),
        });
        let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let entries = [
            buffer(0, wgpu::BufferBindingType::Storage { read_only: true }),
            buffer(1, wgpu::BufferBindingType::Uniform),
            wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format: DISPLAY_FORMAT,
                    view_dimension: wgpu::TextureViewDimension::D2,
                },
                count: None,
            },
        ];
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("display"), entries: &entries });
        let pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some("display"), bind_group_layouts: &[Some(&layout)], immediate_size: 0 });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("display"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("display"),
            compilation_options: Default::default(),
            cache: None,
        });
        DisplayTexture {
            device: device.clone(),
            queue: queue.clone(),
            pipeline: created(GpuObject::Pipeline, pipeline),
            layout,
            texture: None,
            groups: Recent::new(KEPT_GROUPS),
        }
    }

    /// The texture the last [`Self::show`] wrote, if any.
    pub fn texture(&self) -> Option<&wgpu::Texture> {
        self.texture.as_ref().map(|(texture, _)| texture)
    }

    pub fn view(&self) -> Option<&wgpu::TextureView> {
        self.texture.as_ref().map(|(_, view)| view)
    }

    /// Writes the `width` x `height` image held in `planes` from `byte_offset` on (three f32
    /// planes, R, G, B) into the texture, made anew only when the size changed, and submits.
    /// Returns whether the texture was made anew (a window then binds the new one).
    pub fn show(&mut self, planes: &wgpu::Buffer, byte_offset: u64, width: u32, height: u32) -> Result<bool> {
        let needed = byte_offset + 3 * 4 * width as u64 * height as u64;
        if width == 0 || height == 0 || !byte_offset.is_multiple_of(4) || needed > planes.size() {
            return Err(Error::Internal(format!("showing a {width}x{height} image at byte {byte_offset} of a buffer of {} bytes", planes.size())));
        }
        let resized = self.texture.as_ref().is_none_or(|(t, _)| (t.width(), t.height()) != (width, height));
        if resized {
            let texture = self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("display"),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DISPLAY_FORMAT,
                usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let view = texture.create_view(&Default::default());
            self.texture = Some((created(GpuObject::Texture, texture), created(GpuObject::Texture, view)));
        }
        let view = self.texture.as_ref().expect("made above").1.clone();
        // Bind only the planes (pool buffers can exceed the largest storage binding), from
        // the closest aligned offset below `byte_offset`.
        let alignment = self.device.limits().min_storage_buffer_offset_alignment as u64;
        let bind_offset = byte_offset / alignment * alignment;
        let bind_size = std::num::NonZeroU64::new(needed - bind_offset).expect("at least one plane");
        let (device, layout) = (&self.device, &self.layout);
        let group = self.groups.get_or_make((planes.clone(), byte_offset, view.clone()), || {
            use wgpu::util::DeviceExt;
            let params = Params { width, height, base: ((byte_offset - bind_offset) / 4) as u32, unused: 0 };
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let uniform = created(GpuObject::Buffer, uniform);
            let entries = [
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: planes, offset: bind_offset, size: Some(bind_size) }),
                },
                wgpu::BindGroupEntry { binding: 1, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&view) },
            ];
            created(GpuObject::BindGroup, device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some("display"), layout, entries: &entries }))
        });
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("display") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("display"), timestamp_writes: None });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        self.queue.submit([encoder.finish()]);
        Ok(resized)
    }
}
