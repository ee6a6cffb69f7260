//! The page's side of the module (wasm32 only): the site's scene and GlassNet on the browser's
//! WebGPU device, drawn into the page's canvas. The frame is `glassbake render`'s, through the
//! same `FramePipeline` (rasterizer, light coverage, through pass on the GPU, GlassNet): the
//! rasterizer writes every buffer into the network's input tensors on the one device, the
//! network's image goes into a texture (`raster::display`) copied onto the canvas, and nothing
//! is read back. The page's JavaScript (`page/glassbake.js`) fetches the files and drives it.

use std::collections::BTreeMap;

use glassbake_core::{Error, Result};
use glassbake_net::TrainedModel;
use glassbake_raster::display::{DisplayTexture, DISPLAY_FORMAT};
use glassbake_raster::{wgpu, RasterizerOptions};
use glassbake_realtime::gpu_handover::{register_shared, with_buffer};
use glassbake_realtime::orbit::Orbit;
use glassbake_realtime::{FramePipeline, ThroughRays};
use glassbake_scene::Scene;
use wasm_bindgen::prelude::*;

use crate::site::{SceneSource, SiteManifest};

/// A value wasm-bindgen's single thread may hand to wgpu callbacks that ask for `Send`: on
/// wasm32-unknown-unknown without atomics no second thread exists to receive it.
struct OnThisThread<T>(T);
// SAFETY: this module is built for wasm32-unknown-unknown without threads (one thread only).
unsafe impl<T> Send for OnThisThread<T> {}

fn js_error(e: Error) -> JsValue {
    JsValue::from_str(&e.to_string())
}

/// A baked scene drawn into one canvas.
#[wasm_bindgen]
pub struct Viewer {
    site: SiteManifest,
    pipeline: FramePipeline,
    display: DisplayTexture,
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
}

#[wasm_bindgen]
impl Viewer {
    /// Opens the site on `canvas` from the files the page fetched: `site.json`'s text, the
    /// model's `config.json` text and weights, and the scene's files (`scene_names[i]` holds
    /// `scene_files[i]`, each a `Uint8Array`; none for a built-in scene).
    pub async fn open(
        canvas: web_sys::HtmlCanvasElement,
        site: String,
        model_config: String,
        weights: Vec<u8>,
        scene_names: Vec<String>,
        scene_files: Vec<js_sys::Uint8Array>,
    ) -> std::result::Result<Viewer, JsValue> {
        let site = SiteManifest::parse(&site).map_err(js_error)?;
        let files: BTreeMap<String, Vec<u8>> = scene_names.into_iter().zip(scene_files.iter().map(|f| f.to_vec())).collect();
        Self::open_site(canvas, site, &model_config, weights, files).await.map_err(js_error)
    }

    async fn open_site(
        canvas: web_sys::HtmlCanvasElement,
        site: SiteManifest,
        model_config: &str,
        weights: Vec<u8>,
        files: BTreeMap<String, Vec<u8>>,
    ) -> Result<Viewer> {
        let side = site.resolution;
        canvas.set_width(side);
        canvas.set_height(side);
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::BROWSER_WEBGPU,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let surface =
            instance.create_surface(wgpu::SurfaceTarget::Canvas(canvas)).map_err(|e| Error::Internal(format!("drawing into the canvas with WebGPU: {e}")))?;
        let (adapter, device, queue) = glassbake_raster::device::open_for_surface(&instance, &surface).await?;
        surface.configure(
            &device,
            &wgpu::SurfaceConfiguration {
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_DST,
                format: DISPLAY_FORMAT,
                width: side,
                height: side,
                present_mode: wgpu::PresentMode::Fifo,
                desired_maximum_frame_latency: 2,
                alpha_mode: wgpu::CompositeAlphaMode::Opaque,
                view_formats: vec![],
                color_space: wgpu::SurfaceColorSpace::Auto,
            },
        );
        let options = RasterizerOptions { all_adapter_features: true, ..Default::default() };
        let shared = register_shared(instance, adapter, device.clone(), queue.clone(), options)?;
        let model = TrainedModel::from_bytes(model_config, weights, "model", &shared.device)?;
        let scene = site_scene(&site, &files)?;
        // The export checked the scene's content hash against the model's on the machine that
        // trained it. The browser's maths library rounds some functions (the shapes' sines,
        // the textures' sRGB decoding) in the last bit otherwise, so the hash is not recomputed
        // here; what the network's inputs depend on is checked instead.
        let config = model.config();
        if (scene.variables.len(), scene.transparent_count()) != (config.variables, config.transparent_objects) {
            return Err(Error::bad_input(
                "site.json",
                "scene",
                format!(
                    "has {} variables and {} transparent objects; the model was trained on {} and {}",
                    scene.variables.len(),
                    scene.transparent_count(),
                    config.variables,
                    config.transparent_objects
                ),
            ));
        }
        let mut pipeline = FramePipeline::with_rasterizer(scene, model, None, None, shared.rasterizer, true)?;
        // Cast on the CPU, the through rays would have to be read back, which a page cannot
        // wait for.
        pipeline.set_through_rays(ThroughRays::Gpu);
        let display = DisplayTexture::new(&device, &queue);
        Ok(Viewer { site, pipeline, display, surface, device, queue })
    }

    /// Draws the frame of the orbit (degrees and scene units, brought into the trained views)
    /// and the variables' `values` (each brought into its range) onto the canvas.
    pub fn render(&mut self, azimuth: f32, elevation: f32, distance: f32, values: Vec<f32>) -> std::result::Result<(), JsValue> {
        self.draw(Orbit { target: self.site.orbit.target, distance, azimuth, elevation }, &values).map_err(js_error)
    }

    fn draw(&mut self, orbit: Orbit, values: &[f32]) -> Result<()> {
        let camera = self.site.camera_at(orbit);
        let values = self.site.values(values);
        let side = self.site.resolution;
        let (image, _) = self.pipeline.render_on_device(&camera, &values, side, side, false)?;
        with_buffer(&image, |buffer, offset| self.display.show(buffer, offset, side, side))?;
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame) | wgpu::CurrentSurfaceTexture::Suboptimal(frame) => frame,
            other => return Err(Error::Internal(format!("the canvas gave no texture to draw into: {other:?}"))),
        };
        let shown = self.display.texture().expect("written above");
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("canvas") });
        encoder.copy_texture_to_texture(shown.as_image_copy(), frame.texture.as_image_copy(), shown.size());
        self.queue.submit([encoder.finish()]);
        self.queue.present(frame);
        Ok(())
    }

    /// Resolves once the GPU has finished every frame drawn so far.
    pub fn finished(&self) -> js_sys::Promise {
        let queue = self.queue.clone();
        js_sys::Promise::new(&mut |resolve, _reject| {
            let resolve = OnThisThread(resolve);
            queue.on_submitted_work_done(move || {
                let resolve = resolve;
                let _ = resolve.0.call0(&JsValue::NULL);
            });
        })
    }

    /// The last frame's pixels as the canvas shows them (RGBA, 8 bits, sRGB-encoded, rows from
    /// the top), read back from the GPU: for tests and screenshots.
    pub fn pixels(&self) -> js_sys::Promise {
        let shown = self.display.texture().cloned();
        let (device, queue) = (self.device.clone(), self.queue.clone());
        js_sys::Promise::new(&mut |resolve, reject| {
            let Some(texture) = &shown else {
                let _ = reject.call1(&JsValue::NULL, &JsValue::from_str("no frame has been drawn yet"));
                return;
            };
            let (width, height) = (texture.width(), texture.height());
            let row = (4 * width).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("canvas pixels"),
                size: (row * height) as u64,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("canvas pixels") });
            encoder.copy_texture_to_buffer(
                texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: None },
                },
                texture.size(),
            );
            queue.submit([encoder.finish()]);
            let mapped = buffer.clone();
            let (resolve, reject) = (resolve.clone(), reject.clone());
            buffer.map_async(wgpu::MapMode::Read, .., move |result| {
                if let Err(e) = result {
                    let _ = reject.call1(&JsValue::NULL, &JsValue::from_str(&format!("reading the frame back: {e}")));
                    return;
                }
                let view = match mapped.get_mapped_range(..) {
                    Ok(view) => view,
                    Err(e) => {
                        let _ = reject.call1(&JsValue::NULL, &JsValue::from_str(&format!("reading the frame back: {e}")));
                        return;
                    }
                };
                let mut pixels = Vec::with_capacity((4 * width * height) as usize);
                for y in 0..height as usize {
                    let start = y * row as usize;
                    pixels.extend_from_slice(&view[start..start + 4 * width as usize]);
                }
                drop(view);
                mapped.unmap();
                let _ = resolve.call1(&JsValue::NULL, &js_sys::Uint8Array::from(pixels.as_slice()));
            });
        })
    }

    /// The adapter the frame runs on, as the browser names it.
    pub fn adapter(&self) -> String {
        self.pipeline.adapter_name()
    }
}

/// The site's scene: a built-in one by name, or loaded from the files the page fetched.
fn site_scene(site: &SiteManifest, files: &BTreeMap<String, Vec<u8>>) -> Result<Scene> {
    match &site.scene {
        SceneSource::Builtin { name } => {
            glassbake_scene::builtin::builtin(name).ok_or_else(|| Error::bad_input("site.json", "scene.name", format!("{name:?} is not a built-in scene")))
        }
        SceneSource::Files { entry, .. } => glassbake_scene::load::load_scene_from_memory(entry, files),
    }
}

/// Whether this browser offers WebGPU at all (`navigator.gpu`), for the page's message.
#[wasm_bindgen]
pub fn has_webgpu() -> bool {
    let Some(window) = web_sys::window() else { return false };
    js_sys::Reflect::get(&window.navigator(), &JsValue::from_str("gpu")).is_ok_and(|gpu| !gpu.is_undefined() && !gpu.is_null())
}

#[wasm_bindgen(start)]
fn start() {
    // As an Error, whose stack the console shows with the module's function names.
    std::panic::set_hook(Box::new(|info| web_sys::console::error_1(&js_sys::Error::new(&format!("glassbake: {info}")).into())));
}
