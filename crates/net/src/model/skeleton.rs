//! What GlassNet and the naive and concat baselines share: F, the scene encoder, reading the
//! encoded G-buffer and variable planes, and B + R turning its code (with GlassNet's or
//! concat's tau) into the image, composited with the lights the G-buffer sees.
//!
//! The modules stay fields of each model type, so a weights file names them as before
//! (`scene_encoder.*`, `blending.*`, `renderer.*`, `scene_grid.*`); a [`Skeleton`] borrows them.

use burn::prelude::*;

use glassbake_core::layout;

use super::{composite_light, glass_direct_channels, SceneCode, GLASS_DIRECT_CHANNELS, GLASS_LIGHT_CHANNELS, THROUGH_DIRECT_CHANNELS};
use crate::blocks::{positional_encoding, Renderer, UNet};
use crate::config::{Modulator, NetConfig};
use crate::hash_grid::HashGrid;

/// F, B and R of one network, borrowed from its fields.
pub(crate) struct Skeleton<'a> {
    pub config: &'a NetConfig,
    pub scene_encoder: &'a UNet,
    pub scene_grid: Option<&'a HashGrid>,
    pub blending: &'a UNet,
    pub renderer: &'a Renderer,
}

/// F, B and R of a new network whose B reads `blend_input` channels (sigma, then tau's); R
/// reads B's output, the G-buffer's L_d and, for the models that read transparency buffers,
/// the summed glass light ([`glass_direct_channels`]).
pub(crate) fn new_skeleton(config: &NetConfig, blend_input: usize, device: &Device) -> (UNet, UNet, Renderer) {
    let scene_encoder = UNet::new(scene_input_channels(config), &config.scene_encoder, device);
    let blending = UNet::new(blend_input, &config.blending, device);
    let renderer = Renderer::new(config.blending.out_channels + 3 + renderer_glass_inputs(config), &config.renderer, config.renderer_outputs(), device);
    (scene_encoder, blending, renderer)
}

/// What F (or the pixelgen MLP) reads: the encoded G-buffer, the variable planes and, with
/// [`NetConfig::reads_front_through`], the encoded front-most through buffer.
pub(crate) fn scene_input_channels(config: &NetConfig) -> usize {
    config.encoded_buffer_width(layout::OPAQUE_CHANNELS) + config.variables + config.front_through_width()
}

/// R's inputs beyond B's output and L_d: the summed glass light and transmittance for the
/// models that read transparency buffers.
pub(crate) fn renderer_glass_inputs(config: &NetConfig) -> usize {
    if config.model.reads_transparency_buffers() {
        glass_direct_channels(config)
    } else {
        0
    }
}

/// A new scene grid (F's, of the opaque positions) or object grid (h's, of the transparent
/// surfaces'; `index` 1), started near zero as instant-ngp's, not as convolution weights.
pub(crate) fn reinitialize_grid(grid: Option<&mut HashGrid>, seed: u64, index: u64) {
    if let Some(grid) = grid {
        grid.reinitialize(glassbake_core::seed::sample_seed(seed, 1 << 20 | index));
    }
}

/// The positionally encoded G-buffer with the variable values as constant planes: what F
/// (or the pixelgen MLP) reads; with [`NetConfig::reads_front_through`] followed by the
/// front-most through buffer (see [`super::front_through`]) as
/// [`NetConfig::front_through_width`] says.
pub(crate) fn encoded_inputs(
    config: &NetConfig,
    grid: Option<&HashGrid>,
    gbuffer: Tensor<4>,
    values: Tensor<2>,
    front_through: Option<Tensor<4>>,
) -> Tensor<4> {
    let [n, _, h, w] = gbuffer.dims();
    let mut inputs = vec![encode_buffer(config, gbuffer, grid, layout::opaque::POSITION)];
    if config.variables > 0 {
        inputs.push(values.reshape([n, config.variables, 1, 1]).expand([n, config.variables, h, w]));
    }
    if let Some(through) = front_through {
        use layout::through::{LD, ON_SCREEN, SCREEN_OFFSET};
        // L_d clamped to 1 as the G-buffer's (a light seen through glass is 10-50). The
        // screen offset is left out: in pixels it means one thing in a training crop and
        // another in the whole frame.
        let encoded = Tensor::cat(
            vec![through.clone().narrow(1, 0, LD), through.clone().narrow(1, LD, 3).clamp(0.0, 1.0), through.clone().narrow(1, LD + 3, SCREEN_OFFSET - LD - 3)],
            1,
        );
        inputs.push(positional_encoding(encoded, config.encoding_frequencies));
        inputs.push(through.narrow(1, ON_SCREEN, 1));
    }
    Tensor::cat(inputs, 1)
}

/// A buffer's channels Fourier-encoded, or with a grid: the channels other than the
/// position (at `position`) Fourier-encoded, then the raw position, then its grid features.
pub(crate) fn encode_buffer(config: &NetConfig, buffer: Tensor<4>, grid: Option<&HashGrid>, position: usize) -> Tensor<4> {
    let frequencies = config.encoding_frequencies;
    let Some(grid) = grid else {
        return positional_encoding(buffer, frequencies);
    };
    let channels = buffer.dims()[1];
    let positions = buffer.clone().narrow(1, position, 3);
    let others = Tensor::cat(vec![buffer.clone().narrow(1, 0, position), buffer.narrow(1, position + 3, channels - position - 3)], 1);
    Tensor::cat(vec![positional_encoding(others, frequencies), positions.clone(), grid.forward(positions)], 1)
}

impl Skeleton<'_> {
    /// F: the G-buffer and variable values (and, for the naive baseline reading it, the
    /// front-most through buffer) -> sigma, with L_d and the albedo kept for R.
    ///
    /// `light_coverage` is the G-buffer's; a network with [`NetConfig::light_coverage`] panics
    /// without it (`TrainedModel::render` checks beforehand and returns an error).
    pub fn encode_scene(&self, gbuffer: Tensor<4>, light_coverage: Option<Tensor<4>>, values: Tensor<2>, front_through: Option<Tensor<4>>) -> SceneCode {
        assert_eq!(
            front_through.is_some(),
            self.config.reads_front_through(),
            "the naive baseline with through buffers, and only it, reads the front-most through buffer"
        );
        let (gbuffer, light_coverage) = if self.config.light_coverage {
            let light_coverage = light_coverage.expect("a network composited with the light coverage is given the G-buffer's light coverage");
            (with_direct_light_clamped(gbuffer), Some(light_coverage))
        } else {
            (gbuffer, None)
        };
        let direct_light = gbuffer.clone().narrow(1, layout::opaque::LD, 3);
        let albedo = gbuffer.clone().narrow(1, layout::opaque::ALBEDO, 3);
        let sigma = self.scene_encoder.forward(encoded_inputs(self.config, self.scene_grid, gbuffer, values, front_through));
        SceneCode { sigma, direct_light, albedo, light_coverage }
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
    /// carries emitters and what the albedo does not explain. With
    /// [`NetConfig::through_demodulated`] b1 and b2 are demodulated by the through buffers'
    /// albedo instead: what the glass shows is the surface its refracted rays reach, not the
    /// one behind it on screen.
    pub fn decode(&self, scene: &SceneCode, tau: Option<Tensor<4>>) -> Tensor<4> {
        let (b, r) = (self.blending, self.renderer);
        let Some(tau) = tau else {
            let phi = b.forward(scene.sigma.clone());
            let out = r.forward(Tensor::cat(vec![phi, scene.direct_light.clone()], 1));
            return self.finish(self.term(&out, scene, None, 0), scene, None);
        };
        let features = tau.dims()[1] - glass_direct_channels(self.config);
        let light = tau.clone().narrow(1, features, GLASS_LIGHT_CHANNELS);
        let transmittance = tau.clone().narrow(1, features + GLASS_LIGHT_CHANNELS, 3).exp();
        let mut r_inputs = vec![scene.direct_light.clone(), light, transmittance.clone()];
        if self.config.through {
            r_inputs.push(tau.clone().narrow(1, features + GLASS_DIRECT_CHANNELS, THROUGH_DIRECT_CHANNELS));
        }
        let through_albedo = self.config.through.then(|| tau.clone().narrow(1, features + GLASS_DIRECT_CHANNELS, 3));
        let phi = b.forward(Tensor::cat(vec![scene.sigma.clone(), tau.narrow(1, 0, features)], 1));
        r_inputs.insert(0, phi);
        let out = r.forward(Tensor::cat(r_inputs, 1));
        let [a, b1, b2] = [0, 1, 2].map(|k| self.term(&out, scene, through_albedo.as_ref(), k));
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

    /// Term `k` of R's output `out`: its 3 channels, or where the term is demodulated
    /// ([`NetConfig::term_modulator`]) its free 3 plus the albedo times the next 3.
    /// `through_albedo` is the summed through buffers' ([`THROUGH_DIRECT_CHANNELS`]' first 3).
    fn term(&self, out: &Tensor<4>, scene: &SceneCode, through_albedo: Option<&Tensor<4>>, k: usize) -> Tensor<4> {
        let start: usize = (0..k).map(|j| self.config.renderer_term_channels(j)).sum();
        let free = out.clone().narrow(1, start, 3);
        let albedo = match self.config.term_modulator(k) {
            None => return free,
            Some(Modulator::GbufferAlbedo) => scene.albedo.clone(),
            Some(Modulator::ThroughAlbedo) => through_albedo.expect("a through-demodulated GlassNet reads through buffers").clone(),
        };
        free + albedo * out.clone().narrow(1, start + 3, 3)
    }
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
