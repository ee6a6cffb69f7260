//! The headless renderer: pipelines, render targets, per-frame passes and readback.

use glam::{Mat4, Vec3};
use glassbake_core::layout::{self, opaque, transparent};
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_scene::Scene;

use crate::device::{self, RasterizerOptions, GBUFFER_TARGETS};
use crate::frame_data::{FrameData, Layouts, LightUniform, ObjectUniform, ShadingInputs, ShadowContent, ViewUniform};
use crate::light_coverage::LightCoverage;
use crate::ltc;
use crate::resources::{self, Cache};
use glassbake_rays::gpu_stats::{self, created, GpuObject};

/// Sizes of render targets a rasterizer keeps (the current and the one before).
pub(crate) const KEPT_TARGET_SIZES: usize = 2;

/// Largest accepted image side.
pub const MAX_RESOLUTION: u32 = 8192;

const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The transparency pass's targets: 5 written by its near pass (as the G-buffer's), 1 by
/// its far pass (L_d of the object's farthest visible surface).
const TRANSPARENCY_TARGETS: u32 = 6;
const TRANSPARENCY_NEAR_TARGETS: usize = 5;
/// Half field of view of each face of a light's shadow hemicube: a little over 45 degrees so
/// that the 3x3 PCF taps near a face's border stay inside the face.
const SHADOW_HALF_FOV_DEG: f32 = 47.5;

/// Where each channel of a buffer lives in the render targets: (first channel in the layout,
/// channel count, target, first component).
type ChannelMap = [(usize, usize, u32, u32)];

/// The G-buffer target whose first three components hold L_d (`OPAQUE_MAP`).
const LD_TARGET: u32 = 4;

const OPAQUE_MAP: [(usize, usize, u32, u32); 7] = [
    (opaque::NORMAL, 3, 0, 0),
    (opaque::ROUGHNESS, 1, 0, 3),
    (opaque::POSITION, 3, 1, 0),
    (opaque::DEPTH, 1, 1, 3),
    (opaque::ALBEDO, 3, 2, 0),
    (opaque::WO, 3, 3, 0),
    (opaque::LD, 3, LD_TARGET, 0),
];

const TRANSPARENT_MAP: [(usize, usize, u32, u32); 10] = [
    (transparent::NORMAL, 3, 0, 0),
    (transparent::ROUGHNESS, 1, 0, 3),
    (transparent::POSITION, 3, 1, 0),
    (transparent::DEPTH, 1, 1, 3),
    (transparent::ALBEDO, 3, 2, 0),
    (transparent::COVERAGE, 1, 2, 3),
    (transparent::WO, 3, 3, 0),
    (transparent::RELATIVE_DEPTH, 1, 3, 3),
    (transparent::LD, 3, 4, 0),
    (transparent::LD_FAR, 3, 5, 0),
];

/// One set of same-sized Rgba32Float render targets and the buffer they are read back
/// through (rows padded to 256 bytes).
struct TargetSet {
    textures: Vec<wgpu::Texture>,
    views: Vec<wgpu::TextureView>,
    readback: wgpu::Buffer,
    padded_row: u64,
}

impl TargetSet {
    fn new(device: &wgpu::Device, count: u32, width: u32, height: u32, label: &str) -> TargetSet {
        let textures: Vec<wgpu::Texture> = (0..count)
            .map(|_| {
                let texture = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: TARGET_FORMAT,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                });
                created(GpuObject::Texture, texture)
            })
            .collect();
        let views = textures.iter().map(|t| created(GpuObject::Texture, t.create_view(&wgpu::TextureViewDescriptor::default()))).collect();
        let padded_row = padded_row_bytes(width);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: padded_row * height as u64 * count as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let readback = created(GpuObject::Buffer, readback);
        TargetSet { textures, views, readback, padded_row }
    }

    /// Attachments of targets `range`, cleared to 0.
    fn color_attachments(&self, range: std::ops::Range<usize>) -> Vec<Option<wgpu::RenderPassColorAttachment<'_>>> {
        self.views[range]
            .iter()
            .map(|view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
                })
            })
            .collect()
    }

    /// Copy the targets to the host and scatter their components into `out`'s planes.
    fn read_into(&self, device: &wgpu::Device, queue: &wgpu::Queue, map: &ChannelMap, width: u32, height: u32, data: &mut [f32]) -> Result<()> {
        let plane_bytes = self.padded_row * height as u64;
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
        for (t, texture) in self.textures.iter().enumerate() {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo { texture, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: t as u64 * plane_bytes,
                        bytes_per_row: Some(self.padded_row as u32),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            );
        }
        queue.submit([encoder.finish()]);
        map_for_reading(device, &self.readback)?;
        {
            let view = match self.readback.get_mapped_range(..) {
                Ok(view) => view,
                Err(e) => {
                    // Leave the buffer usable for the next frame.
                    self.readback.unmap();
                    return Err(Error::Internal(format!("reading the readback buffer: {e}")));
                }
            };
            let bytes: &[u8] = &view;
            let n = (width * height) as usize;
            for &(first, count, target, component) in map {
                for c in 0..count {
                    let plane = &mut data[(first + c) * n..(first + c + 1) * n];
                    let base = target as u64 * plane_bytes;
                    for y in 0..height as usize {
                        let row = base as usize + y * self.padded_row as usize;
                        for x in 0..width as usize {
                            let at = row + x * 16 + (component as usize + c) * 4;
                            plane[y * width as usize + x] = f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
                        }
                    }
                }
            }
        }
        self.readback.unmap();
        Ok(())
    }
}

/// Maps `buffer` (MAP_READ, its copies submitted) and waits until the host can read it.
fn map_for_reading(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<()> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    gpu_stats::wait(device).map_err(Error::Internal)?;
    rx.recv().map_err(|_| Error::Internal("readback callback dropped".into()))?.map_err(|e| Error::Internal(format!("mapping the readback buffer: {e}")))
}

/// Bytes per readback row: 16 bytes per texel, padded to wgpu's 256-byte copy alignment.
pub(crate) fn padded_row_bytes(width: u32) -> u64 {
    let unpadded = width as u64 * 16;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64;
    unpadded.div_ceil(align) * align
}

struct Targets {
    width: u32,
    height: u32,
    depth: wgpu::TextureView,
    opaque: TargetSet,
    transparency: TargetSet,
    naive: Option<TargetSet>,
    /// The light coverage reduced from this frame, and its host copy's staging buffer, for
    /// the one coverage size (made on first use).
    coverage: Option<CoverageBuffers>,
}

/// Where a frame's light coverage is reduced to, and read back through.
struct CoverageBuffers {
    /// The reduction's factor (the coverage is the frame's size over it).
    factor: u32,
    reduced: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// The reduction's bind groups from the opaque and the naive G-buffer (made on first use).
    groups: [Option<wgpu::BindGroup>; 2],
}

impl CoverageBuffers {
    fn new(device: &wgpu::Device, factor: u32, bytes: u64) -> CoverageBuffers {
        let buffer = |label: &str, usage: wgpu::BufferUsages| {
            created(GpuObject::Buffer, device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: bytes, usage, mapped_at_creation: false }))
        };
        CoverageBuffers {
            factor,
            reduced: buffer("light coverage", wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC),
            readback: buffer("light coverage readback", wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ),
            groups: [None, None],
        }
    }
}

struct ShadowMaps {
    size: u32,
    layers: u32,
    array_view: wgpu::TextureView,
    layer_views: Vec<wgpu::TextureView>,
}

impl ShadowMaps {
    fn new(device: &wgpu::Device, size: u32, layers: u32) -> ShadowMaps {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow maps"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let texture = created(GpuObject::Texture, texture);
        let array_view = texture.create_view(&wgpu::TextureViewDescriptor { dimension: Some(wgpu::TextureViewDimension::D2Array), ..Default::default() });
        let array_view = created(GpuObject::Texture, array_view);
        let layer_views = (0..layers)
            .map(|l| {
                let view = texture.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: l,
                    array_layer_count: Some(1),
                    ..Default::default()
                });
                created(GpuObject::Texture, view)
            })
            .collect();
        ShadowMaps { size, layers, array_view, layer_views }
    }
}

/// The headless rasterizer. Create it once (opening the device is slow), then render frames
/// with [`Rasterizer::begin_frame`] (streaming) or [`Rasterizer::render`] (all at once).
///
/// Channel semantics (docs/raster.md has the full list): normals are world-space, unit and
/// flipped to face the camera; positions world-space; albedo linear and textured (mipmapped,
/// anisotropic; the tint for glass); depth is the Euclidean distance to the camera; w_o points to
/// the camera; L_d is direct light from the rectangle lights (exact polygon form factor for
/// diffuse, LTC for GGX, hemicube shadow maps) plus emission. Background is 0. A transparency
/// buffer holds its object's front-most surface in front of the opaque surface (hidden glass
/// is not drawn), relative depth = opaque depth - depth (0 where no opaque surface is behind)
/// and coverage. Rectangle lights' quads are drawn into the opaque and naive G-buffers.
pub struct Rasterizer {
    options: RasterizerOptions,
    instance: wgpu::Instance,
    adapter: wgpu::Adapter,
    adapter_info: wgpu::AdapterInfo,
    device: wgpu::Device,
    queue: wgpu::Queue,
    view_layout: wgpu::BindGroupLayout,
    object_layout: wgpu::BindGroupLayout,
    shading_layout: wgpu::BindGroupLayout,
    gbuffer_pipeline: wgpu::RenderPipeline,
    transparency_pipeline: wgpu::RenderPipeline,
    transparency_far_pipeline: wgpu::RenderPipeline,
    shadow_pipeline: wgpu::RenderPipeline,
    material_sampler: wgpu::Sampler,
    shadow_sampler: wgpu::Sampler,
    white: wgpu::TextureView,
    no_opaque: wgpu::TextureView,
    ltc_matrix: wgpu::TextureView,
    ltc_amplitude: wgpu::TextureView,
    cache: Cache,
    /// The per-frame data's buffers and bind groups, kept across frames.
    frame_data: FrameData,
    targets: Option<Targets>,
    /// The targets of the size drawn before the current one.
    spare_targets: Option<Targets>,
    shadows: Option<ShadowMaps>,
    /// The compute pass writing buffers into caller-owned storage buffers (made on first use).
    unpacker: Option<crate::unpack::Unpacker>,
    /// The compute pass reducing a fine G-buffer to its light coverage (made on first use).
    coverage_reducer: Option<crate::light_coverage::CoverageReducer>,
}

/// All buffers of one frame.
#[derive(Clone, Debug)]
pub struct FrameBuffers {
    /// Opaque G-buffer (layer `opaque`).
    pub opaque: PlanarImage,
    /// Naive G-buffer: glass drawn over what is behind it (layer `naive`).
    pub naive: PlanarImage,
    /// Transparency buffer k belongs to `scene.transparent_objects()[k]` (layer `transparent.k`).
    pub transparent: Vec<PlanarImage>,
    /// How much of each pixel sees a light, for the opaque and the naive G-buffer.
    pub light_coverage: LightCoverage,
    /// What each transparent object shows through itself, by refracted rays (layer
    /// `transparent.k.through`, `glassbake_rays::through`).
    pub through: Vec<PlanarImage>,
}

impl FrameBuffers {
    /// Every layer in one image (opaque, naive, transparent.0, ...), e.g. for one EXR file.
    pub fn combined(&self) -> Result<PlanarImage> {
        let mut all: Vec<&PlanarImage> = vec![&self.opaque, &self.naive];
        all.extend(self.transparent.iter());
        all.extend([&self.light_coverage.opaque, &self.light_coverage.naive]);
        all.extend(self.through.iter());
        PlanarImage::concat(&all)
    }
}

fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

/// A read-only storage buffer read by the fragment shader.
fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only: true }, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

fn texture_entry(binding: u32, sample_type: wgpu::TextureSampleType, dimension: wgpu::TextureViewDimension) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture { sample_type, view_dimension: dimension, multisampled: false },
        count: None,
    }
}

fn small_texture(device: &wgpu::Device, queue: &wgpu::Queue, format: wgpu::TextureFormat, size: u32, data: &[u8]) -> wgpu::TextureView {
    use wgpu::util::DeviceExt;
    let view = device
        .create_texture_with_data(
            queue,
            &wgpu::TextureDescriptor {
                label: None,
                size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            data,
        )
        .create_view(&wgpu::TextureViewDescriptor::default());
    created(GpuObject::Texture, view)
}

/// Bytes of the one buffer all G-buffer targets are read back through.
fn readback_bytes(width: u32, height: u32) -> u64 {
    padded_row_bytes(width) * height as u64 * GBUFFER_TARGETS as u64
}

fn mat4_cols(m: Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

impl Rasterizer {
    /// Open a Vulkan device (see [`RasterizerOptions`]) and build the pipelines.
    pub fn new(options: RasterizerOptions) -> Result<Rasterizer> {
        let (instance, adapter, device, queue) = device::open(&options)?;
        Rasterizer::from_device(instance, adapter, device, queue, options)
    }

    /// Another rasterizer on this one's device, with targets of its own: a caller that draws
    /// frames of two sizes in turn (the real-time frame and its light coverage's finer one)
    /// keeps each one's targets instead of reallocating them every frame.
    pub fn sibling(&self) -> Result<Rasterizer> {
        Rasterizer::from_device(self.instance.clone(), self.adapter.clone(), self.device.clone(), self.queue.clone(), self.options.clone())
    }

    /// Build the rasterizer on a device opened elsewhere (e.g. by the network's wgpu backend,
    /// to share one device). The device must allow 5 colour targets and 80 colour bytes per
    /// sample (`adapter.limits()` does on Vulkan; wgpu's default limits do not).
    /// `options.adapter_name` and `power_preference` are ignored.
    pub fn from_device(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
        options: RasterizerOptions,
    ) -> Result<Rasterizer> {
        if !device::limits_suffice(&device.limits()) {
            return Err(Error::Internal(format!(
                "the device allows {} colour targets / {} colour bytes per sample; the rasterizer needs {} / {} \
                 (open it with required_limits: adapter.limits())",
                device.limits().max_color_attachments,
                device.limits().max_color_attachment_bytes_per_sample,
                GBUFFER_TARGETS,
                GBUFFER_TARGETS * 16
            )));
        }
        let adapter_info = adapter.get_info();
        tracing::info!("rasterizer on {} ({:?}, {})", adapter_info.name, adapter_info.device_type, adapter_info.driver);

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("gbuffer.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../shaders/gbuffer.wgsl").into()),
        });
        let both = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let view_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("view"), entries: &[uniform_entry(0, both)] });
        let float_filterable = wgpu::TextureSampleType::Float { filterable: true };
        let float_plain = wgpu::TextureSampleType::Float { filterable: false };
        let d2 = wgpu::TextureViewDimension::D2;
        let object_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("object"),
            entries: &[
                uniform_entry(0, both),
                texture_entry(1, float_filterable, d2),
                texture_entry(2, float_filterable, d2),
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let shading_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shading"),
            entries: &[
                storage_entry(0),
                texture_entry(1, wgpu::TextureSampleType::Depth, wgpu::TextureViewDimension::D2Array),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
                texture_entry(3, float_plain, d2),
                texture_entry(4, float_plain, d2),
                texture_entry(5, float_plain, d2),
                storage_entry(6),
            ],
        });
        let shading_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shading"),
            bind_group_layouts: &[Some(&view_layout), Some(&object_layout), Some(&shading_layout)],
            immediate_size: 0,
        });
        let shadow_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shadow"),
            bind_group_layouts: &[Some(&view_layout), Some(&object_layout)],
            immediate_size: 0,
        });
        let primitive = wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::TriangleList, cull_mode: None, ..Default::default() };
        let depth_state = |compare: wgpu::CompareFunction, bias: wgpu::DepthBiasState| wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(compare),
            stencil: wgpu::StencilState::default(),
            bias,
        };
        let vertex_layouts = [Some(resources::vertex_layout())];
        let target = Some(wgpu::ColorTargetState { format: TARGET_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL });
        let gbuffer_targets = vec![target.clone(); GBUFFER_TARGETS as usize];
        let transparency_targets = vec![target.clone(); TRANSPARENCY_NEAR_TARGETS];
        let far_targets = vec![target; TRANSPARENCY_TARGETS as usize - TRANSPARENCY_NEAR_TARGETS];
        let make_pipeline = |label: &str, fragment: &str, targets: &[Option<wgpu::ColorTargetState>], compare: wgpu::CompareFunction| {
            let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&shading_pipeline_layout),
                vertex: wgpu::VertexState { module: &module, entry_point: Some("vs_main"), compilation_options: Default::default(), buffers: &vertex_layouts },
                primitive,
                depth_stencil: Some(depth_state(compare, wgpu::DepthBiasState::default())),
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState { module: &module, entry_point: Some(fragment), compilation_options: Default::default(), targets }),
                multiview_mask: None,
                cache: None,
            });
            created(GpuObject::Pipeline, pipeline)
        };
        let less = wgpu::CompareFunction::Less;
        let gbuffer_pipeline = make_pipeline("gbuffer", "fs_gbuffer", &gbuffer_targets, less);
        let transparency_pipeline = make_pipeline("transparency", "fs_transparency", &transparency_targets, less);
        let transparency_far_pipeline = make_pipeline("transparency far", "fs_transparency_far", &far_targets, wgpu::CompareFunction::Greater);
        let shadow_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("shadow"),
            layout: Some(&shadow_pipeline_layout),
            vertex: wgpu::VertexState { module: &module, entry_point: Some("vs_shadow"), compilation_options: Default::default(), buffers: &vertex_layouts },
            primitive,
            depth_stencil: Some(depth_state(wgpu::CompareFunction::Less, wgpu::DepthBiasState { constant: 2, slope_scale: 2.0, clamp: 0.0 })),
            multisample: wgpu::MultisampleState::default(),
            fragment: None,
            multiview_mask: None,
            cache: None,
        });
        let shadow_pipeline = created(GpuObject::Pipeline, shadow_pipeline);

        let material_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("material"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            address_mode_w: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            // 16x anisotropic where the device supports it (wgpu falls back to trilinear).
            anisotropy_clamp: 16,
            ..Default::default()
        });
        let shadow_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let one = half::f16::ONE.to_bits();
        let white = small_texture(&device, &queue, wgpu::TextureFormat::Rgba16Float, 1, bytemuck::cast_slice(&[one; 4]));
        let no_opaque = small_texture(&device, &queue, TARGET_FORMAT, 1, bytemuck::cast_slice(&[0.0f32; 4]));
        let table = ltc::table();
        let size = ltc::LTC_SIZE as u32;
        let matrix: Vec<f32> = table.iter().flat_map(|c| c.minv).collect();
        let amplitude: Vec<f32> = table.iter().flat_map(|c| [c.amplitude[0], c.amplitude[1], 0.0, 0.0]).collect();
        let ltc_matrix = small_texture(&device, &queue, TARGET_FORMAT, size, bytemuck::cast_slice(&matrix));
        let ltc_amplitude = small_texture(&device, &queue, TARGET_FORMAT, size, bytemuck::cast_slice(&amplitude));

        Ok(Rasterizer {
            options,
            instance,
            adapter,
            adapter_info,
            device,
            queue,
            view_layout,
            object_layout,
            shading_layout,
            gbuffer_pipeline,
            transparency_pipeline,
            transparency_far_pipeline,
            shadow_pipeline,
            material_sampler,
            shadow_sampler,
            white,
            no_opaque,
            ltc_matrix,
            ltc_amplitude,
            cache: Cache::default(),
            frame_data: FrameData::new(),
            targets: None,
            spare_targets: None,
            shadows: None,
            unpacker: None,
            coverage_reducer: None,
        })
    }

    /// The wgpu objects alive on this rasterizer's device, whoever made them (burn's runtime
    /// too, when it shares the device), from wgpu's internal counters: a frame loop whose
    /// count grows leaks.
    pub fn live_gpu_objects(&self) -> i64 {
        let hal = self.device.get_internal_counters().hal;
        [
            &hal.buffers,
            &hal.textures,
            &hal.texture_views,
            &hal.bind_groups,
            &hal.bind_group_layouts,
            &hal.render_pipelines,
            &hal.compute_pipelines,
            &hal.pipeline_layouts,
            &hal.samplers,
            &hal.shader_modules,
            &hal.query_sets,
        ]
        .iter()
        .map(|c| c.read() as i64)
        .sum()
    }

    /// The adapter the rasterizer runs on.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.adapter_info
    }

    /// The wgpu instance, adapter, device and queue, for sharing with other GPU work (e.g. the
    /// network's wgpu backend).
    pub fn instance(&self) -> &wgpu::Instance {
        &self.instance
    }

    pub fn adapter(&self) -> &wgpu::Adapter {
        &self.adapter
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Forget cached meshes and textures (they are kept across frames, keyed by the scene's
    /// shared `Arc`s; call this when switching to another scene for good).
    pub fn clear_cache(&mut self) {
        self.cache.clear();
    }

    /// Render everything of a frame at once: opaque and naive G-buffers, every transparency
    /// buffer, the G-buffers' light coverage (at [`crate::light_coverage::coverage_factor`]),
    /// and each transparency buffer's through buffer (cast on the CPU).
    pub fn render(&mut self, scene: &Scene, camera: &Camera, width: u32, height: u32) -> Result<FrameBuffers> {
        let mut frame = self.begin_frame(scene, camera, width, height)?;
        let opaque = frame.opaque()?;
        let naive = frame.naive()?;
        let transparent = (0..frame.transparent_count()).map(|k| frame.transparent(k)).collect::<Result<Vec<_>>>()?;
        drop(frame);
        let factor = crate::light_coverage::coverage_factor(self, width, height);
        let light_coverage = crate::light_coverage::light_coverage(self, scene, camera, width, height, factor)?;
        let through = glassbake_rays::through::through_buffers(scene, camera, &opaque, &transparent);
        Ok(FrameBuffers { opaque, naive, transparent, light_coverage, through })
    }

    /// Whether a `width` x `height` frame is within what this rasterizer can draw.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        let max = MAX_RESOLUTION.min(self.device.limits().max_texture_dimension_2d);
        width >= 1 && height >= 1 && width <= max && height <= max && readback_bytes(width, height) <= self.device.limits().max_buffer_size
    }

    fn check_resolution(&self, scene: &Scene, width: u32, height: u32) -> Result<()> {
        let max = MAX_RESOLUTION.min(self.device.limits().max_texture_dimension_2d);
        for (name, v) in [("width", width), ("height", height)] {
            if v == 0 || v > max {
                return Err(Error::bad_input(&scene.name, format!("resolution {name}"), format!("{v} is outside [1, {max}]")));
            }
        }
        // All G-buffer targets are read back through one buffer, which the device must allow.
        let readback_bytes = readback_bytes(width, height);
        let limit = self.device.limits().max_buffer_size;
        if readback_bytes > limit {
            return Err(Error::bad_input(
                &scene.name,
                "resolution",
                format!("{width}x{height} needs a {readback_bytes}-byte readback buffer; this device allows {limit}"),
            ));
        }
        Ok(())
    }

    /// Makes the current targets `width` x `height`: the last two sizes drawn are kept, so a
    /// caller alternating between two sizes (a frame and its super-sampler's) makes none.
    fn ensure_targets(&mut self, width: u32, height: u32) {
        let fits = |t: &Option<Targets>| t.as_ref().is_some_and(|t| t.width == width && t.height == height);
        if fits(&self.targets) {
            return;
        }
        if fits(&self.spare_targets) {
            std::mem::swap(&mut self.targets, &mut self.spare_targets);
            return;
        }
        let depth = created(
            GpuObject::Texture,
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("depth"),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            }),
        );
        let depth = created(GpuObject::Texture, depth.create_view(&wgpu::TextureViewDescriptor::default()));
        let targets = Targets {
            width,
            height,
            depth,
            opaque: TargetSet::new(&self.device, GBUFFER_TARGETS, width, height, "opaque"),
            transparency: TargetSet::new(&self.device, TRANSPARENCY_TARGETS, width, height, "transparency"),
            naive: None,
            coverage: None,
        };
        self.spare_targets = self.targets.replace(targets);
    }

    /// Makes the shadow maps fit `layers` faces; true when they were made anew (and so hold
    /// nothing).
    fn ensure_shadow_maps(&mut self, layers: u32) -> bool {
        let size = if layers == 0 { 1 } else { self.options.shadow_map_size.max(16) };
        let layers = layers.max(1);
        if self.shadows.as_ref().is_some_and(|s| s.size == size && s.layers == layers) {
            return false;
        }
        self.shadows = Some(ShadowMaps::new(&self.device, size, layers));
        true
    }

    /// Upload a frame (scene instance + camera), render the shadow maps and the opaque
    /// G-buffer on the GPU, and return a handle that produces the buffers on request. The
    /// transparency buffers are rendered one at a time into one reused set of targets.
    pub fn begin_frame(&mut self, scene: &Scene, camera: &Camera, width: u32, height: u32) -> Result<Frame<'_>> {
        self.check_resolution(scene, width, height)?;
        camera.check()?;
        if scene.rect_lights.is_empty() {
            tracing::warn!("scene {:?} has no rectangle light: L_d holds only emission", scene.name);
        }
        self.ensure_targets(width, height);

        // Lights and their shadow-map layers.
        let bounds = scene.bounds().unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
        let extent = (bounds.1 - bounds.0).length().max(1e-3);
        let mut light_data = Vec::with_capacity(scene.rect_lights.len());
        let mut shadow_views: Vec<Mat4> = Vec::new();
        let tan_half = SHADOW_HALF_FOV_DEG.to_radians().tan();
        let normal_offset = 1.5 * 2.0 * tan_half / self.options.shadow_map_size.max(16) as f32;
        for light in &scene.rect_lights {
            let centre = light.center();
            let n = light.normal();
            let t = light.edge_u.normalize_or(n.any_orthonormal_vector());
            let far = 2.0 * extent + (centre - 0.5 * (bounds.0 + bounds.1)).length();
            let proj = Mat4::perspective_rh(2.0 * SHADOW_HALF_FOV_DEG.to_radians(), 1.0, far * 1e-4, far);
            // The hemicube of one side: faces along s, t, -t, b, -b (as the shader expects).
            let mut hemicube = |s: Vec3| -> f32 {
                if !self.options.shadows {
                    return -1.0;
                }
                let first = shadow_views.len() as f32;
                let b = s.cross(t);
                for (dir, up) in [(s, t), (t, s), (-t, s), (b, s), (-b, s)] {
                    shadow_views.push(proj * Mat4::look_at_rh(centre, centre + dir, up));
                }
                first
            };
            let front_layer = hemicube(n);
            let back_layer = if light.two_sided { hemicube(-n) } else { -1.0 };
            let c = light.corners();
            light_data.push(LightUniform {
                corners: c.map(|p| p.extend(1.0).to_array()),
                radiance: light.radiance.extend(if light.two_sided { 1.0 } else { 0.0 }).to_array(),
                shadow: [front_layer, back_layer, normal_offset, 0.0],
            });
        }
        let light_count = light_data.len() as u32;
        if light_data.is_empty() {
            light_data.push(LightUniform::zeroed_light());
        }
        if self.ensure_shadow_maps(shadow_views.len() as u32) {
            self.frame_data.shadow_content = None;
        }
        let mut matrix_data: Vec<[[f32; 4]; 4]> = shadow_views.iter().map(|m| mat4_cols(*m)).collect();
        if matrix_data.is_empty() {
            matrix_data.push(mat4_cols(Mat4::IDENTITY));
        }

        // Objects (opaque, transparent) and the lights' own quads.
        let mut uniforms: Vec<ObjectUniform> = Vec::new();
        let mut draws: Vec<Draw> = Vec::new();
        let mut transparent_slot = vec![usize::MAX; scene.transparent_count()];
        let transparent_index: Vec<usize> = scene.transparent_objects();
        let mut meshes_to_draw: Vec<(wgpu::Buffer, wgpu::Buffer, u32)> = Vec::new();
        let mut textures: Vec<(wgpu::TextureView, wgpu::TextureView)> = Vec::new();
        for (oi, object) in scene.objects.iter().enumerate() {
            let Some(mesh) = scene.meshes.get(object.mesh) else {
                return Err(Error::bad_input(&scene.name, format!("objects.{}.mesh", object.name), "index out of range"));
            };
            let Some(material) = scene.materials.get(object.material) else {
                return Err(Error::bad_input(&scene.name, format!("objects.{}.material", object.name), "index out of range"));
            };
            let Some(gpu) = self.cache.mesh(&self.device, mesh) else { continue };
            meshes_to_draw.push((gpu.vertices.clone(), gpu.indices.clone(), gpu.index_count));
            let mut texture = |index: Option<usize>| match index.and_then(|i| scene.textures.get(i)) {
                Some(t) => self.cache.texture(&self.device, &self.queue, t),
                None => self.white.clone(),
            };
            textures.push((texture(material.base_color_texture), texture(material.roughness_texture)));
            let model = Mat4::from(object.transform);
            let normal_matrix = Mat4::from_mat3(glam::Mat3::from(object.transform.matrix3).inverse().transpose());
            uniforms.push(ObjectUniform {
                model: mat4_cols(model),
                normal_matrix: mat4_cols(normal_matrix),
                base_color: material.base_color.extend(material.roughness).to_array(),
                emission: material.emission.extend(material.metallic).to_array(),
                params: [material.transmission.map_or(0.0, |t| t.weight.clamp(0.0, 1.0)), 0.0, 0.0, 0.0],
            });
            let class = if object.transparent {
                let k = transparent_index.iter().position(|&i| i == oi).expect("transparent objects are listed");
                transparent_slot[k] = draws.len();
                DrawClass::Transparent
            } else {
                DrawClass::Opaque
            };
            draws.push(Draw { slot: uniforms.len() - 1, class, mesh: meshes_to_draw.len() - 1 });
        }
        if self.options.draw_lights {
            for (light, quad) in scene.rect_lights.iter().zip(self.cache.light_quads(&self.device, &self.queue, &scene.rect_lights)) {
                let Some(quad) = quad else { continue };
                meshes_to_draw.push((quad.vertices.clone(), quad.indices.clone(), quad.index_count));
                textures.push((self.white.clone(), self.white.clone()));
                uniforms.push(ObjectUniform {
                    model: mat4_cols(Mat4::IDENTITY),
                    normal_matrix: mat4_cols(Mat4::IDENTITY),
                    base_color: [0.0, 0.0, 0.0, 1.0],
                    emission: light.radiance.extend(0.0).to_array(),
                    params: [0.0, 1.0, if light.two_sided { 1.0 } else { 0.0 }, 0.0],
                });
                draws.push(Draw { slot: uniforms.len() - 1, class: DrawClass::Light, mesh: meshes_to_draw.len() - 1 });
            }
        }

        // The frame's data into the buffers kept across frames.
        let layouts = Layouts {
            view: &self.view_layout,
            object: &self.object_layout,
            shading: &self.shading_layout,
            material_sampler: &self.material_sampler,
            shadow_sampler: &self.shadow_sampler,
            ltc_matrix: &self.ltc_matrix,
            ltc_amplitude: &self.ltc_amplitude,
        };
        let object_groups = self.frame_data.write_objects(&self.device, &self.queue, &layouts, &uniforms, &textures);
        let mut views = vec![ViewUniform {
            view_proj: mat4_cols(camera.view_projection(width, height)),
            camera_pos: camera.position.extend(1.0).to_array(),
            params: [light_count, u32::from(self.options.shadows), 0, 0],
        }];
        views.extend(shadow_views.iter().map(|m| ViewUniform { view_proj: mat4_cols(*m), camera_pos: [0.0; 4], params: [0; 4] }));
        let view_groups = self.frame_data.write_views(&self.device, &self.queue, &layouts, &views).to_vec();
        let shadows = self.shadows.as_ref().expect("ensured");
        let targets = self.targets.as_ref().expect("ensured");
        let inputs =
            ShadingInputs { shadow_maps: shadows.array_view.clone(), no_opaque: self.no_opaque.clone(), opaque_positions: targets.opaque.views[1].clone() };
        let (shading_opaque, shading_transparency) = self.frame_data.write_shading(&self.device, &self.queue, &layouts, &light_data, &matrix_data, inputs);

        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        // Shadow maps: opaque geometry only (glass and the lights' quads cast no shadow), drawn
        // again only when a light or an occluder moved.
        let occluders = || draws.iter().filter(|d| d.class == DrawClass::Opaque);
        let content = ShadowContent {
            faces: matrix_data.iter().map(|m| m.map(|c| c.map(f32::to_bits))).collect(),
            occluders: occluders().map(|d| (meshes_to_draw[d.mesh].0.clone(), uniforms[d.slot].model.map(|c| c.map(f32::to_bits)))).collect(),
        };
        if self.frame_data.shadow_content.as_ref() != Some(&content) {
            for (layer, group) in view_groups[1..].iter().enumerate() {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shadow"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &shadows.layer_views[layer],
                        depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(&self.shadow_pipeline);
                pass.set_bind_group(0, group, &[]);
                for d in occluders() {
                    let (v, i, n) = &meshes_to_draw[d.mesh];
                    pass.set_bind_group(1, &object_groups[d.slot], &[]);
                    pass.set_vertex_buffer(0, v.slice(..));
                    pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..*n, 0, 0..1);
                }
            }
            self.frame_data.shadow_content = Some(content);
        }
        let frame = Frame {
            width,
            height,
            view: view_groups[0].clone(),
            shading_opaque,
            shading_transparency,
            object_groups,
            meshes: meshes_to_draw,
            draws,
            transparent_slot,
            rasterizer: self,
        };
        frame.encode_pass(&mut encoder, PassKind::Opaque);
        frame.rasterizer.queue.submit([encoder.finish()]);
        Ok(frame)
    }
}

impl LightUniform {
    fn zeroed_light() -> LightUniform {
        bytemuck::Zeroable::zeroed()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DrawClass {
    Opaque,
    Transparent,
    Light,
}

struct Draw {
    slot: usize,
    class: DrawClass,
    mesh: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PassKind {
    Opaque,
    Naive,
    Transparency(usize),
}

/// One frame in flight: the opaque G-buffer is rendered; the naive G-buffer and the
/// transparency buffers are rendered on request, each transparency buffer into the same
/// reused targets and readback buffer (memory does not grow with the object count).
pub struct Frame<'r> {
    rasterizer: &'r mut Rasterizer,
    width: u32,
    height: u32,
    view: wgpu::BindGroup,
    shading_opaque: wgpu::BindGroup,
    shading_transparency: wgpu::BindGroup,
    object_groups: Vec<wgpu::BindGroup>,
    meshes: Vec<(wgpu::Buffer, wgpu::Buffer, u32)>,
    draws: Vec<Draw>,
    /// Draw index of transparency buffer k.
    transparent_slot: Vec<usize>,
}

impl Frame<'_> {
    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Number of transparency buffers (the scene's transparent objects).
    pub fn transparent_count(&self) -> usize {
        self.transparent_slot.len()
    }

    fn encode_pass(&self, encoder: &mut wgpu::CommandEncoder, kind: PassKind) {
        let r = &*self.rasterizer;
        let targets = r.targets.as_ref().expect("frame has targets");
        let (set, pipeline, shading) = match kind {
            PassKind::Opaque => (&targets.opaque, &r.gbuffer_pipeline, &self.shading_opaque),
            PassKind::Naive => (targets.naive.as_ref().expect("created"), &r.gbuffer_pipeline, &self.shading_opaque),
            PassKind::Transparency(_) => (&targets.transparency, &r.transparency_pipeline, &self.shading_transparency),
        };
        let near_targets = match kind {
            PassKind::Transparency(_) => 0..TRANSPARENCY_NEAR_TARGETS,
            _ => 0..set.views.len(),
        };
        // Nearest surfaces: depth cleared to 1, "less".
        let draws: Vec<&Draw> = match kind {
            PassKind::Opaque => self.draws.iter().filter(|d| d.class != DrawClass::Transparent).collect(),
            PassKind::Naive => self.draws.iter().collect(),
            // An object without drawable geometry leaves its buffer cleared: coverage 0.
            PassKind::Transparency(k) => self.draws.get(self.transparent_slot[k]).into_iter().collect(),
        };
        self.encode_draws(encoder, &set.color_attachments(near_targets), pipeline, shading, 1.0, &draws);
        if let PassKind::Transparency(_) = kind {
            // Farthest surfaces of the same object: depth cleared to 0, "greater".
            let far = set.color_attachments(TRANSPARENCY_NEAR_TARGETS..TRANSPARENCY_TARGETS as usize);
            self.encode_draws(encoder, &far, &r.transparency_far_pipeline, shading, 0.0, &draws);
        }
    }

    fn encode_draws(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        attachments: &[Option<wgpu::RenderPassColorAttachment<'_>>],
        pipeline: &wgpu::RenderPipeline,
        shading: &wgpu::BindGroup,
        clear_depth: f32,
        draws: &[&Draw],
    ) {
        let targets = self.rasterizer.targets.as_ref().expect("frame has targets");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("gbuffer"),
            color_attachments: attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(clear_depth), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.view, &[]);
        pass.set_bind_group(2, shading, &[]);
        for d in draws {
            let (v, i, n) = &self.meshes[d.mesh];
            pass.set_bind_group(1, &self.object_groups[d.slot], &[]);
            pass.set_vertex_buffer(0, v.slice(..));
            pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..*n, 0, 0..1);
        }
    }

    /// Read back the opaque G-buffer (17 channels, `layout::opaque_channel_names()`).
    pub fn opaque(&mut self) -> Result<PlanarImage> {
        let mut out = PlanarImage::new(self.width, self.height, layout::opaque_channel_names());
        let r = &*self.rasterizer;
        r.targets.as_ref().expect("targets").opaque.read_into(&r.device, &r.queue, &OPAQUE_MAP, self.width, self.height, out.data_mut())?;
        Ok(out)
    }

    /// Render and read back the naive G-buffer (glass overwrites what is behind it; same 17
    /// channels, `layout::naive_channel_names()`).
    pub fn naive(&mut self) -> Result<PlanarImage> {
        self.ensure_naive_targets();
        let r = &*self.rasterizer;
        let mut encoder = r.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("naive") });
        self.encode_pass(&mut encoder, PassKind::Naive);
        r.queue.submit([encoder.finish()]);
        let mut out = PlanarImage::new(self.width, self.height, layout::naive_channel_names());
        r.targets.as_ref().expect("targets").naive.as_ref().expect("created").read_into(
            &r.device,
            &r.queue,
            &OPAQUE_MAP,
            self.width,
            self.height,
            out.data_mut(),
        )?;
        Ok(out)
    }

    fn ensure_naive_targets(&mut self) {
        let r = &mut *self.rasterizer;
        let targets = r.targets.as_mut().expect("targets");
        if targets.naive.is_none() {
            targets.naive = Some(TargetSet::new(&r.device, GBUFFER_TARGETS, self.width, self.height, "naive"));
        }
    }

    /// The light coverage (`layout::LIGHT_COVERAGE_CHANNELS` planes, channel names `names`)
    /// of this frame's opaque G-buffer, or of its naive one (rendered here) if `naive`, for a
    /// frame `factor` times smaller on each side than this one: reduced on the GPU, so that
    /// only the coverage's planes are read back.
    pub(crate) fn light_coverage(&mut self, naive: bool, factor: u32, names: Vec<String>) -> Result<PlanarImage> {
        let (width, height) = self.reduce_light_coverage(naive, factor, None)?;
        let r = &*self.rasterizer;
        let readback = &r.targets.as_ref().expect("targets").coverage.as_ref().expect("reduced above").readback;
        map_for_reading(&r.device, readback)?;
        let planes = readback.get_mapped_range(..).map(|view| bytemuck::pod_collect_to_vec::<u8, f32>(&view));
        readback.unmap();
        let planes = planes.map_err(|e| Error::Internal(format!("reading the light coverage: {e}")))?;
        PlanarImage::from_planes(width, height, names, planes)
    }

    /// [`Self::light_coverage`] written into `out` from `byte_offset` on (4 f32 planes, e.g.
    /// a network input tensor's storage on this device), on the GPU: submitted, not waited
    /// for, and nothing read back.
    pub fn light_coverage_to_buffer(&mut self, naive: bool, factor: u32, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        self.reduce_light_coverage(naive, factor, Some((out, byte_offset))).map(|_| ())
    }

    /// Reduces the light coverage on the GPU into the targets' coverage buffer and copies it
    /// to `out` when given, else to the readback buffer (to be mapped). Returns the
    /// coverage's size.
    fn reduce_light_coverage(&mut self, naive: bool, factor: u32, out: Option<(&wgpu::Buffer, u64)>) -> Result<(u32, u32)> {
        if factor == 0 || !self.width.is_multiple_of(factor) || !self.height.is_multiple_of(factor) {
            return Err(Error::Internal(format!("light coverage of a {}x{} frame at factor {factor}", self.width, self.height)));
        }
        let (width, height) = (self.width / factor, self.height / factor);
        let bytes = (layout::LIGHT_COVERAGE_CHANNELS as u64) * (width as u64) * (height as u64) * 4;
        if let Some((buffer, offset)) = out {
            if !offset.is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT) || offset + bytes > buffer.size() {
                return Err(Error::Internal(format!("the light coverage's {bytes} bytes at byte {offset} of a buffer of {}", buffer.size())));
            }
        }
        if naive {
            self.ensure_naive_targets();
        }
        let r = &mut *self.rasterizer;
        let reducer = r.coverage_reducer.get_or_insert_with(|| crate::light_coverage::CoverageReducer::new(&r.device));
        let targets = r.targets.as_mut().expect("targets");
        if targets.coverage.as_ref().is_none_or(|c| c.factor != factor) {
            targets.coverage = Some(CoverageBuffers::new(&r.device, factor, bytes));
        }
        let coverage = targets.coverage.as_mut().expect("made above");
        let set = if naive { targets.naive.as_ref().expect("created above") } else { &targets.opaque };
        let group = coverage.groups[usize::from(naive)]
            .get_or_insert_with(|| reducer.bind(&r.device, &set.views[LD_TARGET as usize], width, height, factor, &coverage.reduced))
            .clone();
        let r = &*self.rasterizer;
        let mut encoder = r.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("light coverage") });
        if naive {
            self.encode_pass(&mut encoder, PassKind::Naive);
        }
        let coverage = r.targets.as_ref().expect("targets").coverage.as_ref().expect("made above");
        r.coverage_reducer.as_ref().expect("made above").encode(&mut encoder, &group, width, height);
        match out {
            Some((buffer, offset)) => encoder.copy_buffer_to_buffer(&coverage.reduced, 0, buffer, offset, bytes),
            None => encoder.copy_buffer_to_buffer(&coverage.reduced, 0, &coverage.readback, 0, bytes),
        }
        r.queue.submit([encoder.finish()]);
        Ok((width, height))
    }

    /// Render transparency buffer `k` into the reused transparency targets, on the GPU only
    /// (for consumers that read the targets in place; see [`Frame::transparency_textures`]).
    pub fn render_transparent(&mut self, k: usize) -> Result<()> {
        if k >= self.transparent_count() {
            return Err(Error::Internal(format!("transparency buffer {k} of {}", self.transparent_count())));
        }
        let r = &*self.rasterizer;
        let mut encoder = r.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("transparency") });
        self.encode_pass(&mut encoder, PassKind::Transparency(k));
        r.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Render transparency buffer `k` and read it back into `planes`: `layout::TRANSPARENT_CHANNELS` planes of
    /// width x height f32 in the channel order of `layout::transparent_channel_names`
    /// (planar, row 0 at the top). The streaming path for the network: the caller keeps one
    /// buffer and the GPU one set of targets, whatever the number of objects.
    pub fn transparent_into(&mut self, k: usize, planes: &mut [f32]) -> Result<()> {
        let expected = layout::TRANSPARENT_CHANNELS * (self.width * self.height) as usize;
        if planes.len() != expected {
            return Err(Error::Internal(format!("transparency planes: got {} floats, expected {expected}", planes.len())));
        }
        self.render_transparent(k)?;
        let r = &*self.rasterizer;
        r.targets.as_ref().expect("targets").transparency.read_into(&r.device, &r.queue, &TRANSPARENT_MAP, self.width, self.height, planes)
    }

    /// Write the opaque G-buffer into `out` from `byte_offset` on as 17 f32 planes of
    /// width x height (NCHW, `layout::opaque_channel_names()` order), on the GPU: no host copy.
    /// `out` must have STORAGE usage, and lives on this rasterizer's device (e.g. a tensor's
    /// storage when the network shares the device). Submitted; not waited for.
    pub fn opaque_to_buffer(&mut self, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        let mut encoder = self.rasterizer.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("opaque to buffer") });
        self.encode_unpack(&mut encoder, false, out, byte_offset)?;
        self.rasterizer.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Render transparency buffer `k` and write it into `out` from `byte_offset` on as `layout::TRANSPARENT_CHANNELS` f32
    /// planes (`layout::transparent_channel_names(k)` order), on the GPU, in one submission.
    pub fn transparent_to_buffer(&mut self, k: usize, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        if k >= self.transparent_count() {
            return Err(Error::Internal(format!("transparency buffer {k} of {}", self.transparent_count())));
        }
        let mut encoder = self.rasterizer.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("transparency to buffer") });
        self.encode_pass(&mut encoder, PassKind::Transparency(k));
        self.encode_unpack(&mut encoder, true, out, byte_offset)?;
        self.rasterizer.queue.submit([encoder.finish()]);
        Ok(())
    }

    fn encode_unpack(&mut self, encoder: &mut wgpu::CommandEncoder, transparency: bool, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        let r = &mut *self.rasterizer;
        if r.unpacker.is_none() {
            r.unpacker = Some(crate::unpack::Unpacker::new(&r.device));
        }
        let targets = r.targets.as_ref().expect("targets");
        let (set, map, channels): (&TargetSet, &ChannelMap, usize) = if transparency {
            (&targets.transparency, &TRANSPARENT_MAP, layout::TRANSPARENT_CHANNELS)
        } else {
            (&targets.opaque, &OPAQUE_MAP, layout::OPAQUE_CHANNELS)
        };
        r.unpacker.as_mut().expect("made above").encode(&r.device, encoder, &set.views, map, channels, self.width, self.height, out, byte_offset)
    }

    /// Render and read back transparency buffer `k`.
    pub fn transparent(&mut self, k: usize) -> Result<PlanarImage> {
        let mut out = PlanarImage::new(self.width, self.height, layout::transparent_channel_names(k));
        self.transparent_into(k, out.data_mut())?;
        Ok(out)
    }

    /// Block until the GPU has finished all submitted work (for timing).
    pub fn wait(&self) -> Result<()> {
        gpu_stats::wait(&self.rasterizer.device).map_err(Error::Internal)
    }

    /// The reused transparency targets, holding the buffer last rendered.
    pub fn transparency_textures(&self) -> &[wgpu::Texture] {
        &self.rasterizer.targets.as_ref().expect("targets").transparency.textures
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn covers_each_channel_once(map: &ChannelMap, channels: usize, targets: u32) {
        let mut seen = vec![0; channels];
        let mut slots = std::collections::HashSet::new();
        for &(first, count, target, component) in map {
            assert!(target < targets && component as usize + count <= 4);
            for c in 0..count {
                seen[first + c] += 1;
                assert!(slots.insert((target, component as usize + c)), "slot used twice");
            }
        }
        assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
    }

    #[test]
    fn channel_maps_cover_the_layout() {
        covers_each_channel_once(&OPAQUE_MAP, layout::OPAQUE_CHANNELS, GBUFFER_TARGETS);
        covers_each_channel_once(&TRANSPARENT_MAP, layout::TRANSPARENT_CHANNELS, TRANSPARENCY_TARGETS);
    }

    #[test]
    fn readback_rows_are_padded_to_256_bytes() {
        assert_eq!(padded_row_bytes(16), 256);
        assert_eq!(padded_row_bytes(17), 512);
        assert_eq!(padded_row_bytes(256), 4096);
        assert_eq!(padded_row_bytes(1), 256);
    }
}
