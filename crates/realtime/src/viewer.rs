//! The interactive viewer: an eframe window (egui on wgpu/winit, X11) showing the pipeline's
//! frames, with an orbit camera (drag to turn, scroll to zoom), a slider per scene variable, a
//! resolution slider, a choice between GlassNet, the naive baseline and any single buffer
//! attribute, and the frame rate.
//!
//! When the network runs on the rasterizer's wgpu device (`--device wgpu`), the window is
//! drawn on that device too, and the network's image goes from its output tensor into a
//! texture the window samples (`raster::display`) without being read back; buffer views and
//! the other devices read the image back and upload it.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use eframe::egui;
use glassbake_core::color::linear_to_srgb;
use glassbake_core::layout::{GROUND_TRUTH_CHANNELS, OPAQUE_ATTRIBUTES, TRANSPARENT_ATTRIBUTES};
use glassbake_core::{Camera, Error, PlanarImage, Result};

use glassbake_raster::display::DisplayTexture;

use crate::orbit::Orbit;
use crate::pipeline::{FramePipeline, FrameTimes, Output};

pub struct ViewerOptions {
    /// Starting frame resolution (square).
    pub resolution: u32,
    /// Save a screenshot of the whole window here after `screenshot_after` frames, then quit
    /// (for tests and docs under Xvfb).
    pub screenshot: Option<PathBuf>,
    pub screenshot_after: usize,
    pub title: String,
}

/// Fails with a clear message when there is no display to open a window on.
pub fn check_display() -> Result<()> {
    let has = |v: &str| std::env::var_os(v).is_some_and(|s| !s.is_empty());
    if !has("DISPLAY") {
        return Err(Error::bad_input(
            "glassbake view",
            "display",
            if has("WAYLAND_DISPLAY") {
                "only a Wayland display is set; the viewer needs X11 (DISPLAY), e.g. XWayland".to_string()
            } else {
                "no display (DISPLAY is not set): run it on a desktop, over `ssh -X`, or headless under `xvfb-run -s '-screen 0 1280x800x24' glassbake view ...`".to_string()
            },
        ));
    }
    Ok(())
}

/// Everything the output menu offers.
fn output_choices(pipeline: &FramePipeline) -> Vec<(String, Output)> {
    let mut choices = vec![("GlassNet".to_string(), Output::GlassNet)];
    if pipeline.naive.is_some() {
        choices.push(("naive baseline".into(), Output::Naive));
    }
    for layer in ["opaque", "naive"] {
        for a in OPAQUE_ATTRIBUTES {
            choices.push((format!("{layer} buffer: {}", a.name), Output::Buffer { layer: layer.into(), attribute: a.name.into() }));
        }
    }
    for k in 0..pipeline.scene.transparent_count() {
        for a in TRANSPARENT_ATTRIBUTES {
            choices.push((format!("transparency buffer {k}: {}", a.name), Output::Buffer { layer: format!("transparent.{k}"), attribute: a.name.into() }));
        }
    }
    choices
}

fn color_image(image: &PlanarImage) -> egui::ColorImage {
    let planes: Vec<&[f32]> = GROUND_TRUTH_CHANNELS.iter().map(|c| image.plane_by_name(c).expect("RGB frame")).collect();
    let bytes: Vec<u8> = (0..image.pixel_count()).flat_map(|i| planes.iter().map(move |p| (linear_to_srgb(p[i]) * 255.0 + 0.5) as u8)).collect();
    egui::ColorImage::from_rgb([image.width() as usize, image.height() as usize], &bytes)
}

struct Viewer {
    pipeline: FramePipeline,
    template: Camera,
    orbit: Orbit,
    values: Vec<f32>,
    choices: Vec<(String, Output)>,
    choice: usize,
    resolution: u32,
    size_multiple: u32,
    texture: Option<egui::TextureHandle>,
    /// The image written on the GPU, when the network shares the window's device.
    on_device: Option<OnDevice>,
    /// Which of the two textures the last frame wrote.
    shown: Shown,
    /// Exponential moving average of the time between frames, ms.
    frame_ms: Option<f64>,
    last_frame_at: Option<Instant>,
    last: FrameTimes,
    error: Option<String>,
    frames: usize,
    screenshot: Option<PathBuf>,
    screenshot_after: usize,
    screenshot_requested: bool,
    screenshot_result: Arc<Mutex<Option<std::result::Result<PathBuf, String>>>>,
}

/// The display pass and the texture id the window's renderer knows it by.
struct OnDevice {
    display: DisplayTexture,
    id: Option<egui::TextureId>,
}

#[derive(Clone, Copy, PartialEq)]
enum Shown {
    Nothing,
    Uploaded,
    OnDevice,
}

impl Viewer {
    fn render(&mut self, ctx: &egui::Context, frame: &eframe::Frame) {
        let camera = self.orbit.camera(&self.template);
        let output = self.choices[self.choice].1.clone();
        let rendered = match (&mut self.on_device, &output, frame.wgpu_render_state()) {
            (Some(on_device), Output::GlassNet | Output::Naive, Some(state)) => {
                Self::render_on_device(&mut self.pipeline, on_device, state, &camera, &self.values, self.resolution, output == Output::Naive)
                    .inspect(|_| self.shown = Shown::OnDevice)
            }
            _ => self.pipeline.render(&camera, &self.values, self.resolution, self.resolution, &output).map(|(image, times)| {
                let picture = color_image(&image);
                match &mut self.texture {
                    Some(t) => t.set(picture, egui::TextureOptions::NEAREST),
                    None => self.texture = Some(ctx.load_texture("frame", picture, egui::TextureOptions::NEAREST)),
                }
                self.shown = Shown::Uploaded;
                times
            }),
        };
        match rendered {
            Ok(times) => {
                // The time between frames: with the image left on the GPU, a frame's own
                // times end when its work is submitted.
                let now = Instant::now();
                if let Some(before) = self.last_frame_at.replace(now) {
                    let interval = (now - before).as_secs_f64() * 1e3;
                    self.frame_ms = Some(self.frame_ms.map_or(interval, |m| 0.9 * m + 0.1 * interval));
                }
                self.last = times;
                self.error = None;
                self.frames += 1;
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// The frame into the display texture on the shared device; the window's renderer is
    /// told of the texture when it was made anew.
    fn render_on_device(
        pipeline: &mut FramePipeline,
        on_device: &mut OnDevice,
        state: &eframe::egui_wgpu::RenderState,
        camera: &Camera,
        values: &[f32],
        resolution: u32,
        naive: bool,
    ) -> Result<FrameTimes> {
        let (image, times) = pipeline.render_on_device(camera, values, resolution, resolution, naive)?;
        let display = &mut on_device.display;
        let remade = crate::gpu_handover::with_buffer(&image, |buffer, offset| display.show(buffer, offset, resolution, resolution))?;
        if remade || on_device.id.is_none() {
            let view = display.view().expect("written above");
            let mut renderer = state.renderer.write();
            on_device.id = Some(match on_device.id {
                Some(id) => {
                    renderer.update_egui_texture_from_wgpu_texture(&state.device, view, eframe::wgpu::FilterMode::Nearest, id);
                    id
                }
                None => renderer.register_native_texture(&state.device, view, eframe::wgpu::FilterMode::Nearest),
            });
        }
        Ok(times)
    }

    /// The texture the last frame wrote.
    fn frame_texture(&self) -> Option<egui::TextureId> {
        match self.shown {
            Shown::Nothing => None,
            Shown::Uploaded => self.texture.as_ref().map(|t| t.id()),
            Shown::OnDevice => self.on_device.as_ref().and_then(|d| d.id),
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("glassbake");
        match self.frame_ms {
            Some(ms) => {
                let t = &self.last;
                ui.label(format!(
                    "{:.1} FPS ({ms:.1} ms/frame)\nraster {:.1} ms, through rays {:.1} ms, network {:.1} ms",
                    1000.0 / ms,
                    t.raster_ms,
                    t.through_ms,
                    t.network_ms
                ))
            }
            None => ui.label("first frame..."),
        };
        ui.separator();
        egui::ComboBox::from_label("output").selected_text(self.choices[self.choice].0.clone()).show_ui(ui, |ui| {
            for (i, (label, _)) in self.choices.iter().enumerate() {
                ui.selectable_value(&mut self.choice, i, label);
            }
        });
        let m = self.size_multiple;
        let mut steps = self.resolution / m;
        ui.add(egui::Slider::new(&mut steps, (32 / m).max(1)..=(1024 / m)).text("resolution").custom_formatter(move |v, _| format!("{} px", v as u32 * m)));
        self.resolution = steps * m;
        ui.separator();
        ui.label("camera (drag the image to orbit, scroll to zoom)");
        ui.add(egui::Slider::new(&mut self.orbit.azimuth, -180.0..=180.0).text("azimuth"));
        ui.add(egui::Slider::new(&mut self.orbit.elevation, -85.0..=85.0).text("elevation"));
        let far = (self.orbit.distance * 2.0).max(10.0);
        ui.add(egui::Slider::new(&mut self.orbit.distance, 0.1..=far).text("distance"));
        ui.separator();
        ui.label("scene variables");
        for (variable, value) in self.pipeline.scene.variables.iter().zip(self.values.iter_mut()) {
            ui.add(egui::Slider::new(value, variable.min..=variable.max).text(&variable.name));
        }
        if let Some(error) = &self.error {
            ui.separator();
            ui.colored_label(egui::Color32::RED, error);
        }
    }
}

impl eframe::App for Viewer {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.render(&ctx, frame);
        egui::Panel::left("controls").show(ui, |ui| self.controls(ui));
        egui::CentralPanel::default_margins().show(ui, |ui| {
            if let Some(texture) = self.frame_texture() {
                let available = ui.available_size();
                let side = available.x.min(available.y).max(64.0);
                let response =
                    ui.add(egui::Image::from_texture(egui::load::SizedTexture::new(texture, egui::vec2(side, side))).sense(egui::Sense::click_and_drag()));
                if response.dragged() {
                    let d = response.drag_delta();
                    self.orbit.azimuth = (self.orbit.azimuth - 0.4 * d.x + 540.0).rem_euclid(360.0) - 180.0;
                    self.orbit.elevation = (self.orbit.elevation + 0.4 * d.y).clamp(-85.0, 85.0);
                }
                if response.hovered() {
                    let scroll = ui.input(|i| i.smooth_scroll_delta.y);
                    self.orbit.distance = (self.orbit.distance * (-0.002 * scroll).exp()).max(0.05);
                }
            }
        });
        if let Some(path) = self.screenshot.clone() {
            if !self.screenshot_requested && self.frames >= self.screenshot_after {
                self.screenshot_requested = true;
                let result = self.screenshot_result.clone();
                let request_ctx = ctx.clone();
                ctx.request_screenshot(move |image| {
                    let saved = eframe_image_png(&image, &path).map(|()| path.clone());
                    *result.lock().expect("screenshot result") = Some(saved);
                    request_ctx.request_repaint();
                });
            }
            if self.screenshot_result.lock().expect("screenshot result").is_some() {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
        ctx.request_repaint();
    }
}

fn eframe_image_png(image: &egui::ColorImage, path: &std::path::Path) -> std::result::Result<(), String> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| [c.r(), c.g(), c.b()]).collect();
    let buffer = image::RgbImage::from_raw(w as u32, h as u32, bytes).ok_or("screenshot size")?;
    let mut png = Vec::new();
    buffer.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).map_err(|e| e.to_string())?;
    glassbake_core::image::write_bytes_atomically(path, &png).map_err(|e| e.to_string())
}

/// Opens the window and runs until it is closed (or the screenshot is taken).
pub fn run_viewer(pipeline: FramePipeline, options: ViewerOptions) -> Result<Option<PathBuf>> {
    check_display()?;
    let template = pipeline.scene.camera.middle();
    let values = pipeline.scene.default_values();
    let choices = output_choices(&pipeline);
    let size_multiple = (pipeline.glassnet.config().size_multiple() as u32) * if pipeline.super_sampler.is_some() { 2 } else { 1 };
    let resolution = (options.resolution / size_multiple).max(1) * size_multiple;
    let result = Arc::new(Mutex::new(None));
    // With the network on the rasterizer's device, the window is drawn on it too, so that
    // the network's image can be sampled where it is.
    let shared = pipeline.zero_copy().then(|| pipeline.wgpu_handles());
    let on_device = shared.as_ref().map(|(_, _, device, queue)| OnDevice { display: DisplayTexture::new(device, queue), id: None });
    let viewer = Viewer {
        orbit: Orbit::from_camera(&template),
        template,
        values,
        choices,
        choice: 0,
        resolution,
        size_multiple,
        texture: None,
        on_device,
        shown: Shown::Nothing,
        frame_ms: None,
        last_frame_at: None,
        last: Default::default(),
        error: None,
        frames: 0,
        screenshot: options.screenshot.clone(),
        screenshot_after: options.screenshot_after,
        screenshot_requested: false,
        screenshot_result: result.clone(),
        pipeline,
    };
    let mut native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1100.0, 760.0]).with_title(options.title.clone()),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    if let Some((instance, adapter, device, queue)) = shared {
        native.wgpu_options.wgpu_setup = eframe::egui_wgpu::WgpuSetup::Existing(eframe::egui_wgpu::WgpuSetupExisting { instance, adapter, device, queue });
    }
    eframe::run_native(&options.title, native, Box::new(|_| Ok(Box::new(viewer)))).map_err(|e| Error::Internal(format!("the viewer window: {e}")))?;
    let outcome = result.lock().expect("screenshot result").take();
    match outcome {
        Some(Ok(path)) => Ok(Some(path)),
        Some(Err(e)) => Err(Error::Internal(format!("saving the screenshot: {e}"))),
        None if options.screenshot.is_some() => Err(Error::Internal("the window closed before the screenshot was taken".into())),
        None => Ok(None),
    }
}
