//! Network and training configuration: every width, depth and frequency in one serde struct.
//! The named sizes a user picks (`tiny`, `quick`, `paper`) are values of the bake's `Preset`
//! (glassbake-bake); a [`NetShape`] is the part of one that does not depend on the scene.

use serde::{Deserialize, Serialize};

use glassbake_core::{layout, Error, Result};

/// Which network the same F+B+R skeleton becomes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// The paper's model: opaque G-buffer + one transparency buffer per object, summed by T.
    Glassnet,
    /// Baseline: one ordinary G-buffer in which glass overwrites what is behind it; no T.
    Naive,
    /// Baseline: all transparency buffers concatenated in a fixed order (order-dependent,
    /// memory grows with the number of objects).
    Concat,
    /// Baseline after Active Exploration's PixelGenerator (Diolatzis et al. 2022): a per-pixel
    /// MLP on the naive G-buffer, no convolution across pixels, no F/B/R.
    Pixelgen,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Glassnet => "glassnet",
            ModelKind::Naive => "naive",
            ModelKind::Concat => "concat",
            ModelKind::Pixelgen => "pixelgen",
        }
    }

    pub const ALL: [ModelKind; 4] = [ModelKind::Glassnet, ModelKind::Naive, ModelKind::Concat, ModelKind::Pixelgen];

    /// Whether the network reads transparency buffers (GlassNet and the concat baseline).
    pub fn reads_transparency_buffers(self) -> bool {
        matches!(self, ModelKind::Glassnet | ModelKind::Concat)
    }

    pub fn parse(name: &str) -> Option<ModelKind> {
        match name {
            "glassnet" => Some(ModelKind::Glassnet),
            "naive" => Some(ModelKind::Naive),
            "concat" => Some(ModelKind::Concat),
            "pixelgen" => Some(ModelKind::Pixelgen),
            _ => None,
        }
    }
}

/// A U-Net: `levels` resolutions, `base_width` channels at the top doubling per level, two
/// convolutions per level (3x3; the very first 1x1, projecting the encoded input), strided-convolution down-sampling and transposed-convolution
/// up-sampling (bilinear up-sampling has no backward pass on burn's GPU backends).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UNetConfig {
    pub base_width: usize,
    pub levels: usize,
    pub out_channels: usize,
}

/// A plain CNN at full resolution: `layers` convolutions of `width` channels (the first 1x1,
/// projecting the encoded input; the rest 3x3), then a 1x1 convolution to `out_channels`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CnnConfig {
    pub width: usize,
    pub layers: usize,
    pub out_channels: usize,
}

/// The rendering network R (paper 3.4): no down-sampling, one larger kernel for blur-like
/// global effects, 3x3 layers, and 1x1 convolutions at the end to keep shapes sharp.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RendererConfig {
    pub width: usize,
    /// Side of the first, larger kernel (odd).
    pub large_kernel: usize,
    /// 3x3 layers after the large one.
    pub layers: usize,
    /// 1x1 layers before the final 1x1 projection to RGB.
    pub pointwise_layers: usize,
}

/// Active Exploration's PixelGenerator: `layers` 1x1 convolutions of `width` channels (a
/// per-pixel MLP), the encoded input concatenated again to the input of layer `skip_at`
/// (as NeRF's MLP does), then a 1x1 projection to RGB.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PixelGeneratorConfig {
    pub width: usize,
    pub layers: usize,
    pub skip_at: usize,
}

/// What one of R's output terms multiplies its predicted light by ([`NetConfig::term_modulator`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Modulator {
    /// The opaque G-buffer's albedo.
    GbufferAlbedo,
    /// The through buffers' albedo, summed over the objects.
    ThroughAlbedo,
}

/// The whole GlassNet (and baselines) architecture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetConfig {
    pub model: ModelKind,
    /// The preset this config came from (informative).
    pub preset: String,
    /// NeRF positional encoding: each input channel x becomes x, sin(2^k pi x), cos(2^k pi x)
    /// for k in 0..frequencies. 0 switches the encoding off (the paper's ablation).
    pub encoding_frequencies: usize,
    /// Scene variables, fed to F as constant planes of their normalised values.
    pub variables: usize,
    /// Transparent objects in the scene. GlassNet accepts any number up to
    /// [`MAX_EXACT_OBJECTS`]; `concat` is built for exactly this many.
    pub transparent_objects: usize,
    /// F: opaque G-buffer -> sigma.
    pub scene_encoder: UNetConfig,
    /// h: (transparency buffer, sigma) -> rho_i, summed into tau. For `concat`, the CNN that
    /// reads all buffers at once.
    pub transparency_encoder: CnnConfig,
    /// Whether each object's term h(b_i, sigma) is multiplied by that object's coverage, so an
    /// object adds nothing where it does not cover the pixel, exactly as an object out of view
    /// adds nothing. Without it every in-view object adds h(0, sigma) everywhere, and B has to
    /// learn to ignore a term whose size depends on how many objects happen to be in view
    /// (measured on cornellbox at 1500 steps: no change beyond run-to-run spread; kept for the
    /// consistency). False in configs saved before this existed, so those models render as
    /// they were trained.
    #[serde(default)]
    pub terms_masked_by_coverage: bool,
    /// A multiresolution hash grid of world position (`hash_grid.rs`) that replaces the Fourier
    /// features of the position channels for F (opaque position) and, in GlassNet, for h
    /// (the transparent surface's position, a grid of its own); the other channels keep theirs.
    /// Absent: every channel Fourier-encoded, as in the paper.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_grid: Option<crate::hash_grid::HashGridConfig>,
    /// Whether R predicts, beside each RGB term, the light that multiplies the G-buffer's
    /// albedo (demodulated output, as neural radiance caching and denoisers such as KPCN do),
    /// so printed text and textures come from the G-buffer instead of being learnt. False in
    /// configs saved before this existed, so those models render as they were trained.
    #[serde(default)]
    pub demodulated: bool,
    /// Whether R's two transmitted terms (b1, b2: what the camera sees through the glass)
    /// each predict, beside their RGB, the light that multiplies the through buffers' albedo
    /// (the surface each object's refracted rays reach, averaged over the pixel's footprint
    /// and weighted by their Fresnel transmittance and coverage, summed over the objects), so
    /// text seen through a lens takes its contrast from the through buffer in its refracted
    /// place instead of from the weights. Only for GlassNet reading through buffers
    /// ([`Self::through`]). False in configs saved before this existed.
    #[serde(default)]
    pub through_demodulated: bool,
    /// Whether pixels whose rasterized direct light (seen through the glass in front, for the
    /// models that read transparency buffers) reaches 1 in every channel are drawn as 1, the
    /// tone map's white, whatever the network predicts there: the emitters, whose hard edges
    /// the convolutions otherwise smear into a ring a pixel wide. False in configs saved
    /// before this existed.
    #[serde(default)]
    pub saturate_direct_light: bool,
    /// Whether the image is composited with the G-buffer's light coverage
    /// (`layout::LIGHT_COVERAGE_ATTRIBUTES`): light + (1 - coverage) x the network's image,
    /// the light seen through the glass in front for the models that read transparency
    /// buffers. Where a light covers the whole pixel this is [`Self::saturate_direct_light`]'s
    /// white; at a light's edge it is the share of the pixel the light covers, which a
    /// centre-sampled G-buffer cannot tell and which held 87% of GlassNet's squared error over
    /// the default cornellbox bake's frames (docs/benchmarks.md). Supersedes
    /// `saturate_direct_light` (the two are not both on). False in configs saved before this
    /// existed.
    #[serde(default)]
    pub light_coverage: bool,
    /// Whether h also reads each transparency buffer's through buffer
    /// (`layout::THROUGH_ATTRIBUTES`: what the camera sees through that object, by refracted
    /// rays), and R its albedo and direct light times the Fresnel transmittance, summed over
    /// the objects beside the glass light. For the naive baseline (the `front-through`
    /// ablation of `glassbake train`), F reads beside its G-buffer the through buffer of the
    /// object in front at each pixel: the same input without GlassNet's architecture. False
    /// in configs saved before this existed.
    #[serde(default)]
    pub through: bool,
    /// B: (sigma, tau) -> phi.
    pub blending: UNetConfig,
    /// R: (phi, L_d) -> image.
    pub renderer: RendererConfig,
    /// The `pixelgen` baseline's MLP, which replaces F, T, B and R (their fields above are
    /// then unused).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel_generator: Option<PixelGeneratorConfig>,
}

/// The most transparency buffers GlassNet sums exactly (see `sum.rs`).
pub const MAX_EXACT_OBJECTS: usize = 16;

/// The sizes of a network that do not depend on the scene: what a preset chooses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetShape {
    pub encoding_frequencies: usize,
    pub scene_encoder: UNetConfig,
    pub transparency_encoder: CnnConfig,
    pub blending: UNetConfig,
    pub renderer: RendererConfig,
    /// Used by the `pixelgen` baseline only.
    pub pixel_generator: PixelGeneratorConfig,
}

impl NetShape {
    /// The smallest network every model kind builds: U-Nets of 2 levels, widths of 4. What
    /// tests train and the `tiny` preset bakes.
    pub fn smallest() -> NetShape {
        NetShape {
            encoding_frequencies: 2,
            scene_encoder: UNetConfig { base_width: 4, levels: 2, out_channels: 4 },
            transparency_encoder: CnnConfig { width: 4, layers: 1, out_channels: 4 },
            blending: UNetConfig { base_width: 4, levels: 2, out_channels: 4 },
            renderer: RendererConfig { width: 4, large_kernel: 5, layers: 1, pointwise_layers: 1 },
            pixel_generator: PixelGeneratorConfig { width: 8, layers: 3, skip_at: 2 },
        }
    }
}

impl NetConfig {
    /// `model` of `shape` (a preset's, named `preset_name`) for a scene with `variables`
    /// variables and `transparent_objects` transparent objects.
    pub fn new(shape: &NetShape, preset_name: &str, model: ModelKind, variables: usize, transparent_objects: usize) -> Result<NetConfig> {
        let NetShape { encoding_frequencies, scene_encoder, transparency_encoder, blending, renderer, pixel_generator } = shape.clone();
        let config = NetConfig {
            model,
            preset: preset_name.to_string(),
            encoding_frequencies,
            variables,
            transparent_objects,
            scene_encoder,
            transparency_encoder,
            terms_masked_by_coverage: true,
            position_grid: None,
            // Demodulated lost 0.4 dB against RGB on the default cornellbox bake, with or
            // without the saturation (docs/history/benchmarks-2026-11.md, 2026-11-25).
            demodulated: false,
            through_demodulated: false,
            // The light coverage composite supersedes the saturation (the pixelgen baseline
            // keeps the paper's plain output).
            saturate_direct_light: false,
            light_coverage: model != ModelKind::Pixelgen,
            through: model == ModelKind::Glassnet,
            blending,
            renderer,
            pixel_generator: (model == ModelKind::Pixelgen).then_some(pixel_generator),
        };
        config.check("preset")?;
        Ok(config)
    }

    /// Checks the config is buildable; `origin` names the file or flag it came from.
    pub fn check(&self, origin: &str) -> Result<()> {
        let bad = |field: &str, message: String| Err(Error::bad_input(origin, field, message));
        let (f, h, b, r) = (&self.scene_encoder, &self.transparency_encoder, &self.blending, &self.renderer);
        let mut sizes = vec![
            ("scene_encoder.base_width", f.base_width),
            ("scene_encoder.out_channels", f.out_channels),
            ("transparency_encoder.width", h.width),
            ("transparency_encoder.layers", h.layers),
            ("transparency_encoder.out_channels", h.out_channels),
            ("blending.base_width", b.base_width),
            ("blending.out_channels", b.out_channels),
            ("renderer.width", r.width),
            ("renderer.large_kernel", r.large_kernel),
            ("renderer.layers", r.layers),
            ("renderer.pointwise_layers", r.pointwise_layers),
        ];
        if let Some(p) = &self.pixel_generator {
            sizes.extend([("pixel_generator.width", p.width), ("pixel_generator.layers", p.layers)]);
        }
        check_sizes(origin, &sizes)?;
        for (field, unet) in [("scene_encoder", &self.scene_encoder), ("blending", &self.blending)] {
            if unet.base_width == 0 || unet.out_channels == 0 || !(1..=6).contains(&unet.levels) {
                return bad(field, "base_width and out_channels must be at least 1 and levels in 1..=6".into());
            }
        }
        let h = &self.transparency_encoder;
        if h.width == 0 || h.out_channels == 0 {
            return bad("transparency_encoder", "width and out_channels must be at least 1".into());
        }
        let r = &self.renderer;
        if r.width == 0 || r.large_kernel.is_multiple_of(2) {
            return bad("renderer", "width must be at least 1 and large_kernel odd".into());
        }
        if self.encoding_frequencies > 12 {
            return bad("encoding_frequencies", format!("{} is more than 12 (2^12 pi would alias at any buffer precision)", self.encoding_frequencies));
        }
        if self.model == ModelKind::Glassnet && self.transparent_objects > MAX_EXACT_OBJECTS {
            return bad("transparent_objects", format!("{} transparent objects; GlassNet sums at most {MAX_EXACT_OBJECTS} exactly", self.transparent_objects));
        }
        match (&self.pixel_generator, self.model) {
            (None, ModelKind::Pixelgen) => return bad("pixel_generator", "the pixelgen baseline needs its MLP's widths".into()),
            (Some(_), kind) if kind != ModelKind::Pixelgen => {
                return bad("pixel_generator", format!("only the pixelgen baseline has one, not {}", kind.name()))
            }
            (Some(p), _) if p.width == 0 || p.skip_at == 0 || p.skip_at >= p.layers => {
                return bad("pixel_generator", "width must be at least 1 and skip_at in 1..layers".into())
            }
            _ => {}
        }
        if self.light_coverage && self.saturate_direct_light {
            return bad("light_coverage", "the light coverage composite supersedes saturate_direct_light: switch one off".into());
        }
        if self.light_coverage && self.model == ModelKind::Pixelgen {
            return bad("light_coverage", "the pixelgen baseline keeps the paper's plain output".into());
        }
        if self.through && !matches!(self.model, ModelKind::Glassnet | ModelKind::Naive) {
            return bad("through", format!("only GlassNet and the naive baseline read through buffers, not {}", self.model.name()));
        }
        if let Some(grid) = &self.position_grid {
            if self.model == ModelKind::Pixelgen {
                return bad("position_grid", "the pixelgen baseline keeps the paper's Fourier features".into());
            }
            grid.check(origin)?;
        }
        if self.through_demodulated && !(self.model == ModelKind::Glassnet && self.through) {
            return bad("through_demodulated", "only GlassNet reading through buffers has a through albedo to demodulate by".into());
        }
        if self.model == ModelKind::Concat && self.transparent_objects == 0 {
            return bad("transparent_objects", "the concat baseline needs at least one transparent object".into());
        }
        Ok(())
    }

    /// Input sides must be multiples of this (the U-Nets halve the resolution levels-1 times).
    pub fn size_multiple(&self) -> usize {
        if self.model == ModelKind::Pixelgen {
            return 1;
        }
        1 << (self.scene_encoder.levels.max(self.blending.levels) - 1)
    }

    /// Channels of R's output term `k` (0: direct, 1 and 2: transmitted): RGB, and the RGB
    /// light its albedo multiplies where the term is demodulated ([`Self::term_modulator`]).
    pub fn renderer_term_channels(&self, k: usize) -> usize {
        if self.term_modulator(k).is_some() {
            6
        } else {
            3
        }
    }

    /// The albedo R's output term `k` is demodulated by, if any: the G-buffer's
    /// ([`Self::demodulated`]) or, for the transmitted terms, the through buffers'
    /// ([`Self::through_demodulated`]), which replaces the G-buffer's there.
    pub fn term_modulator(&self, k: usize) -> Option<Modulator> {
        if k > 0 && self.through_demodulated {
            Some(Modulator::ThroughAlbedo)
        } else if self.demodulated {
            Some(Modulator::GbufferAlbedo)
        } else {
            None
        }
    }

    /// R's output terms: one for the models that read no transparency buffer, three (direct,
    /// transmitted, transmitted twice) for those that do.
    pub fn renderer_terms(&self) -> usize {
        if self.model.reads_transparency_buffers() {
            3
        } else {
            1
        }
    }

    /// R's output channels: its terms' one after the other.
    pub fn renderer_outputs(&self) -> usize {
        (0..self.renderer_terms()).map(|k| self.renderer_term_channels(k)).sum()
    }

    /// Channels of each transparent object's input: its transparency buffer, and with
    /// [`Self::through`] its through buffer after it.
    pub fn object_channels(&self) -> usize {
        layout::TRANSPARENT_CHANNELS + if self.through { layout::THROUGH_CHANNELS } else { 0 }
    }

    /// Of [`Self::object_channels`], those h reads encoded: all but the through buffer's
    /// screen offset and on-screen flag, which say where h reads the scene code instead.
    pub fn encoded_object_channels(&self) -> usize {
        layout::TRANSPARENT_CHANNELS + if self.through { layout::through::SCREEN_OFFSET } else { 0 }
    }

    /// Whether F reads the through buffer of the object in front ([`Self::through`] on the
    /// naive baseline).
    pub fn reads_front_through(&self) -> bool {
        self.through && self.model == ModelKind::Naive
    }

    /// Channels F reads beside the G-buffer with [`Self::reads_front_through`]: the front-most
    /// through buffer's channels before its screen offset Fourier-encoded (L_d clamped to 1),
    /// then its on-screen flag.
    pub fn front_through_width(&self) -> usize {
        if !self.reads_front_through() {
            return 0;
        }
        layout::through::SCREEN_OFFSET * self.encoded_width() + 1
    }

    /// Channels of one positionally encoded input channel.
    pub fn encoded_width(&self) -> usize {
        1 + 2 * self.encoding_frequencies
    }

    /// Channels of a buffer of `channels` channels once encoded: each Fourier-encoded, or with a
    /// position grid the 3 position channels raw plus the grid's features instead.
    pub fn encoded_buffer_width(&self, channels: usize) -> usize {
        match &self.position_grid {
            None => channels * self.encoded_width(),
            Some(grid) => (channels - 3) * self.encoded_width() + 3 + grid.output_channels(),
        }
    }
}

/// Optimisation settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    pub steps: u64,
    pub batch_size: usize,
    /// Square random crop of each training frame; `None` trains on whole frames.
    pub crop: Option<u32>,
    pub learning_rate: f64,
    /// Decoupled (AdamW) weight decay.
    pub weight_decay: f64,
    /// Linear warm-up steps, then cosine decay to `final_lr_fraction` of the rate.
    pub warmup_steps: u64,
    pub final_lr_fraction: f64,
    /// The SSIM term's weight: loss = L1 + ssim_weight * (1 - SSIM). 0 is the "L1 only" ablation.
    pub ssim_weight: f64,
    pub validate_every: u64,
    pub checkpoint_every: u64,
    /// Validation frames used at each validation (all, when `None`).
    pub validation_frames: Option<usize>,
    pub seed: u64,
}

impl TrainConfig {
    /// Learning rate at `step`: linear warm-up, then cosine decay.
    pub fn learning_rate_at(&self, step: u64) -> f64 {
        if step < self.warmup_steps {
            return self.learning_rate * (step + 1) as f64 / self.warmup_steps as f64;
        }
        let span = self.steps.saturating_sub(self.warmup_steps).max(1) as f64;
        let progress = ((step - self.warmup_steps) as f64 / span).min(1.0);
        let cosine = 0.5 * (1.0 + (std::f64::consts::PI * progress).cos());
        self.learning_rate * (self.final_lr_fraction + (1.0 - self.final_lr_fraction) * cosine)
    }

    pub fn check(&self, origin: &str) -> Result<()> {
        let bad = |field: &str, message: &str| Err(Error::bad_input(origin, field, message));
        if self.steps == 0 {
            return bad("steps", "must be at least 1");
        }
        if self.batch_size == 0 {
            return bad("batch_size", "must be at least 1");
        }
        if !(self.learning_rate > 0.0 && self.learning_rate.is_finite()) {
            return bad("learning_rate", "must be a positive number");
        }
        if self.weight_decay.is_nan() || self.weight_decay < 0.0 {
            return bad("weight_decay", "must be at least 0");
        }
        if self.validate_every == 0 || self.checkpoint_every == 0 {
            return bad("validate_every/checkpoint_every", "must be at least 1");
        }
        if !(0.0..=1.0).contains(&self.final_lr_fraction) {
            return bad("final_lr_fraction", "must lie in [0, 1]");
        }
        if self.ssim_weight.is_nan() || self.ssim_weight < 0.0 {
            return bad("ssim_weight", "must be at least 0");
        }
        if self.crop.is_some_and(|side| (side as usize) < crate::loss::SSIM_WINDOW) {
            return Err(Error::bad_input(origin, "crop", format!("crops must be at least the SSIM window, {} px", crate::loss::SSIM_WINDOW)));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_model_of_a_shape_is_valid_and_only_pixelgen_has_its_mlp() {
        for kind in ModelKind::ALL {
            let config = NetConfig::new(&NetShape::smallest(), "small", kind, 3, 4).unwrap();
            assert_eq!(config.pixel_generator.is_some(), kind == ModelKind::Pixelgen);
            assert_eq!(config.through, kind == ModelKind::Glassnet);
            assert_eq!(ModelKind::parse(kind.name()), Some(kind));
        }
    }

    #[test]
    fn too_many_objects_for_exact_sums_are_refused() {
        let err = NetConfig::new(&NetShape::smallest(), "small", ModelKind::Glassnet, 0, MAX_EXACT_OBJECTS + 1).unwrap_err();
        assert!(err.to_string().contains("transparent_objects"), "{err}");
    }

    #[test]
    fn learning_rate_warms_up_then_decays_to_the_floor() {
        let c = TrainConfig {
            steps: 100,
            batch_size: 1,
            crop: None,
            learning_rate: 1.0,
            weight_decay: 0.0,
            warmup_steps: 10,
            final_lr_fraction: 0.1,
            ssim_weight: 1.0,
            validate_every: 10,
            checkpoint_every: 10,
            validation_frames: None,
            seed: 0,
        };
        assert!((c.learning_rate_at(0) - 0.1).abs() < 1e-12);
        assert!((c.learning_rate_at(9) - 1.0).abs() < 1e-12);
        assert!((c.learning_rate_at(10) - 1.0).abs() < 1e-12);
        // Halfway through the cosine: the midpoint between peak and floor.
        assert!((c.learning_rate_at(55) - 0.55).abs() < 1e-12);
        assert!((c.learning_rate_at(100) - 0.1).abs() < 1e-12);
        assert!((c.learning_rate_at(1000) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn config_round_trips_through_json() {
        let c = NetConfig::new(&NetShape::smallest(), "small", ModelKind::Concat, 4, 4).unwrap();
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<NetConfig>(&json).unwrap(), c);
        assert!(json.contains("\"model\":\"concat\""));
    }
}

/// The x2 super-sampler's settings (the `super_sampler` module).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuperSamplerConfig {
    pub preset: String,
    pub encoding_frequencies: usize,
    pub network: CnnConfig,
    /// Whether the full-resolution image is composited with the full-resolution G-buffer's
    /// light coverage, as GlassNet's is ([`NetConfig::light_coverage`]): without it the
    /// lights' edges at twice GlassNet's resolution are the super-sampler's to draw, and it
    /// drew them with a dark, coloured rim. False in configs saved before this existed.
    #[serde(default)]
    pub light_coverage: bool,
}

/// The largest width (channels) or depth (layers) of any convolution stack, and the largest
/// kernel: far above the paper's network (widths up to 128), far below what cannot be allocated.
pub const MAX_NETWORK_SIZE: usize = 1024;
pub const MAX_KERNEL: usize = 31;

/// Each size at most [`MAX_NETWORK_SIZE`] (kernels at most [`MAX_KERNEL`]), checked before a
/// network of that size is allocated.
fn check_sizes(origin: &str, sizes: &[(&str, usize)]) -> Result<()> {
    for &(field, size) in sizes {
        let limit = if field.ends_with("kernel") { MAX_KERNEL } else { MAX_NETWORK_SIZE };
        if size > limit {
            return Err(Error::bad_input(origin, field, format!("{size} is above {limit}")));
        }
    }
    Ok(())
}

impl SuperSamplerConfig {
    /// Checks the config is buildable; `origin` names the file or flag it came from.
    pub fn check(&self, origin: &str) -> Result<()> {
        let n = &self.network;
        check_sizes(origin, &[("network.width", n.width), ("network.layers", n.layers)])?;
        if n.width == 0 || n.layers == 0 || n.out_channels != 3 {
            return Err(Error::bad_input(origin, "network", "width and layers must be at least 1, out_channels 3 (RGB)"));
        }
        if self.encoding_frequencies > 12 {
            return Err(Error::bad_input(origin, "encoding_frequencies", format!("{} is more than 12", self.encoding_frequencies)));
        }
        Ok(())
    }
}
