//! Picking a Vulkan adapter and opening a device on it (docs/design.md §3: pin the Vulkan backend,
//! request the adapter's own limits, choose by power preference or `WGPU_ADAPTER_NAME`).

use glassbake_core::{Error, Result};

/// Colour bytes per sample the G-buffer pass writes: 5 Rgba32Float targets.
pub(crate) const GBUFFER_TARGETS: u32 = 5;
const REQUIRED_COLOR_BYTES: u32 = GBUFFER_TARGETS * 16;

/// Which adapter to prefer when several are usable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PowerPreference {
    /// Discrete GPU first, then integrated, virtual, and the CPU (lavapipe) last.
    #[default]
    HighPerformance,
    /// Integrated GPU first, then discrete, virtual, CPU.
    LowPower,
}

/// How a [`crate::Rasterizer`] is created.
#[derive(Clone, Debug)]
pub struct RasterizerOptions {
    pub power_preference: PowerPreference,
    /// Pick the first adapter whose name contains this (case-insensitive). `None` reads the
    /// `WGPU_ADAPTER_NAME` environment variable; if that is unset too, the power preference
    /// decides.
    pub adapter_name: Option<String>,
    /// Side of each face of a rectangle light's shadow hemicube (5 faces per emitting side), in texels.
    pub shadow_map_size: u32,
    /// Shadow the rectangle lights' direct light (L_d) with shadow maps.
    pub shadows: bool,
    /// Draw rectangle lights' own quads into the opaque and naive G-buffers (they show their
    /// radiance in L_d, as the path tracer sees them).
    pub draw_lights: bool,
    /// Open the device with every feature the adapter offers (mappable primary buffers
    /// excepted), as burn's wgpu backend expects of a device it is given to share.
    pub all_adapter_features: bool,
}

impl Default for RasterizerOptions {
    fn default() -> Self {
        RasterizerOptions {
            power_preference: PowerPreference::HighPerformance,
            adapter_name: None,
            shadow_map_size: 512,
            shadows: true,
            draw_lights: true,
            all_adapter_features: false,
        }
    }
}

pub(crate) const NO_ADAPTER_HELP: &str = "no usable Vulkan adapter found (glassbake-raster needs Vulkan with 5 Rgba32Float \
     render targets); on a machine without a GPU install Mesa's software driver lavapipe: \
     `apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1`";

fn rank(device_type: wgpu::DeviceType, preference: PowerPreference) -> u32 {
    use wgpu::DeviceType::*;
    match (preference, device_type) {
        (PowerPreference::HighPerformance, DiscreteGpu) => 0,
        (PowerPreference::HighPerformance, IntegratedGpu) => 1,
        (PowerPreference::LowPower, IntegratedGpu) => 0,
        (PowerPreference::LowPower, DiscreteGpu) => 1,
        (_, VirtualGpu) => 2,
        (_, Other) => 3,
        (_, Cpu) => 4,
    }
}

/// Whether a device opened with these limits can run the G-buffer pass.
pub(crate) fn limits_suffice(limits: &wgpu::Limits) -> bool {
    limits.max_color_attachments >= GBUFFER_TARGETS && limits.max_color_attachment_bytes_per_sample >= REQUIRED_COLOR_BYTES
}

fn usable(adapter: &wgpu::Adapter) -> bool {
    let limits = adapter.limits();
    let format = adapter.get_texture_format_features(wgpu::TextureFormat::Rgba32Float);
    limits.max_color_attachments >= GBUFFER_TARGETS
        && limits.max_color_attachment_bytes_per_sample >= REQUIRED_COLOR_BYTES
        && format.allowed_usages.contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
}

/// The adapter features a device shared with burn asks for: all of them except mappable primary
/// buffers (slow device-local mapping) and wgpu's experimental features, which a device may only
/// request with an unsafe opt-in (NVIDIA drivers offer mesh shaders, cooperative matrices and
/// ray-tracing pipelines; asking for them fails the whole request).
fn shareable_features(adapter_features: wgpu::Features) -> wgpu::Features {
    adapter_features - wgpu::Features::MAPPABLE_PRIMARY_BUFFERS - wgpu::Features::all_experimental_mask()
}

/// Opens the Vulkan device the options choose: (instance, adapter, device, queue).
pub fn open(options: &RasterizerOptions) -> Result<(wgpu::Instance, wgpu::Adapter, wgpu::Device, wgpu::Queue)> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor { backends: wgpu::Backends::VULKAN, ..wgpu::InstanceDescriptor::new_without_display_handle() });
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
    let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
    if names.is_empty() {
        return Err(Error::Internal(format!("{NO_ADAPTER_HELP} (no Vulkan adapter found)")));
    }
    let mut candidates: Vec<wgpu::Adapter> = adapters.into_iter().filter(usable).collect();
    let wanted = options.adapter_name.clone().or_else(|| std::env::var("WGPU_ADAPTER_NAME").ok());
    if let Some(wanted) = wanted.filter(|w| !w.trim().is_empty()) {
        let w = wanted.to_lowercase();
        candidates.retain(|a| a.get_info().name.to_lowercase().contains(&w));
        if candidates.is_empty() {
            return Err(Error::Internal(format!(
                "no usable Vulkan adapter named like {wanted:?} (WGPU_ADAPTER_NAME / adapter_name); found: [{}]",
                names.join(", ")
            )));
        }
    }
    candidates.sort_by_key(|a| rank(a.get_info().device_type, options.power_preference));
    let adapter = candidates.into_iter().next().ok_or_else(|| Error::Internal(format!("{NO_ADAPTER_HELP} (Vulkan adapters found: {})", names.join(", "))))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("glassbake-raster"),
        required_features: if options.all_adapter_features { shareable_features(adapter.features()) } else { wgpu::Features::empty() },
        required_limits: adapter.limits(),
        ..Default::default()
    }))
    .map_err(|e| Error::Internal(format!("opening the Vulkan device {:?}: {e}", adapter.get_info().name)))?;
    Ok((instance, adapter, device, queue))
}

/// Opens a device on the adapter `instance` offers for `surface` (a browser's WebGPU, which
/// offers one and answers asynchronously), as [`open`] does with `all_adapter_features`: what
/// the rasterizer and burn's runtime sharing it need. Refused where the adapter cannot draw
/// the G-buffer.
pub async fn open_for_surface(instance: &wgpu::Instance, surface: &wgpu::Surface<'_>) -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue)> {
    let adapter = instance
        .request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: Some(surface),
            ..Default::default()
        })
        .await
        .map_err(|e| Error::Internal(format!("no WebGPU adapter: {e}")))?;
    if !usable(&adapter) {
        let limits = adapter.limits();
        return Err(Error::Internal(format!(
            "the adapter {:?} allows {} colour targets / {} colour bytes per sample of Rgba32Float; the G-buffer needs {GBUFFER_TARGETS} / {REQUIRED_COLOR_BYTES}",
            adapter.get_info().name,
            limits.max_color_attachments,
            limits.max_color_attachment_bytes_per_sample
        )));
    }
    let (device, queue) = adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("glassbake-raster"),
            required_features: shareable_features(adapter.features()),
            required_limits: adapter.limits(),
            ..Default::default()
        })
        .await
        .map_err(|e| Error::Internal(format!("opening the WebGPU device: {e}")))?;
    Ok((adapter, device, queue))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shared_device_never_asks_for_experimental_features() {
        let asked = shareable_features(wgpu::Features::all());
        assert!(!asked.intersects(wgpu::Features::all_experimental_mask()), "{asked:?}");
        assert!(!asked.contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS));
        assert!(asked.contains(wgpu::Features::SHADER_F16 | wgpu::Features::SUBGROUP | wgpu::Features::TIMESTAMP_QUERY));
    }

    #[test]
    fn preference_ranks_gpus_before_the_cpu() {
        use wgpu::DeviceType::*;
        let order = |p| {
            let mut types = vec![Cpu, Other, VirtualGpu, IntegratedGpu, DiscreteGpu];
            types.sort_by_key(|&t| rank(t, p));
            types
        };
        assert_eq!(order(PowerPreference::HighPerformance), vec![DiscreteGpu, IntegratedGpu, VirtualGpu, Other, Cpu]);
        assert_eq!(order(PowerPreference::LowPower), vec![IntegratedGpu, DiscreteGpu, VirtualGpu, Other, Cpu]);
    }

    #[test]
    fn missing_adapters_are_reported_with_the_package_to_install() {
        assert!(NO_ADAPTER_HELP.contains("mesa-vulkan-drivers"));
        let options = RasterizerOptions { adapter_name: Some("no adapter is called this".into()), ..Default::default() };
        let err = match open(&options) {
            Ok(_) => panic!("an adapter matched a name no adapter has"),
            Err(e) => e.to_string(),
        };
        assert!(err.contains("no adapter is called this"), "{err}");
    }
}
