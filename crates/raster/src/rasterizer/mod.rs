//! The headless renderer: its device, pipelines and layouts (here), the GPU memory it keeps
//! across frames (`targets.rs`), and a frame's passes and read-backs (`frame.rs`).

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

mod frame;
mod targets;

pub use frame::Frame;
use glassbake_rays::gpu_readback::map_for_reading;
pub(crate) use targets::padded_row_bytes;
use targets::{CoverageBuffers, ShadowMaps, TargetSet, Targets};

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
/// The G-buffer target holding the position (xyz) and depth (w) (`OPAQUE_MAP`).
const POSITION_DEPTH_TARGET: u32 = 1;

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

/// The headless rasterizer. Create it once (opening the device is slow), then render frames
/// with [`Rasterizer::begin_frame`] (streaming) or [`Rasterizer::render`] (all at once).
///
/// Channel semantics (docs/raster.md has the full list): normals are world-space, unit and
/// flipped to face the camera; positions world-space; albedo linear and textured (the
/// texture's mean over the pixel's footprint; the tint for glass); depth is the Euclidean
/// distance to the camera; w_o points to the camera; L_d is direct light from the rectangle
/// lights (exact polygon form factor for diffuse, LTC for GGX, hemicube shadow maps) plus
/// emission. Background is 0. A transparency
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
    coverage_reducer: Option<crate::light_coverage::sampled::CoverageReducer>,
    /// The compute pass clipping the lights' outlines to the pixels (made on first use).
    exact_coverage: Option<crate::light_coverage::exact::ExactCoverage>,
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

        let (view_layout, object_layout, shading_layout) = bind_group_layouts(&device);
        let Pipelines { gbuffer_pipeline, transparency_pipeline, transparency_far_pipeline, shadow_pipeline } =
            pipelines(&device, &view_layout, &object_layout, &shading_layout);
        let (material_sampler, shadow_sampler) = samplers(&device);
        let ConstantTextures { white, no_opaque, ltc_matrix, ltc_amplitude } = constant_textures(&device, &queue);

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
            exact_coverage: None,
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
    /// buffer, the G-buffers' light coverage (exact, or sampled at
    /// [`crate::light_coverage::coverage_factor`]: [`crate::light_coverage::CoverageMethod`]),
    /// and each transparency buffer's through buffer (cast on the CPU).
    pub fn render(&mut self, scene: &Scene, camera: &Camera, width: u32, height: u32) -> Result<FrameBuffers> {
        let mut frame = self.begin_frame(scene, camera, width, height)?;
        let opaque = frame.opaque()?;
        let naive = frame.naive()?;
        let transparent = (0..frame.transparent_count()).map(|k| frame.transparent(k)).collect::<Result<Vec<_>>>()?;
        let exact = crate::light_coverage::exact_of_frame(&mut frame, scene, camera)?;
        drop(frame);
        let light_coverage = match exact {
            Some(coverage) => coverage,
            None => {
                let factor = crate::light_coverage::coverage_factor(self, width, height);
                crate::light_coverage::light_coverage(self, scene, camera, width, height, factor)?
            }
        };
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
}

/// The bind groups' layouts: the view (camera or shadow face), the object (uniform, textures,
/// sampler) and the shading inputs (lights, shadow maps, LTC tables, opaque positions).
fn bind_group_layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
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
    (view_layout, object_layout, shading_layout)
}

/// `shaders/gbuffer.wgsl` after the constants it takes from Rust and the lights' form factor,
/// which the through pass shares (`glassbake_rays::direct::POLYGON_WGSL`).
pub(crate) fn gbuffer_source() -> String {
    use glassbake_core::wgsl::{constants, Value, DIELECTRIC_F0};
    constants(&[("LTC_SIZE", Value::I32(ltc::LTC_SIZE as i32)), ("DIELECTRIC_F0", Value::F32(DIELECTRIC_F0))])
        + glassbake_rays::direct::POLYGON_WGSL
        + include_str!("../../shaders/gbuffer.wgsl")
}

/// The render pipelines of `shaders/gbuffer.wgsl`.
struct Pipelines {
    gbuffer_pipeline: wgpu::RenderPipeline,
    transparency_pipeline: wgpu::RenderPipeline,
    transparency_far_pipeline: wgpu::RenderPipeline,
    shadow_pipeline: wgpu::RenderPipeline,
}

fn pipelines(
    device: &wgpu::Device,
    view_layout: &wgpu::BindGroupLayout,
    object_layout: &wgpu::BindGroupLayout,
    shading_layout: &wgpu::BindGroupLayout,
) -> Pipelines {
    let module =
        device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("gbuffer.wgsl"), source: wgpu::ShaderSource::Wgsl(gbuffer_source().into()) });
    let shading_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("shading"),
        bind_group_layouts: &[Some(view_layout), Some(object_layout), Some(shading_layout)],
        immediate_size: 0,
    });
    let shadow_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("shadow"),
        bind_group_layouts: &[Some(view_layout), Some(object_layout)],
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
    Pipelines { gbuffer_pipeline, transparency_pipeline, transparency_far_pipeline, shadow_pipeline }
}

/// The materials' sampler (trilinear, repeating) and the shadow maps' (comparing).
fn samplers(device: &wgpu::Device) -> (wgpu::Sampler, wgpu::Sampler) {
    let material_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("material"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        address_mode_w: wgpu::AddressMode::Repeat,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        // Trilinear, not anisotropic: the G-buffer reads each texture over the pixel's
        // footprint in 4x4 lookups of its own (`footprint_sample` in gbuffer.wgsl), which
        // give the same mean on every device; lavapipe's anisotropic filter ignores their
        // explicit gradients and blurs over the whole footprint again.
        anisotropy_clamp: 1,
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
    (material_sampler, shadow_sampler)
}

/// Textures every frame reads: a white texel for untextured materials, a "no opaque surface"
/// texel, and the LTC tables.
struct ConstantTextures {
    white: wgpu::TextureView,
    no_opaque: wgpu::TextureView,
    ltc_matrix: wgpu::TextureView,
    ltc_amplitude: wgpu::TextureView,
}

fn constant_textures(device: &wgpu::Device, queue: &wgpu::Queue) -> ConstantTextures {
    let one = half::f16::ONE.to_bits();
    let white = small_texture(device, queue, wgpu::TextureFormat::Rgba16Float, 1, bytemuck::cast_slice(&[one; 4]));
    let no_opaque = small_texture(device, queue, TARGET_FORMAT, 1, bytemuck::cast_slice(&[0.0f32; 4]));
    let table = ltc::table();
    let size = ltc::LTC_SIZE as u32;
    let matrix: Vec<f32> = table.iter().flat_map(|c| c.minv).collect();
    let amplitude: Vec<f32> = table.iter().flat_map(|c| [c.amplitude[0], c.amplitude[1], 0.0, 0.0]).collect();
    let ltc_matrix = small_texture(device, queue, TARGET_FORMAT, size, bytemuck::cast_slice(&matrix));
    let ltc_amplitude = small_texture(device, queue, TARGET_FORMAT, size, bytemuck::cast_slice(&amplitude));
    ConstantTextures { white, no_opaque, ltc_matrix, ltc_amplitude }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gbuffer_shader_takes_its_physics_constants_from_rust() {
        use glassbake_core::wgsl::{declarations, DIELECTRIC_F0};
        let (file, source) = (include_str!("../../shaders/gbuffer.wgsl"), gbuffer_source());
        for name in ["LTC_SIZE", "DIELECTRIC_F0"] {
            assert_eq!((declarations(file, name), declarations(&source, name)), (0, 1), "{name}");
        }
        assert!(source.contains(&format!("const LTC_SIZE: i32 = {};", ltc::LTC_SIZE)));
        assert!(source.contains(&format!("const DIELECTRIC_F0: f32 = {DIELECTRIC_F0:?};")));
        assert!(!file.contains("0.04"), "a literal F0 beside the constant");
    }

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
