//! One frame: camera + variable values -> rasterizer -> GlassNet -> optional x2 super-sampler.
//!
//! The rasterizer renders the opaque G-buffer, then each transparency buffer into one reused
//! set of targets, handed to GlassNet's streaming forward pass, so neither the GPU nor the host
//! holds more than one transparency buffer whatever the object count. With separate devices
//! (the CPU network, or `--host-copy`) each buffer is read back into one reused host buffer and
//! crosses the host once; with burn's wgpu runtime on the rasterizer's device it is written
//! straight into the network's input tensor (`gpu_handover`), and so is its through buffer when
//! the GPU pass casts it (see docs/realtime.md for why and what each costs).

use web_time::Instant;

use glam::Vec3;
use glassbake_core::layout::{self, OPAQUE_ATTRIBUTES, TRANSPARENT_ATTRIBUTES, TRANSPARENT_CHANNELS};
use glassbake_core::{Camera, Error, PlanarImage, Result};
use glassbake_net::batch::image_from_tensor;
use glassbake_net::burn::prelude::*;
use glassbake_net::burn::tensor::TensorData;
use glassbake_net::super_sampler::downsample_box2_tensor;
use glassbake_net::{TrainedModel, TrainedSuperSampler};
use glassbake_raster::light_coverage::{
    coverage_factor, exact_light_coverage_into_frame, exact_light_coverage_of_frame, light_coverage_into, light_coverage_of, CoverageMethod,
    LIGHT_COVERAGE_FACTOR,
};
use glassbake_raster::{wgpu, Frame, Rasterizer, RasterizerOptions};
use glassbake_rays::through::{through_buffer, ThroughScene};
use glassbake_rays::through_gpu::{GpuThroughPass, GpuThroughScene, PlanesAt};
use glassbake_scene::Scene;

/// What a frame shows.
#[derive(Clone, Debug, PartialEq)]
pub enum Output {
    /// The trained GlassNet (the pipeline's main model).
    GlassNet,
    /// The naive baseline, when one was loaded.
    Naive,
    /// One attribute of one rasterized buffer: `layer` is `opaque`, `naive` or
    /// `transparent.K`; `attribute` one of `layout`'s attribute names.
    Buffer { layer: String, attribute: String },
}

impl Output {
    /// `glassnet`, `naive`, or a buffer attribute `LAYER.ATTRIBUTE` (`opaque.albedo`,
    /// `transparent.0.coverage`).
    pub fn parse(text: &str) -> Result<Output> {
        Ok(match text {
            "glassnet" => Output::GlassNet,
            "naive" => Output::Naive,
            other => {
                let (layer, attribute) = other
                    .rsplit_once('.')
                    .ok_or_else(|| Error::bad_input("--output", "output", format!("{other:?} is not glassnet, naive or LAYER.ATTRIBUTE")))?;
                Output::Buffer { layer: layer.into(), attribute: attribute.into() }
            }
        })
    }
}

/// Where a frame's through rays are cast, for a model that reads through buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThroughRays {
    /// On the CPU (`glassbake_rays::through`), with rayon over the rows.
    Cpu,
    /// In a wgpu compute pass on the rasterizer's device (`glassbake_rays::through_gpu`).
    Gpu,
}

impl ThroughRays {
    /// `auto` (`None`: the pipeline chooses for its adapter), `cpu` or `gpu`.
    pub fn parse(text: &str) -> Result<Option<ThroughRays>> {
        match text {
            "auto" => Ok(None),
            "cpu" => Ok(Some(ThroughRays::Cpu)),
            "gpu" => Ok(Some(ThroughRays::Gpu)),
            other => Err(Error::bad_input("--through-rays", "through_rays", format!("{other:?} is not auto, cpu or gpu"))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ThroughRays::Cpu => "cpu",
            ThroughRays::Gpu => "gpu",
        }
    }
}

/// A frame's through-ray caster, with what it built for the frame's scene instance.
enum ThroughCaster {
    Cpu(ThroughScene),
    Gpu(GpuThroughScene),
}

/// Wall-clock split of one frame, milliseconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameTimes {
    /// Rasterizing and reading back buffers (including the transparency buffers fed while the
    /// network runs).
    pub raster_ms: f64,
    /// Casting the through buffers' refracted rays (on the CPU or the GPU, see
    /// [`ThroughRays`]: BVHs and rays), for a model that reads them; part of neither of the
    /// others. In the zero-copy frame the GPU pass is only submitted here and runs with the
    /// network.
    pub through_ms: f64,
    /// Everything else: the network, uploads, the image read-back.
    pub network_ms: f64,
    pub total_ms: f64,
}

impl std::fmt::Display for FrameTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let FrameTimes { raster_ms, through_ms, network_ms, total_ms } = self;
        write!(f, "{total_ms:.1} ms (raster {raster_ms:.1}, through rays {through_ms:.1}, network {network_ms:.1})")
    }
}

pub struct FramePipeline {
    pub scene: Scene,
    pub glassnet: TrainedModel,
    pub naive: Option<TrainedModel>,
    pub super_sampler: Option<TrainedSuperSampler>,
    /// Samples per pixel side of the light coverage (for models with it): the datasets'
    /// `LIGHT_COVERAGE_FACTOR` unless a faster, coarser frame is asked for.
    pub light_coverage_factor: u32,
    rasterizer: Rasterizer,
    /// Draws the light coverage's finer frame on the same device, so neither rasterizer
    /// reallocates its targets every frame.
    coverage_rasterizer: Rasterizer,
    /// The one host buffer transparency buffers are read back into.
    planes: Vec<f32>,
    /// GlassNet's inputs are written by the rasterizer straight into tensors on the shared
    /// wgpu device (`gpu_handover`) instead of going through `planes`.
    zero_copy: bool,
    through_rays: ThroughRays,
    /// The GPU through pass, compiled when first used.
    gpu_through: Option<GpuThroughPass>,
    /// The through rays' geometry (BVHs, on the CPU or uploaded) and the variable values it
    /// was made for: a camera moving through a still scene does no BVH work, a variable that
    /// moves an object or a light refits the BVHs to it.
    through_geometry: BuiltForValues<ThroughCaster>,
}

/// What was built for one set of variable values, kept until the values change.
struct BuiltForValues<T> {
    built: Option<(Vec<u32>, T)>,
}

impl<T> BuiltForValues<T> {
    fn new() -> BuiltForValues<T> {
        BuiltForValues { built: None }
    }

    /// What was built for `values` if it `fits`, else what `build` makes now from what was
    /// built before, if anything (kept for later frames). Values compare bit for bit: any
    /// move of a variable rebuilds.
    fn get_or_build(&mut self, values: &[f32], fits: impl Fn(&T) -> bool, build: impl FnOnce(Option<T>) -> Result<T>) -> Result<&T> {
        let key: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
        let current = matches!(&self.built, Some((built_for, value)) if *built_for == key && fits(value));
        if !current {
            let previous = self.built.take().map(|(_, value)| value);
            self.built = Some((key, build(previous)?));
        }
        Ok(&self.built.as_ref().expect("built above").1)
    }

    fn clear(&mut self) {
        self.built = None;
    }
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl FramePipeline {
    pub fn new(
        scene: Scene,
        glassnet: TrainedModel,
        naive: Option<TrainedModel>,
        super_sampler: Option<TrainedSuperSampler>,
        raster: RasterizerOptions,
    ) -> Result<FramePipeline> {
        FramePipeline::with_rasterizer(scene, glassnet, naive, super_sampler, Rasterizer::new(raster)?, false)
    }

    /// A pipeline on a given rasterizer. `zero_copy`: the models live on burn's wgpu runtime
    /// registered on the rasterizer's own device (`gpu_handover::open_shared`).
    pub fn with_rasterizer(
        scene: Scene,
        glassnet: TrainedModel,
        naive: Option<TrainedModel>,
        super_sampler: Option<TrainedSuperSampler>,
        rasterizer: Rasterizer,
        zero_copy: bool,
    ) -> Result<FramePipeline> {
        if glassnet.net.reads_naive_gbuffer() {
            return Err(Error::bad_input(
                glassnet.files.dir.display(),
                "network",
                format!("is the {} baseline on the naive G-buffer; give a GlassNet model (the baseline goes to --naive)", glassnet.kind().name()),
            ));
        }
        if let Some(n) = &naive {
            if !n.net.reads_naive_gbuffer() {
                return Err(Error::bad_input(n.files.dir.display(), "network", "is not a baseline on the naive G-buffer (naive or pixelgen)"));
            }
        }
        let coverage_rasterizer = rasterizer.sibling()?;
        // On a CPU adapter (lavapipe) the CPU caster is the faster (docs/realtime.md).
        let through_rays = if rasterizer.adapter_info().device_type == glassbake_raster::wgpu::DeviceType::Cpu { ThroughRays::Cpu } else { ThroughRays::Gpu };
        Ok(FramePipeline {
            scene,
            glassnet,
            naive,
            super_sampler,
            light_coverage_factor: LIGHT_COVERAGE_FACTOR,
            rasterizer,
            coverage_rasterizer,
            planes: Vec::new(),
            zero_copy,
            through_rays,
            gpu_through: None,
            through_geometry: BuiltForValues::new(),
        })
    }

    /// Where the through rays are cast: the GPU pass on a GPU adapter, the CPU caster on a
    /// CPU adapter, unless [`Self::set_through_rays`] chose.
    pub fn through_rays(&self) -> ThroughRays {
        self.through_rays
    }

    pub fn set_through_rays(&mut self, through_rays: ThroughRays) {
        self.through_rays = through_rays;
    }

    /// Whether frame data stays on the GPU between the rasterizer and the network.
    pub fn zero_copy(&self) -> bool {
        self.zero_copy
    }

    /// Whether GlassNet's frames stay on the GPU: zero-copy, unless its through rays are cast
    /// on the CPU.
    pub fn glassnet_frames_zero_copy(&self) -> bool {
        self.zero_copy && !(self.glassnet.config().through && self.through_rays == ThroughRays::Cpu)
    }

    /// Replaces the scene (the benchmark's object counts); the models stay.
    pub fn set_scene(&mut self, scene: Scene) {
        self.scene = scene;
        self.through_geometry.clear();
        self.rasterizer.clear_cache();
        self.coverage_rasterizer.clear_cache();
    }

    /// The wgpu objects alive on the rasterizer's device (see
    /// [`Rasterizer::live_gpu_objects`]).
    pub fn live_gpu_objects(&self) -> i64 {
        self.rasterizer.live_gpu_objects()
    }

    /// The rasterizer's wgpu instance, adapter, device and queue (the network's too when
    /// [`Self::zero_copy`]), for a window to draw on the same device.
    pub fn wgpu_handles(&self) -> (wgpu::Instance, wgpu::Adapter, wgpu::Device, wgpu::Queue) {
        let r = &self.rasterizer;
        (r.instance().clone(), r.adapter().clone(), r.device().clone(), r.queue().clone())
    }

    pub fn adapter_name(&self) -> String {
        self.rasterizer.adapter_info().name.clone()
    }

    /// Renders one `width` x `height` frame. `values` are the variables' values in their
    /// units (not normalised). Returns linear RGB clamped to [0, 1] (channels R, G, B).
    pub fn render(&mut self, camera: &Camera, values: &[f32], width: u32, height: u32, output: &Output) -> Result<(PlanarImage, FrameTimes)> {
        let start = Instant::now();
        let (image, mut times) = match output {
            Output::Buffer { layer, attribute } => {
                let instance = self.scene.instantiate(values)?;
                let image = self.buffer_view(&instance, camera, width, height, layer, attribute)?;
                (image, FrameTimes { raster_ms: ms(start), ..FrameTimes::default() })
            }
            Output::GlassNet | Output::Naive => {
                let (prediction, times) = self.render_on_device(camera, values, width, height, *output == Output::Naive)?;
                if self.zero_copy {
                    // Reading the image back is the frame's one wait for the GPU.
                    glassbake_rays::gpu_stats::waited_elsewhere();
                }
                (image_from_tensor(&prediction, 0)?, times)
            }
        };
        times.total_ms = ms(start);
        times.network_ms = (times.total_ms - times.raster_ms - times.through_ms).max(0.0);
        Ok((image, times))
    }

    /// GlassNet's frame (the naive baseline's with `naive`) left on the network's device: a
    /// [1, 3, height, width] tensor of linear RGB clamped to [0, 1], which [`Self::render`]
    /// reads back and a window can show as it is (`raster::display`, the viewer). Its times
    /// end when the frame's work is submitted, not done.
    pub fn render_on_device(&mut self, camera: &Camera, values: &[f32], width: u32, height: u32, naive: bool) -> Result<(Tensor<4>, FrameTimes)> {
        let start = Instant::now();
        let instance = self.scene.instantiate(values)?;
        let normalised: Vec<f32> = self.scene.variables.iter().zip(values).map(|(v, &x)| v.normalize(x)).collect();
        let mut times = FrameTimes::default();
        let (lw, lh) = self.network_size(naive, width, height)?;
        let sr = self.super_sampler.is_some();
        let model = if naive { self.naive.as_ref().expect("checked") } else { &self.glassnet };
        let reads_objects = model.net.reads_object_buffers();
        model.net.check_inputs(lw as usize, lh as usize, if reads_objects { instance.transparent_count() } else { 0 })?;
        let device = model.device.clone();
        let through = model.config().through;
        if through && self.through_rays == ThroughRays::Gpu && self.gpu_through.is_none() {
            self.gpu_through = Some(GpuThroughPass::new(self.rasterizer.device().clone(), self.rasterizer.queue().clone())?);
        }
        // The through buffers are cast from read-back buffers (on the CPU or the GPU).
        // A model reading through buffers stays on the GPU when the GPU pass casts them.
        let zero_copy = self.zero_copy && !naive && (!through || self.through_rays == ThroughRays::Gpu);
        let raster_start = Instant::now();
        // With the super-sampler the coverage is drawn at the full resolution it composites
        // at, and 2x2-averaged for the network, as train-sr and eval do. Zero-copy, it is
        // reduced into a tensor and averaged on the GPU; else it crosses the host once. The
        // exact coverage at the network's resolution comes from the frame's own G-buffer.
        let sampler_coverage = self.super_sampler.as_ref().is_some_and(|s| s.net.config.light_coverage);
        let wants_coverage = model.config().light_coverage || sampler_coverage;
        let from_frame = wants_coverage && !sr && CoverageMethod::for_scene(&instance, LIGHT_COVERAGE_FACTOR) == CoverageMethod::Exact;
        let coverage = if wants_coverage && !from_frame {
            let full = if sr { (width, height) } else { (lw, lh) };
            let factor = self.light_coverage_factor;
            Some(sampled_coverage(&mut self.coverage_rasterizer, factor, &instance, camera, full, zero_copy, &device, naive)?)
        } else {
            None
        };
        let mut frame = self.rasterizer.begin_frame(&instance, camera, lw, lh)?;
        let coverage = if from_frame { Some(exact_coverage_of_frame(&mut frame, &instance, camera, zero_copy, &device, naive)?) } else { coverage };
        let light_coverage = match &coverage {
            Some(full) if model.config().light_coverage => Some(if sr { downsample_box2_tensor(full.clone()) } else { full.clone() }),
            _ => None,
        };
        let (h, w) = (lh as usize, lw as usize);
        let to_tensor = |data: Vec<f32>, channels: usize| Tensor::<4>::from_data(TensorData::new(data, [1, channels, h, w]), &device);
        let (gbuffer, opaque_image) = gbuffer_tensor(&mut frame, zero_copy, naive, through, &device)?;
        let objects = if reads_objects { frame.transparent_count() } else { 0 };
        // The GPU pass reads the opaque G-buffer's L_d from the network's input tensor.
        let gbuffer_on_gpu = (zero_copy && through).then(|| gbuffer.clone());
        times.raster_ms += ms(raster_start);
        let values_tensor = Tensor::<2>::from_data(TensorData::new(normalised.clone(), [1, normalised.len()]), &device);
        let planes = &mut self.planes;
        if !zero_copy {
            planes.resize(TRANSPARENT_CHANNELS * w * h, 0.0);
        }
        let build_start = Instant::now();
        let gpu_through = self.gpu_through.as_ref();
        let on_gpu = self.through_rays == ThroughRays::Gpu && gpu_through.is_some();
        let caster = if through { Some(through_caster(&mut self.through_geometry, gpu_through.filter(|_| on_gpu), &instance, values)?) } else { None };
        let build_ms = ms(build_start);
        let mut cast_ms = 0.0;
        let mut failure = None;
        let mut raster_ms = 0.0;
        let prediction = model.net.forward_streaming(gbuffer, light_coverage, values_tensor, objects, &mut |k| {
            let t = Instant::now();
            let tensor = if let (true, Some(ThroughCaster::Gpu(uploaded)), Some(opaque)) = (zero_copy, &caster, &gbuffer_on_gpu) {
                // The transparency buffer, then the through buffer the GPU pass casts
                // from its coverage and the opaque G-buffer's L_d, into one tensor.
                let channels = TRANSPARENT_CHANNELS + layout::THROUGH_CHANNELS;
                crate::gpu_handover::input_tensor(&device, channels, h, w, |buffer, offset| {
                    frame.transparent_to_buffer(k, buffer, offset)?;
                    let cast = Instant::now();
                    crate::gpu_handover::with_buffer(opaque, |gbuffer, gbuffer_offset| {
                        let ld = PlanesAt { buffer: gbuffer, byte_offset: gbuffer_offset, plane: layout::opaque::LD as u64 };
                        let pass = gpu_through.expect("compiled above");
                        pass.cast_into(uploaded, k, camera, lw, lh, ld, buffer, offset, layout::transparent::COVERAGE as u64, TRANSPARENT_CHANNELS as u64)
                    })?;
                    cast_ms += ms(cast);
                    Ok(())
                })
            } else if zero_copy {
                crate::gpu_handover::input_tensor(&device, TRANSPARENT_CHANNELS, h, w, |buffer, offset| frame.transparent_to_buffer(k, buffer, offset))
            } else {
                frame.transparent_into(k, planes).and_then(|()| match (&caster, &opaque_image) {
                    (Some(caster), Some(opaque)) => {
                        let cast = Instant::now();
                        let through = cast_on_host(&instance, caster, gpu_through, k, camera, opaque, planes);
                        cast_ms += ms(cast);
                        let mut data = Vec::with_capacity((TRANSPARENT_CHANNELS + layout::THROUGH_CHANNELS) * w * h);
                        data.extend_from_slice(planes);
                        data.extend_from_slice(through?.data());
                        Ok(to_tensor(data, TRANSPARENT_CHANNELS + layout::THROUGH_CHANNELS))
                    }
                    _ => Ok(to_tensor(planes.clone(), TRANSPARENT_CHANNELS)),
                })
            };
            raster_ms += ms(t);
            match tensor {
                Ok(tensor) => Some(tensor),
                Err(e) => {
                    failure = Some(e);
                    None
                }
            }
        });
        drop(frame);
        if let Some(e) = failure {
            return Err(e);
        }
        // The rays were cast inside the rasterizer's timed callback.
        times.through_ms = build_ms + cast_ms;
        times.raster_ms += raster_ms - cast_ms;
        let mut prediction = prediction.clamp(0.0, 1.0);
        if self.super_sampler.is_some() {
            let (image, raster_ms) = self.super_sample(prediction, &instance, camera, width, height, coverage.filter(|_| sampler_coverage))?;
            prediction = image;
            times.raster_ms += raster_ms;
        }
        times.total_ms = ms(start);
        times.network_ms = (times.total_ms - times.raster_ms - times.through_ms).max(0.0);
        Ok((prediction, times))
    }

    /// The size the network renders at for a `width` x `height` frame (half of it with the
    /// super-sampler), or why the request cannot be served.
    fn network_size(&self, naive: bool, width: u32, height: u32) -> Result<(u32, u32)> {
        if naive && self.naive.is_none() {
            return Err(Error::bad_input("--naive", "model", "no naive baseline was loaded"));
        }
        if self.super_sampler.is_none() {
            return Ok((width, height));
        }
        if !(width.is_multiple_of(2) && height.is_multiple_of(2)) {
            return Err(Error::bad_input("--res", "resolution", "the x2 super-sampler needs an even size"));
        }
        Ok((width / 2, height / 2))
    }

    /// `low`, the network's half-resolution image, brought up to `width` x `height` by the
    /// super-sampler with the full-resolution G-buffer (and the lights' coverage, when the
    /// super-sampler reads it). Returns the image and the milliseconds its G-buffer took.
    fn super_sample(
        &mut self,
        low: Tensor<4>,
        instance: &Scene,
        camera: &Camera,
        width: u32,
        height: u32,
        coverage: Option<Tensor<4>>,
    ) -> Result<(Tensor<4>, f64)> {
        let sampler = self.super_sampler.as_ref().expect("called with a super-sampler");
        let t = Instant::now();
        let mut full = self.rasterizer.begin_frame(instance, camera, width, height)?;
        let (h, w) = (height as usize, width as usize);
        let gbuffer = if self.zero_copy {
            crate::gpu_handover::input_tensor(&sampler.device, layout::OPAQUE_CHANNELS, h, w, |buffer, offset| full.opaque_to_buffer(buffer, offset))?
        } else {
            Tensor::<4>::from_data(TensorData::new(full.opaque()?.data().to_vec(), [1, layout::OPAQUE_CHANNELS, h, w]), &sampler.device)
        };
        drop(full);
        let raster_ms = ms(t);
        let low = low.to_device(&sampler.device);
        let light_coverage = coverage.map(|full| full.to_device(&sampler.device));
        Ok((sampler.net.forward(low, gbuffer, light_coverage).clamp(0.0, 1.0), raster_ms))
    }

    /// One attribute of one buffer as an RGB image (scalars grey; normals and directions
    /// mapped from [-1, 1]; positions and depths scaled by the scene's extent).
    fn buffer_view(&mut self, instance: &Scene, camera: &Camera, width: u32, height: u32, layer: &str, attribute: &str) -> Result<PlanarImage> {
        let mut frame = self.rasterizer.begin_frame(instance, camera, width, height)?;
        let (image, attributes) = match layer {
            "opaque" => (frame.opaque()?, &OPAQUE_ATTRIBUTES[..]),
            "naive" => (frame.naive()?, &OPAQUE_ATTRIBUTES[..]),
            other => {
                let k =
                    other.strip_prefix("transparent.").and_then(|k| k.parse::<usize>().ok()).filter(|&k| k < frame.transparent_count()).ok_or_else(|| {
                        Error::bad_input("--layer", "layer", format!("{other:?} is not opaque, naive or transparent.K with K < {}", frame.transparent_count()))
                    })?;
                (frame.transparent(k)?, &TRANSPARENT_ATTRIBUTES[..])
            }
        };
        drop(frame);
        let mut offset = 0;
        let found = attributes.iter().find(|a| {
            let hit = a.name == attribute;
            if !hit {
                offset += a.components.len();
            }
            hit
        });
        let attr = found.ok_or_else(|| {
            Error::bad_input(
                "--layer",
                "attribute",
                format!("{attribute:?} is not one of {}", attributes.iter().map(|a| a.name).collect::<Vec<_>>().join(", ")),
            )
        })?;
        let extent = instance.bounds().map(|(lo, hi)| (hi - lo).length()).unwrap_or(1.0).max(1e-6);
        let centre = instance.bounds().map(|(lo, hi)| 0.5 * (lo + hi)).unwrap_or(Vec3::ZERO);
        let map = |c: usize, v: f32| match attr.name {
            "normal" | "wo" => 0.5 * v + 0.5,
            "position" => (v - centre[c]) / extent + 0.5,
            "depth" => v / extent,
            _ => v,
        };
        let pixels = (width * height) as usize;
        let mut data = Vec::with_capacity(3 * pixels);
        for c in 0..3 {
            let component = c.min(attr.components.len() - 1);
            data.extend(image.plane(offset + component).iter().map(|&v| map(component, v)));
        }
        PlanarImage::from_planes(width, height, layout::GROUND_TRUTH_CHANNELS.iter().map(|s| s.to_string()).collect(), data)
    }
}

/// The lights' coverage of each pixel of a `size` frame as a network input on `device`:
/// `make(Some((buffer, offset)))` writes it straight into the tensor's buffer when
/// `zero_copy`, else `make(None)` returns it on the host to be uploaded.
fn coverage_tensor(
    (width, height): (u32, u32),
    zero_copy: bool,
    device: &Device,
    make: impl FnOnce(Option<(&wgpu::Buffer, u64)>) -> Result<Option<PlanarImage>>,
) -> Result<Tensor<4>> {
    let (channels, h, w) = (layout::LIGHT_COVERAGE_CHANNELS, height as usize, width as usize);
    if zero_copy {
        crate::gpu_handover::input_tensor(device, channels, h, w, |buffer, offset| make(Some((buffer, offset))).map(|_| ()))
    } else {
        let image = make(None)?.ok_or_else(|| Error::Internal("the light coverage was not made on the host".into()))?;
        Ok(Tensor::<4>::from_data(TensorData::new(image.data().to_vec(), [1, channels, h, w]), device))
    }
}

/// The lights' coverage at `size` sampled on `rasterizer`'s own G-buffer (at most
/// `max_factor`² samples a pixel): written straight into a tensor zero-copy, else read back once.
#[allow(clippy::too_many_arguments)]
fn sampled_coverage(
    rasterizer: &mut Rasterizer,
    max_factor: u32,
    instance: &Scene,
    camera: &Camera,
    (width, height): (u32, u32),
    zero_copy: bool,
    device: &Device,
    naive: bool,
) -> Result<Tensor<4>> {
    let factor = coverage_factor(rasterizer, width, height).min(max_factor.max(1));
    coverage_tensor((width, height), zero_copy, device, |out| match out {
        Some((buffer, offset)) => light_coverage_into(rasterizer, instance, camera, width, height, factor, naive, buffer, offset).map(|()| None),
        None => light_coverage_of(rasterizer, instance, camera, width, height, factor, naive).map(Some),
    })
}

/// The lights' exact coverage at the frame's own size, from its G-buffer (a scene whose
/// lights are all rectangles, see `CoverageMethod::for_scene`).
fn exact_coverage_of_frame(frame: &mut Frame<'_>, instance: &Scene, camera: &Camera, zero_copy: bool, device: &Device, naive: bool) -> Result<Tensor<4>> {
    let exact_only = || Error::Internal("the exact light coverage was chosen for a scene that needs the sampled one".into());
    let size = (frame.width(), frame.height());
    coverage_tensor(size, zero_copy, device, |out| match out {
        Some((buffer, offset)) => exact_light_coverage_into_frame(frame, instance, camera, naive, buffer, offset)?.then_some(None).ok_or_else(exact_only),
        None => exact_light_coverage_of_frame(frame, instance, camera, naive)?.ok_or_else(exact_only).map(Some),
    })
}

/// Object `k`'s through buffer from its transparency buffer `planes` read back to the host
/// and the opaque G-buffer `opaque` (for the direct light where the rays land).
fn cast_on_host(
    instance: &Scene,
    caster: &ThroughCaster,
    gpu: Option<&GpuThroughPass>,
    k: usize,
    camera: &Camera,
    opaque: &PlanarImage,
    planes: &[f32],
) -> Result<PlanarImage> {
    let pixels = opaque.width() as usize * opaque.height() as usize;
    let coverage = &planes[layout::transparent::COVERAGE * pixels..(layout::transparent::COVERAGE + 1) * pixels];
    Ok(match caster {
        ThroughCaster::Cpu(geometry) => through_buffer(instance, geometry, k, camera, opaque, coverage),
        ThroughCaster::Gpu(uploaded) => gpu.expect("a GPU caster is made by the GPU pass").through_buffer(uploaded, k, camera, opaque, coverage)?,
    })
}

/// The network's G-buffer input (the naive one with `naive`) and, on the host path, the opaque
/// G-buffer kept for the through rays' direct light (`through`).
fn gbuffer_tensor(frame: &mut Frame<'_>, zero_copy: bool, naive: bool, through: bool, device: &Device) -> Result<(Tensor<4>, Option<PlanarImage>)> {
    let (h, w) = (frame.height() as usize, frame.width() as usize);
    let to_tensor = |image: &PlanarImage| Tensor::<4>::from_data(TensorData::new(image.data().to_vec(), [1, layout::OPAQUE_CHANNELS, h, w]), device);
    if zero_copy {
        let tensor = crate::gpu_handover::input_tensor(device, layout::OPAQUE_CHANNELS, h, w, |buffer, offset| frame.opaque_to_buffer(buffer, offset))?;
        Ok((tensor, None))
    } else if naive {
        let opaque = if through { Some(frame.opaque()?) } else { None };
        Ok((to_tensor(&frame.naive()?), opaque))
    } else {
        let opaque = frame.opaque()?;
        Ok((to_tensor(&opaque), Some(opaque)))
    }
}

/// The through rays' geometry for `instance` (its variable `values`): kept while the values
/// stay, refit when objects or lights moved (on the GPU written into the last upload's
/// buffers), built anew otherwise; uploaded to `gpu` when given, else on the CPU.
fn through_caster<'a>(
    geometry: &'a mut BuiltForValues<ThroughCaster>,
    gpu: Option<&GpuThroughPass>,
    instance: &Scene,
    values: &[f32],
) -> Result<&'a ThroughCaster> {
    geometry.get_or_build(
        values,
        |caster| matches!(caster, ThroughCaster::Gpu(_)) == gpu.is_some(),
        |previous| {
            Ok(match (gpu, previous) {
                (Some(pass), Some(ThroughCaster::Gpu(uploaded))) => ThroughCaster::Gpu(pass.upload_reusing(instance, Some(uploaded))?),
                (Some(pass), _) => ThroughCaster::Gpu(pass.upload(instance)?),
                (None, Some(ThroughCaster::Cpu(cpu))) => ThroughCaster::Cpu(cpu.refit_or_build(instance)),
                (None, _) => ThroughCaster::Cpu(ThroughScene::build(instance)),
            })
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    #[test]
    fn geometry_is_rebuilt_only_when_a_value_or_the_caster_changes() {
        let builds = Cell::new(0);
        let mut built = BuiltForValues::new();
        let mut get = |values: &[f32], kind: char| -> (char, usize) {
            let got = *built
                .get_or_build(
                    values,
                    |&k| k == kind,
                    |_| {
                        builds.set(builds.get() + 1);
                        Ok(kind)
                    },
                )
                .unwrap();
            (got, builds.get())
        };
        assert_eq!(get(&[0.5, 1.0], 'c'), ('c', 1));
        // The camera moved, the values did not: nothing is built.
        assert_eq!(get(&[0.5, 1.0], 'c'), ('c', 1));
        // One variable moved by the smallest step a float takes.
        assert_eq!(get(&[0.5, f32::from_bits(1.0f32.to_bits() + 1)], 'c'), ('c', 2));
        assert_eq!(get(&[0.5, 1.0], 'c'), ('c', 3));
        // The same values, cast on the other side.
        assert_eq!(get(&[0.5, 1.0], 'g'), ('g', 4));
        assert_eq!(get(&[0.5, 1.0], 'g'), ('g', 4));
    }

    #[test]
    fn a_failed_build_keeps_nothing_for_its_values() {
        let mut built = BuiltForValues::new();
        assert_eq!(*built.get_or_build(&[1.0], |_| true, |_| Ok(1)).unwrap(), 1);
        assert!(built.get_or_build(&[2.0], |_| true, |_| Err(Error::Internal("no GPU".into()))).is_err());
        // The next frame at those values builds again instead of using the old geometry.
        assert_eq!(*built.get_or_build(&[2.0], |_| true, |_| Ok(2)).unwrap(), 2);
        built.clear();
        assert_eq!(*built.get_or_build(&[2.0], |_| true, |_| Ok(3)).unwrap(), 3);
    }

    #[test]
    fn a_rebuild_is_handed_what_was_built_before() {
        let mut built = BuiltForValues::new();
        assert_eq!(*built.get_or_build(&[1.0], |_| true, |previous| Ok(previous.unwrap_or(0) + 1)).unwrap(), 1);
        assert_eq!(*built.get_or_build(&[2.0], |_| true, |previous| Ok(previous.unwrap_or(0) + 1)).unwrap(), 2);
        built.clear();
        assert_eq!(*built.get_or_build(&[2.0], |_| true, |previous| Ok(previous.unwrap_or(0) + 1)).unwrap(), 1);
    }
}
