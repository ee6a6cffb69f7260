//! GlassNet (paper 3.4): F encodes the opaque G-buffer into sigma; T sums
//! `q(c_i h(encoded b_i, sigma))` over the transparent objects' buffers b_i, h one CNN shared by
//! all of them, c_i object i's coverage and q the exact-sum snapping of `sum.rs`, so the sum is
//! the same to the last bit in any order and memory does not grow with the objects; B and R
//! turn (sigma, tau) into the image.
//!
//! Reads the opaque G-buffer and every object's transparency buffer (followed by its through
//! buffer with [`NetConfig::through`]). Saved as `scene_encoder.*`, `transparency_encoder.*`
//! (h), `blending.*`, `renderer.*`, and with a position grid `scene_grid.*` and `object_grid.*`.

use burn::prelude::*;

use glassbake_core::layout::{self, TRANSPARENT_CHANNELS};
use glassbake_core::{Error, Result};

use super::skeleton::{encode_buffer, new_skeleton, reinitialize_grid, Skeleton};
use super::{check_kind, glass_direct, glass_direct_channels, sigma_at_hits, start_glass_inputs_at_zero, start_tau_at_zero, SceneCode, SceneModel};
use crate::blocks::{PlainCnn, Renderer, UNet};
use crate::config::{ModelKind, NetConfig, MAX_EXACT_OBJECTS};
use crate::hash_grid::HashGrid;
use crate::sum::{snap_to_grid, TransparencySum};

#[derive(Module, Debug)]
pub struct GlassNet {
    /// F.
    pub scene_encoder: UNet,
    /// h, shared by every transparent object.
    pub transparency_encoder: PlainCnn,
    /// B.
    pub blending: UNet,
    /// R.
    pub renderer: Renderer,
    /// F's grid of opaque positions, with [`NetConfig::position_grid`].
    pub scene_grid: Option<HashGrid>,
    /// h's grid of transparent surfaces' positions, with [`NetConfig::position_grid`].
    pub object_grid: Option<HashGrid>,
    #[module(skip)]
    pub config: NetConfig,
}

impl GlassNet {
    /// A network with weights drawn from `seed` (see `init.rs`); T's last layer and R's glass
    /// inputs start at zero, so a new GlassNet renders what the naive network on the opaque
    /// G-buffer would.
    pub fn new(config: &NetConfig, seed: u64, device: &Device) -> Result<GlassNet> {
        check_kind(config, ModelKind::Glassnet)?;
        let sigma = config.scene_encoder.out_channels;
        let tau = config.transparency_encoder.out_channels;
        let warped_sigma = if config.through { sigma } else { 0 };
        let (scene_encoder, blending, renderer) = new_skeleton(config, sigma + tau, device);
        let transparency_encoder =
            PlainCnn::new(config.encoded_buffer_width(config.encoded_object_channels()) + sigma + warped_sigma, &config.transparency_encoder, device);
        let net = GlassNet {
            scene_encoder,
            transparency_encoder,
            blending,
            renderer,
            scene_grid: config.position_grid.as_ref().map(|g| HashGrid::new(g, seed, device)),
            object_grid: config.position_grid.as_ref().map(|g| HashGrid::new(g, seed, device)),
            config: config.clone(),
        };
        let mut net = crate::init::initialize(net, seed);
        reinitialize_grid(net.scene_grid.as_mut(), seed, 0);
        reinitialize_grid(net.object_grid.as_mut(), seed, 1);
        start_tau_at_zero(&mut net.transparency_encoder);
        start_glass_inputs_at_zero(&mut net.renderer, config);
        Ok(net)
    }

    fn skeleton(&self) -> Skeleton<'_> {
        Skeleton {
            config: &self.config,
            scene_encoder: &self.scene_encoder,
            scene_grid: self.scene_grid.as_ref(),
            blending: &self.blending,
            renderer: &self.renderer,
        }
    }

    /// F: the opaque G-buffer, its light coverage and the variable values -> sigma (and L_d
    /// kept for R). The first of the three streaming steps.
    pub fn encode_scene(&self, gbuffer: Tensor<4>, light_coverage: Option<Tensor<4>>, values: Tensor<2>) -> SceneCode {
        self.skeleton().encode_scene(gbuffer, light_coverage, values, None)
    }

    /// h for one transparency buffer (times the buffer's coverage, see
    /// [`NetConfig::terms_masked_by_coverage`]), followed by the buffer's glass light and log
    /// transmittance ([`glass_direct_channels`]), snapped for the exact sum: one term of tau.
    pub fn transparency_term(&self, scene: &SceneCode, buffer: Tensor<4>) -> Tensor<4> {
        let buffer = self.object_input(buffer);
        let coverage = buffer.clone().narrow(1, layout::transparent::COVERAGE, 1);
        let direct = glass_direct(&buffer, self.config.through);
        let read = self.config.encoded_object_channels();
        let encoded = encode_buffer(&self.config, buffer.clone().narrow(1, 0, read), self.object_grid.as_ref(), layout::transparent::POSITION);
        let mut inputs = vec![encoded, scene.sigma.clone()];
        if self.config.through {
            inputs.push(sigma_at_hits(scene.sigma.clone(), buffer.narrow(1, read, 3)));
        }
        let term = self.transparency_encoder.forward(Tensor::cat(inputs, 1));
        let term = if self.config.terms_masked_by_coverage { term * coverage } else { term };
        snap_to_grid(Tensor::cat(vec![term, direct], 1))
    }

    /// B and R on sigma and the summed terms: the image (see `Skeleton::decode`).
    pub fn decode(&self, scene: &SceneCode, tau: Tensor<4>) -> Tensor<4> {
        self.skeleton().decode(scene, Some(tau))
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
}

impl SceneModel for GlassNet {
    fn config(&self) -> &NetConfig {
        &self.config
    }

    fn reads_naive_gbuffer(&self) -> bool {
        false
    }

    fn reads_object_buffers(&self) -> bool {
        true
    }

    fn unseen_objects_add_nothing(&self) -> bool {
        self.config.terms_masked_by_coverage
    }

    fn check_objects(&self, objects: usize) -> Result<()> {
        if objects > MAX_EXACT_OBJECTS {
            return Err(Error::bad_input("inputs", "transparent", format!("{objects} transparency buffers; at most {MAX_EXACT_OBJECTS} sum exactly")));
        }
        Ok(())
    }

    /// Streams the buffers through h one at a time: at most one is alive.
    fn forward_streaming(
        &self,
        gbuffer: Tensor<4>,
        light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        objects: usize,
        buffer: &mut dyn FnMut(usize) -> Option<Tensor<4>>,
    ) -> Tensor<4> {
        let scene = self.encode_scene(gbuffer, light_coverage, values);
        let [n, _, h, w] = scene.sigma.dims();
        let mut sum = TransparencySum::new();
        for k in 0..objects {
            if let Some(b) = buffer(k) {
                sum.add(self.transparency_term(&scene, b));
            }
        }
        let tau = sum.finish([n, self.config.transparency_encoder.out_channels + glass_direct_channels(&self.config), h, w], &scene.sigma.device());
        self.decode(&scene, tau)
    }
}
