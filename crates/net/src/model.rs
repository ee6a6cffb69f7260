//! GlassNet (paper 3.4) and its two baselines on one skeleton:
//!
//! - F, the scene encoder (U-Net): encoded G-buffer + variable planes -> sigma
//! - T: tau = sum_i q(c_i h(encoded b_i, sigma)), h a CNN shared by all transparent objects,
//!   c_i object i's coverage and q the exact-sum snapping of `sum.rs`; `concat` replaces it by
//!   one CNN over all buffers concatenated in a fixed order, `naive` drops it
//! - B, the blending network (U-Net): (sigma, tau) -> phi
//! - R, the rendering network: (phi, L_d) -> linear RGB (clamped to [0, 1] by the tone map).
//!   For the models that read transparency buffers, R also reads the glass light and the glass
//!   transmittance (see [`GLASS_DIRECT_CHANNELS`]) and the transmittance multiplies part of
//!   its output
//!
//! The `pixelgen` baseline replaces all four by one per-pixel MLP on the encoded naive
//! G-buffer and variable planes (`blocks::PixelGenerator`).
//!
//! The streaming entry points ([`GlassNet::encode_scene`], [`GlassNet::transparency_term`],
//! [`GlassNet::decode`]) let a caller feed transparency buffers one at a time, so memory does not
//! grow with their number; [`GlassNet::forward`] composes them for training.

use burn::prelude::*;

use glassbake_core::layout::{self, OPAQUE_CHANNELS, TRANSPARENT_CHANNELS};
use glassbake_core::{Error, Result};

use crate::blocks::{positional_encoding, PixelGenerator, PlainCnn, Renderer, UNet};
use crate::config::{ModelKind, NetConfig};
use crate::hash_grid::HashGrid;
use crate::sum::{snap_to_grid, TransparencySum};

#[derive(Module, Debug)]
pub struct GlassNet {
    /// F; absent for `pixelgen`, as are B and R.
    pub scene_encoder: Option<UNet>,
    /// h for GlassNet, the concatenation CNN for `concat`, absent for `naive` and `pixelgen`.
    pub transparency_encoder: Option<PlainCnn>,
    pub blending: Option<UNet>,
    pub renderer: Option<Renderer>,
    /// The whole `pixelgen` baseline; absent for the others.
    pub pixel_generator: Option<PixelGenerator>,
    /// F's grid of opaque positions, with [`NetConfig::position_grid`].
    pub scene_grid: Option<HashGrid>,
    /// h's grid of transparent surfaces' positions (GlassNet), with [`NetConfig::position_grid`].
    pub object_grid: Option<HashGrid>,
    #[module(skip)]
    pub config: NetConfig,
}

/// One frame batch on the device.
#[derive(Clone, Debug)]
pub struct NetInputs {
    /// [N, 17, H, W]: the opaque G-buffer (GlassNet, concat) or the naive one (naive).
    pub gbuffer: Tensor<4>,
    /// Per transparent object, [N, C, H, W]: its transparency buffer
    /// (`layout::TRANSPARENT_CHANNELS`), then its through buffer (`layout::THROUGH_CHANNELS`)
    /// for the networks that read it ([`NetConfig::through`]); ignored by `naive`.
    pub transparent: Vec<Tensor<4>>,
    /// [N, variables], normalised to [0, 1].
    pub values: Tensor<2>,
    /// [N, 4, H, W]: the light coverage of `gbuffer` (`layout::LIGHT_COVERAGE_ATTRIBUTES`),
    /// for the networks with [`NetConfig::light_coverage`].
    pub light_coverage: Option<Tensor<4>>,
}

/// What F computed once per frame and every later stage reads.
#[derive(Clone, Debug)]
pub struct SceneCode {
    pub sigma: Tensor<4>,
    /// L_d of the G-buffer, for R.
    pub direct_light: Tensor<4>,
    /// The G-buffer's albedo, which a demodulated R multiplies part of its output by.
    pub albedo: Tensor<4>,
    /// The G-buffer's light coverage, which the image is composited with.
    pub light_coverage: Option<Tensor<4>>,
}

impl GlassNet {
    /// A network with weights drawn from `seed` (see `init.rs`).
    pub fn new(config: &NetConfig, seed: u64, device: &Device) -> Result<GlassNet> {
        config.check("config")?;
        let e = config.encoded_width();
        let input_channels = config.encoded_buffer_width(OPAQUE_CHANNELS) + config.variables + config.front_through_width();
        if let (ModelKind::Pixelgen, Some(pixel)) = (config.model, &config.pixel_generator) {
            let net = GlassNet {
                scene_encoder: None,
                transparency_encoder: None,
                blending: None,
                renderer: None,
                pixel_generator: Some(PixelGenerator::new(input_channels, pixel, 3, device)),
                scene_grid: None,
                object_grid: None,
                config: config.clone(),
            };
            return Ok(crate::init::initialize(net, seed));
        }
        let sigma = config.scene_encoder.out_channels;
        let tau = config.transparency_encoder.out_channels;
        let scene_encoder = UNet::new(input_channels, &config.scene_encoder, device);
        let (transparency_encoder, blend_input) = match config.model {
            ModelKind::Glassnet => {
                let warped_sigma = if config.through { sigma } else { 0 };
                (
                    Some(PlainCnn::new(
                        config.encoded_buffer_width(config.encoded_object_channels()) + sigma + warped_sigma,
                        &config.transparency_encoder,
                        device,
                    )),
                    sigma + tau,
                )
            }
            ModelKind::Concat => {
                (Some(PlainCnn::new(config.transparent_objects * TRANSPARENT_CHANNELS * e + sigma, &config.transparency_encoder, device)), sigma + tau)
            }
            ModelKind::Naive | ModelKind::Pixelgen => (None, sigma),
        };
        let blending = UNet::new(blend_input, &config.blending, device);
        let glass_direct = if config.model.reads_transparency_buffers() { glass_direct_channels(config) } else { 0 };
        let renderer_outputs = config.renderer_outputs();
        let renderer = Renderer::new(config.blending.out_channels + 3 + glass_direct, &config.renderer, renderer_outputs, device);
        let net = GlassNet {
            scene_encoder: Some(scene_encoder),
            transparency_encoder,
            blending: Some(blending),
            renderer: Some(renderer),
            pixel_generator: None,
            scene_grid: config.position_grid.as_ref().map(|g| HashGrid::new(g, seed, device)),
            object_grid: config.position_grid.as_ref().filter(|_| config.model == ModelKind::Glassnet).map(|g| HashGrid::new(g, seed, device)),
            config: config.clone(),
        };
        let mut net = crate::init::initialize(net, seed);
        // The grids start near zero as instant-ngp's, not as convolution weights.
        for (k, grid) in [net.scene_grid.as_mut(), net.object_grid.as_mut()].into_iter().enumerate() {
            if let Some(grid) = grid {
                grid.reinitialize(glassbake_core::seed::sample_seed(seed, 1 << 20 | k as u64));
            }
        }
        // T's last layer starts at zero, so tau = 0 and a new GlassNet is the naive network on
        // the opaque G-buffer; tau grows where it lowers the loss. With random weights tau
        // starts as noise B must first learn to ignore: on cornellbox (1,500 steps) GlassNet's
        // validation loss was 0.144 from random, 0.135 from zero (naive: 0.138).
        if let Some(t) = net.transparency_encoder.as_mut() {
            t.head.weight = t.head.weight.clone().map(|w| {
                let outputs = w.dims()[0];
                zero_last(w, 0, outputs)
            });
        }
        // Likewise R's weights on the glass light and transmittance (its last input channels)
        // start at zero, and so do its two transmitted outputs (all but the first term), so a
        // new network still renders what the naive one would.
        if glass_direct > 0 {
            let transmitted = renderer_outputs - config.renderer_term_channels();
            let r = net.renderer.as_mut().expect("built above");
            r.large.conv.weight = r.large.conv.weight.clone().map(|w| zero_last(w, 1, glass_direct));
            r.head.weight = r.head.weight.clone().map(|w| zero_last(w, 0, transmitted));
            r.head.bias = r.head.bias.take().map(|b| b.map(|b| zero_last(b, 0, transmitted)));
        }
        Ok(net)
    }

    pub fn kind(&self) -> ModelKind {
        self.config.model
    }

    /// Checks that a frame of `width` x `height` with `objects` transparency buffers fits.
    pub fn check_inputs(&self, width: usize, height: usize, objects: usize) -> Result<()> {
        let m = self.config.size_multiple();
        if !width.is_multiple_of(m) || !height.is_multiple_of(m) || width == 0 || height == 0 {
            return Err(Error::bad_input(
                "inputs",
                "resolution",
                format!("{width}x{height} is not a multiple of {m} (the U-Nets halve it {} times)", m.trailing_zeros()),
            ));
        }
        match self.config.model {
            ModelKind::Concat if objects != self.config.transparent_objects => Err(Error::bad_input(
                "inputs",
                "transparent",
                format!("the concat baseline was built for {} transparency buffers, got {objects}", self.config.transparent_objects),
            )),
            ModelKind::Naive if self.config.reads_front_through() && objects != self.config.transparent_objects => Err(Error::bad_input(
                "inputs",
                "transparent",
                format!(
                    "the naive baseline reading the front-most through buffer was built for {} transparency buffers, got {objects}",
                    self.config.transparent_objects
                ),
            )),
            ModelKind::Glassnet if objects > crate::config::MAX_EXACT_OBJECTS => Err(Error::bad_input(
                "inputs",
                "transparent",
                format!("{objects} transparency buffers; at most {} sum exactly", crate::config::MAX_EXACT_OBJECTS),
            )),
            _ => Ok(()),
        }
    }

    /// The positionally encoded G-buffer with the variable values as constant planes: what F
    /// (or the pixelgen MLP) reads; with [`NetConfig::reads_front_through`] followed by the
    /// front-most through buffer (see [`front_through`]) as [`NetConfig::front_through_width`]
    /// says.
    fn encoded_inputs(&self, gbuffer: Tensor<4>, values: Tensor<2>, front_through: Option<Tensor<4>>) -> Tensor<4> {
        let [n, _, h, w] = gbuffer.dims();
        let mut inputs = vec![self.encode_buffer(gbuffer, self.scene_grid.as_ref(), layout::opaque::POSITION)];
        if self.config.variables > 0 {
            inputs.push(values.reshape([n, self.config.variables, 1, 1]).expand([n, self.config.variables, h, w]));
        }
        if let Some(through) = front_through {
            use layout::through::{LD, ON_SCREEN, SCREEN_OFFSET};
            // L_d clamped to 1 as the G-buffer's (a light seen through glass is 10-50). The
            // screen offset is left out: in pixels it means one thing in a training crop and
            // another in the whole frame.
            let encoded = Tensor::cat(
                vec![
                    through.clone().narrow(1, 0, LD),
                    through.clone().narrow(1, LD, 3).clamp(0.0, 1.0),
                    through.clone().narrow(1, LD + 3, SCREEN_OFFSET - LD - 3),
                ],
                1,
            );
            inputs.push(positional_encoding(encoded, self.config.encoding_frequencies));
            inputs.push(through.narrow(1, ON_SCREEN, 1));
        }
        Tensor::cat(inputs, 1)
    }

    /// A buffer's channels Fourier-encoded, or with a grid: the channels other than the
    /// position (at `position`) Fourier-encoded, then the raw position, then its grid features.
    fn encode_buffer(&self, buffer: Tensor<4>, grid: Option<&HashGrid>, position: usize) -> Tensor<4> {
        let frequencies = self.config.encoding_frequencies;
        let Some(grid) = grid else {
            return positional_encoding(buffer, frequencies);
        };
        let channels = buffer.dims()[1];
        let positions = buffer.clone().narrow(1, position, 3);
        let others = Tensor::cat(vec![buffer.clone().narrow(1, 0, position), buffer.narrow(1, position + 3, channels - position - 3)], 1);
        Tensor::cat(vec![positional_encoding(others, frequencies), positions.clone(), grid.forward(positions)], 1)
    }

    /// F: the G-buffer and variable values -> sigma (and L_d kept for R).
    ///
    /// `light_coverage` is the G-buffer's ([`NetInputs::light_coverage`]); a network with
    /// [`NetConfig::light_coverage`] panics without it (`TrainedModel::render` checks
    /// beforehand and returns an error).
    pub fn encode_scene(&self, gbuffer: Tensor<4>, light_coverage: Option<Tensor<4>>, values: Tensor<2>) -> SceneCode {
        self.encode_scene_through(gbuffer, light_coverage, values, None)
    }

    /// [`Self::encode_scene`] for a network with [`NetConfig::reads_front_through`], given the
    /// front-most through buffer ([`front_through`]); `None` for the others.
    pub fn encode_scene_through(
        &self,
        gbuffer: Tensor<4>,
        light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        front_through: Option<Tensor<4>>,
    ) -> SceneCode {
        assert_eq!(
            front_through.is_some(),
            self.config.reads_front_through(),
            "the naive baseline with through buffers, and only it, reads the front-most through buffer"
        );
        let f = self.scene_encoder.as_ref().expect("pixelgen has no F: use forward_streaming");
        let (gbuffer, light_coverage) = if self.config.light_coverage {
            let light_coverage = light_coverage.expect("a network composited with the light coverage is given the G-buffer's light coverage");
            (with_direct_light_clamped(gbuffer), Some(light_coverage))
        } else {
            (gbuffer, None)
        };
        let direct_light = gbuffer.clone().narrow(1, layout::opaque::LD, 3);
        let albedo = gbuffer.clone().narrow(1, layout::opaque::ALBEDO, 3);
        SceneCode { sigma: f.forward(self.encoded_inputs(gbuffer, values, front_through)), direct_light, albedo, light_coverage }
    }

    /// An object's buffer as h reads it: the transparency buffer with its through buffer
    /// ([`NetConfig::through`]), or only the transparency buffer's channels.
    fn object_input(&self, buffer: Tensor<4>) -> Tensor<4> {
        let channels = buffer.dims()[1];
        if self.config.through {
            assert_eq!(channels, self.config.object_channels(), "a network reading through buffers is given them after each transparency buffer");
            buffer
        } else if channels == TRANSPARENT_CHANNELS {
            buffer
        } else {
            buffer.narrow(1, 0, TRANSPARENT_CHANNELS)
        }
    }

    /// h for one transparency buffer (times the buffer's coverage, see
    /// [`NetConfig::terms_masked_by_coverage`]), followed by the buffer's glass light and log
    /// transmittance ([`glass_direct_channels`]), snapped for the exact sum. GlassNet only.
    pub fn transparency_term(&self, scene: &SceneCode, buffer: Tensor<4>) -> Tensor<4> {
        assert_eq!(self.config.model, ModelKind::Glassnet, "transparency_term is GlassNet's T");
        let h = self.transparency_encoder.as_ref().expect("GlassNet has h");
        let buffer = self.object_input(buffer);
        let coverage = buffer.clone().narrow(1, layout::transparent::COVERAGE, 1);
        let direct = glass_direct(&buffer, self.config.through);
        let read = self.config.encoded_object_channels();
        let encoded = self.encode_buffer(buffer.clone().narrow(1, 0, read), self.object_grid.as_ref(), layout::transparent::POSITION);
        let mut inputs = vec![encoded, scene.sigma.clone()];
        if self.config.through {
            inputs.push(sigma_at_hits(scene.sigma.clone(), buffer.narrow(1, read, 3)));
        }
        let term = h.forward(Tensor::cat(inputs, 1));
        let term = if self.config.terms_masked_by_coverage { term * coverage } else { term };
        snap_to_grid(Tensor::cat(vec![term, direct], 1))
    }

    /// The concat baseline's tau: every buffer at once, in the given (fixed) order, followed
    /// by the buffers' summed glass light and log transmittance, as GlassNet's.
    pub fn concat_term(&self, scene: &SceneCode, buffers: &[Tensor<4>]) -> Tensor<4> {
        assert_eq!(self.config.model, ModelKind::Concat, "concat_term is the concat baseline's");
        let cnn = self.transparency_encoder.as_ref().expect("concat has its CNN");
        let buffers: Vec<Tensor<4>> = buffers.iter().map(|b| self.object_input(b.clone())).collect();
        let mut inputs: Vec<Tensor<4>> = buffers.iter().map(|b| positional_encoding(b.clone(), self.config.encoding_frequencies)).collect();
        inputs.push(scene.sigma.clone());
        let term = cnn.forward(Tensor::cat(inputs, 1));
        let [n, _, h, w] = term.dims();
        let direct = buffers
            .iter()
            .map(|b| glass_direct(b, false))
            .reduce(|a, b| a + b)
            .unwrap_or_else(|| Tensor::zeros([n, GLASS_DIRECT_CHANNELS, h, w], &term.device()));
        Tensor::cat(vec![term, direct], 1)
    }

    /// B and R: (sigma, tau) -> phi -> linear RGB. For the models that read transparency
    /// buffers, `tau`'s last [`GLASS_DIRECT_CHANNELS`] are the summed glass light and log
    /// transmittance, which go to R beside the G-buffer's L_d instead of through B; R then
    /// renders `a + t b1 + t^2 b2` from its 9 outputs (a, b1, b2), t the transmittance (1 where
    /// there is no glass; t^2 for solid glass, tinted where light enters and leaves).
    ///
    /// With [`NetConfig::demodulated`] each of R's terms is `free + albedo * light`, the
    /// albedo the G-buffer's (for GlassNet that of the opaque surface, also behind glass), so
    /// texture detail comes from the G-buffer instead of from the weights; the free part
    /// carries emitters and what the albedo does not explain.
    pub fn decode(&self, scene: &SceneCode, tau: Option<Tensor<4>>) -> Tensor<4> {
        let (b, r) = (self.blending.as_ref().expect("pixelgen has no B"), self.renderer.as_ref().expect("pixelgen has no R"));
        let Some(tau) = tau else {
            let phi = b.forward(scene.sigma.clone());
            let out = r.forward(Tensor::cat(vec![phi, scene.direct_light.clone()], 1));
            return self.finish(self.term(&out, scene, 0), scene, None);
        };
        let features = tau.dims()[1] - glass_direct_channels(&self.config);
        let light = tau.clone().narrow(1, features, GLASS_LIGHT_CHANNELS);
        let transmittance = tau.clone().narrow(1, features + GLASS_LIGHT_CHANNELS, 3).exp();
        let mut r_inputs = vec![scene.direct_light.clone(), light, transmittance.clone()];
        if self.config.through {
            r_inputs.push(tau.clone().narrow(1, features + GLASS_DIRECT_CHANNELS, THROUGH_DIRECT_CHANNELS));
        }
        let phi = b.forward(Tensor::cat(vec![scene.sigma.clone(), tau.narrow(1, 0, features)], 1));
        r_inputs.insert(0, phi);
        let out = r.forward(Tensor::cat(r_inputs, 1));
        let [a, b1, b2] = [0, 1, 2].map(|k| self.term(&out, scene, k));
        self.finish(a + (b1 + b2 * transmittance.clone()) * transmittance.clone(), scene, Some(transmittance))
    }

    /// The network's `image` with the lights the G-buffer sees put in, through the glass's
    /// `transmittance` where there is one: composited with the light coverage
    /// ([`NetConfig::light_coverage`]) or saturated ([`NetConfig::saturate_direct_light`]).
    fn finish(&self, image: Tensor<4>, scene: &SceneCode, transmittance: Option<Tensor<4>>) -> Tensor<4> {
        if let Some(coverage) = &scene.light_coverage {
            return composite_light(image, coverage.clone(), transmittance);
        }
        let direct_light = match transmittance {
            Some(t) => scene.direct_light.clone() * t,
            None => scene.direct_light.clone(),
        };
        self.saturate(image, direct_light)
    }

    /// With [`NetConfig::saturate_direct_light`]: 1 wherever `direct_light` alone reaches 1 in
    /// every channel (the clamp of the tone map makes the true image white there too), the
    /// network's `image` elsewhere. No gradient reaches the network from those pixels.
    fn saturate(&self, image: Tensor<4>, direct_light: Tensor<4>) -> Tensor<4> {
        if !self.config.saturate_direct_light {
            return image;
        }
        let saturated = direct_light.detach().min_dim(1).greater_equal_elem(1.0).float();
        let [n, c, h, w] = image.dims();
        let saturated = saturated.expand([n, c, h, w]);
        image * saturated.clone().neg().add_scalar(1.0) + saturated
    }

    /// Term `k` of R's output `out`: its 3 channels, or with [`NetConfig::demodulated`] its
    /// free 3 plus the albedo times the next 3.
    fn term(&self, out: &Tensor<4>, scene: &SceneCode, k: usize) -> Tensor<4> {
        let width = self.config.renderer_term_channels();
        let free = out.clone().narrow(1, k * width, 3);
        if self.config.demodulated {
            free + scene.albedo.clone() * out.clone().narrow(1, k * width + 3, 3)
        } else {
            free
        }
    }

    /// The whole network on a batch. GlassNet streams the buffers through h one at a time.
    pub fn forward(&self, inputs: &NetInputs) -> Tensor<4> {
        self.forward_streaming(inputs.gbuffer.clone(), inputs.light_coverage.clone(), inputs.values.clone(), inputs.transparent.len(), |k| {
            Some(inputs.transparent[k].clone())
        })
    }

    /// The whole network, asking `buffer(k)` for transparency buffer k of `objects` only when it
    /// is needed, so GlassNet holds at most one at a time. `None` is an object out of view: it
    /// adds nothing to GlassNet's sum and is zeros for `concat`.
    pub fn forward_streaming(
        &self,
        gbuffer: Tensor<4>,
        light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        objects: usize,
        mut buffer: impl FnMut(usize) -> Option<Tensor<4>>,
    ) -> Tensor<4> {
        if let Some(pixel) = &self.pixel_generator {
            return pixel.forward(self.encoded_inputs(gbuffer, values, None));
        }
        // Given none, it would read no glass at all: a caller that forgot the buffers.
        assert!(
            !self.config.reads_front_through() || objects == self.config.transparent_objects,
            "the naive baseline reading the front-most through buffer is given every transparency buffer"
        );
        let front = self.config.reads_front_through().then(|| {
            let [n, _, h, w] = gbuffer.dims();
            front_through((0..objects).filter_map(&mut buffer), [n, h, w], &gbuffer.device())
        });
        let scene = self.encode_scene_through(gbuffer, light_coverage, values, front);
        let [n, _, h, w] = scene.sigma.dims();
        let device = scene.sigma.device();
        let tau = match self.config.model {
            ModelKind::Naive | ModelKind::Pixelgen => None,
            ModelKind::Concat => {
                let buffers: Vec<Tensor<4>> =
                    (0..objects).map(|k| buffer(k).unwrap_or_else(|| Tensor::zeros([n, TRANSPARENT_CHANNELS, h, w], &device))).collect();
                Some(self.concat_term(&scene, &buffers))
            }
            ModelKind::Glassnet => {
                let mut sum = TransparencySum::new();
                for k in 0..objects {
                    if let Some(b) = buffer(k) {
                        sum.add(self.transparency_term(&scene, b));
                    }
                }
                Some(sum.finish([n, self.config.transparency_encoder.out_channels + glass_direct_channels(&self.config), h, w], &device))
            }
        };
        self.decode(&scene, tau)
    }
}

/// At each pixel, the through buffer of the object in front there (the covering transparency
/// buffer of least depth), zeros where no object covers it: what the naive G-buffer's glass
/// surface lets the camera see. `buffers` are transparency buffers each followed by its through
/// buffer, taken one at a time so memory does not grow with their number.
pub fn front_through(buffers: impl Iterator<Item = Tensor<4>>, [n, h, w]: [usize; 3], device: &Device) -> Tensor<4> {
    let mut nearest = Tensor::<4>::full([n, 1, h, w], f32::MAX, device);
    let mut through = Tensor::<4>::zeros([n, layout::THROUGH_CHANNELS, h, w], device);
    for buffer in buffers {
        assert_eq!(buffer.dims()[1], TRANSPARENT_CHANNELS + layout::THROUGH_CHANNELS, "a transparency buffer followed by its through buffer");
        let covered = buffer.clone().narrow(1, layout::transparent::COVERAGE, 1).greater_elem(0.0);
        let depth = buffer.clone().narrow(1, layout::transparent::DEPTH, 1);
        let in_front = depth.clone().lower(nearest.clone()).float() * covered.float();
        let keep = in_front.clone().neg().add_scalar(1.0);
        nearest = nearest * keep.clone() + depth * in_front.clone();
        let shape = [n, layout::THROUGH_CHANNELS, h, w];
        through = through * keep.expand(shape) + buffer.narrow(1, TRANSPARENT_CHANNELS, layout::THROUGH_CHANNELS) * in_front.expand(shape);
    }
    through
}

/// Channels of a transparency buffer's glass light: L_d and L_d far, times its coverage.
pub const GLASS_LIGHT_CHANNELS: usize = 6;
/// What each transparency buffer adds to the exact sum beside h's output and R reads without
/// going through h and B: the glass light, then the log transmittance (3 channels).
pub const GLASS_DIRECT_CHANNELS: usize = GLASS_LIGHT_CHANNELS + 3;
/// Tints darker than this count as this (ln 1/256 = -5.5 stays well inside the exact sum's
/// term bound).
const DARKEST_TINT: f32 = 1.0 / 256.0;

/// What R reads of each object's through buffer, summed over the objects beside the glass
/// light: the albedo, then the direct light (clamped to 1, as the G-buffer's), of the surface
/// seen through the object, each times the Fresnel transmittance and the coverage. The
/// printed text behind a lens reaches R in its refracted place without passing h and B.
pub const THROUGH_DIRECT_CHANNELS: usize = 6;

/// [`GLASS_DIRECT_CHANNELS`], plus [`THROUGH_DIRECT_CHANNELS`] for a network with
/// [`NetConfig::through`].
pub fn glass_direct_channels(config: &NetConfig) -> usize {
    GLASS_DIRECT_CHANNELS + if config.through { THROUGH_DIRECT_CHANNELS } else { 0 }
}

/// The light a transparency buffer's surfaces reflect (L_d then L_d far, masked by the
/// coverage), then the log of its tint (albedo) times the coverage, then with `through` the
/// through buffer's part ([`THROUGH_DIRECT_CHANNELS`]). Summed over the objects, the first
/// reaches R directly, as the naive network's L_d does: through h and B the highlights, a
/// pixel or two wide and several times brighter than anything else, came out smeared. The
/// second is the log of the product of the tints in front of each pixel, so R multiplies what
/// it sees through glass by the glass's colour instead of learning the product (desk, whose
/// tints are the variables: both networks drew its glass grey or brown; docs/design.md §5).
fn glass_direct(buffer: &Tensor<4>, through: bool) -> Tensor<4> {
    const { assert!(layout::transparent::LD_FAR == layout::transparent::LD + 3) };
    let coverage = buffer.clone().narrow(1, layout::transparent::COVERAGE, 1);
    let light = buffer.clone().narrow(1, layout::transparent::LD, GLASS_LIGHT_CHANNELS);
    let log_tint = buffer.clone().narrow(1, layout::transparent::ALBEDO, 3).clamp(DARKEST_TINT, 1.0).log();
    let mut parts = vec![light, log_tint];
    if through {
        let at = |offset: usize, count: usize| buffer.clone().narrow(1, layout::TRANSPARENT_CHANNELS + offset, count);
        let transmittance = at(layout::through::TRANSMITTANCE, 1);
        parts.push(at(layout::through::ALBEDO, 3) * transmittance.clone());
        parts.push(at(layout::through::LD, 3).clamp(0.0, 1.0) * transmittance);
    }
    Tensor::cat(parts, 1) * coverage
}

/// `sigma` [N, C, H, W] read at the pixel each through hit projects to
/// (`screen`: [N, 3, H, W], the through buffer's screen offset and on-screen flag), 0 where the
/// hit is hidden or outside the frame (or the crop). What the scene encoder says of the surface
/// seen through the glass, its light included: the through buffer's own L_d is direct light
/// only. Gradients reach sigma at the pixels read.
pub fn sigma_at_hits(sigma: Tensor<4>, screen: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = sigma.dims();
    let device = sigma.device();
    let screen = screen.detach();
    let columns = Tensor::<1, Int>::arange(0..w as i64, &device).float().reshape([1, 1, 1, w]).expand([n, 1, h, w]);
    let rows = Tensor::<1, Int>::arange(0..h as i64, &device).float().reshape([1, 1, h, 1]).expand([n, 1, h, w]);
    let x = (columns + screen.clone().narrow(1, 0, 1)).round();
    let y = (rows + screen.clone().narrow(1, 1, 1)).round();
    let shown = screen.narrow(1, 2, 1).greater_elem(0.5);
    let inside = x
        .clone()
        .greater_equal_elem(0.0)
        .bool_and(x.clone().lower_elem(w as f32))
        .bool_and(y.clone().greater_equal_elem(0.0))
        .bool_and(y.clone().lower_elem(h as f32));
    let read = shown.bool_and(inside).float();
    let index = (y.clamp(0.0, (h - 1) as f32) * w as f32 + x.clamp(0.0, (w - 1) as f32)).int().reshape([n, 1, h * w]).expand([n, c, h * w]);
    sigma.reshape([n, c, h * w]).gather(2, index).reshape([n, c, h, w]) * read.expand([n, c, h, w])
}

/// The G-buffer with its L_d clamped to [0, 1]. With the light coverage the lights come from
/// the composite; what the network needs to read of them is that they are at least white. An
/// emitter's own radiance (17 in cornellbox), Fourier-encoded, is noise to the convolutions
/// around it (clamped: +0.1 dB GlassNet, +0.4 dB naive on the default cornellbox bake, one
/// seed; docs/history/benchmarks-2026-11.md).
fn with_direct_light_clamped(gbuffer: Tensor<4>) -> Tensor<4> {
    const { assert!(layout::opaque::LD + 3 == layout::OPAQUE_CHANNELS) };
    let direct_light = gbuffer.clone().narrow(1, layout::opaque::LD, 3).clamp(0.0, 1.0);
    Tensor::cat(vec![gbuffer.narrow(1, 0, layout::opaque::LD), direct_light], 1)
}

/// `light x t + (1 - covered) image`, from a light coverage [N, 4, H, W]
/// (`layout::LIGHT_COVERAGE_ATTRIBUTES`) and the `transmittance` t of the glass in front (1
/// without): the pixel the ground truth holds when a share `covered` of it sees `light` (summed
/// over that share) and the rest `image`. Where a light is seen it is clamped to 1, the tone
/// map's white: the loss compares with the clamped truth and must not push the rest of the
/// pixel down to make up for a light brighter than white. No gradient reaches the coverage.
pub(crate) fn composite_light(image: Tensor<4>, light_coverage: Tensor<4>, transmittance: Option<Tensor<4>>) -> Tensor<4> {
    let light_coverage = light_coverage.detach();
    let covered = light_coverage.clone().narrow(1, layout::light_coverage::COVERAGE, 1);
    let light = light_coverage.narrow(1, layout::light_coverage::LIGHT, 3);
    let light = match transmittance {
        Some(t) => light * t,
        None => light,
    };
    let [n, c, h, w] = image.dims();
    let lit = covered.clone().greater_elem(0.0).expand([n, c, h, w]);
    let composite = light + image * covered.neg().add_scalar(1.0).expand([n, c, h, w]);
    composite.clone().mask_where(lit, composite.clamp_max(1.0))
}

/// `w` with its last `count` entries along `dim` set to zero, still trainable if it was.
fn zero_last<const D: usize>(w: Tensor<D>, dim: usize, count: usize) -> Tensor<D> {
    let dims = w.dims();
    let ranges: [std::ops::Range<usize>; D] = std::array::from_fn(|d| if d == dim { dims[d] - count..dims[d] } else { 0..dims[d] });
    let mut zero_dims = dims;
    zero_dims[dim] = count;
    let zeroed = w.clone().slice_assign(ranges, Tensor::zeros(zero_dims, &w.device()));
    if w.is_require_grad() {
        zeroed.detach().require_grad()
    } else {
        zeroed
    }
}
