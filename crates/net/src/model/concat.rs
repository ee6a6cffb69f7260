//! The concat baseline: GlassNet with T replaced by one CNN over every transparency buffer
//! concatenated in a fixed order (so it depends on the order, and is built for one number of
//! objects), followed by the buffers' summed glass light and log transmittance as GlassNet's.
//!
//! Reads the opaque G-buffer and the transparency buffers (never the through buffers). Saved
//! as `scene_encoder.*`, `transparency_encoder.*` (the CNN), `blending.*`, `renderer.*`, and
//! with a position grid `scene_grid.*`.

use burn::prelude::*;

use glassbake_core::layout::TRANSPARENT_CHANNELS;
use glassbake_core::{Error, Result};

use super::skeleton::{new_skeleton, reinitialize_grid, Skeleton};
use super::{check_kind, glass_direct, start_glass_inputs_at_zero, start_tau_at_zero, SceneModel, GLASS_DIRECT_CHANNELS};
use crate::blocks::{positional_encoding, PlainCnn, Renderer, UNet};
use crate::config::{ModelKind, NetConfig};
use crate::hash_grid::HashGrid;

#[derive(Module, Debug)]
pub struct Concat {
    /// F.
    pub scene_encoder: UNet,
    /// The CNN over all buffers at once, in T's place.
    pub transparency_encoder: PlainCnn,
    /// B.
    pub blending: UNet,
    /// R.
    pub renderer: Renderer,
    /// F's grid of opaque positions, with [`NetConfig::position_grid`].
    pub scene_grid: Option<HashGrid>,
    #[module(skip)]
    pub config: NetConfig,
}

impl Concat {
    /// A network with weights drawn from `seed` (see `init.rs`), its CNN's last layer and R's
    /// glass inputs at zero as GlassNet's.
    pub fn new(config: &NetConfig, seed: u64, device: &Device) -> Result<Concat> {
        check_kind(config, ModelKind::Concat)?;
        let sigma = config.scene_encoder.out_channels;
        let (scene_encoder, blending, renderer) = new_skeleton(config, sigma + config.transparency_encoder.out_channels, device);
        let e = config.encoded_width();
        let transparency_encoder = PlainCnn::new(config.transparent_objects * TRANSPARENT_CHANNELS * e + sigma, &config.transparency_encoder, device);
        let net = Concat {
            scene_encoder,
            transparency_encoder,
            blending,
            renderer,
            scene_grid: config.position_grid.as_ref().map(|g| HashGrid::new(g, seed, device)),
            config: config.clone(),
        };
        let mut net = crate::init::initialize(net, seed);
        reinitialize_grid(net.scene_grid.as_mut(), seed, 0);
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
}

impl SceneModel for Concat {
    fn config(&self) -> &NetConfig {
        &self.config
    }

    fn reads_naive_gbuffer(&self) -> bool {
        false
    }

    fn reads_object_buffers(&self) -> bool {
        true
    }

    fn check_objects(&self, objects: usize) -> Result<()> {
        if objects != self.config.transparent_objects {
            return Err(Error::bad_input(
                "inputs",
                "transparent",
                format!("the concat baseline was built for {} transparency buffers, got {objects}", self.config.transparent_objects),
            ));
        }
        Ok(())
    }

    /// Every buffer at once, in the given (fixed) order; an object out of view is zeros.
    fn forward_streaming(
        &self,
        gbuffer: Tensor<4>,
        light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        objects: usize,
        buffer: &mut dyn FnMut(usize) -> Option<Tensor<4>>,
    ) -> Tensor<4> {
        let skeleton = self.skeleton();
        let scene = skeleton.encode_scene(gbuffer, light_coverage, values, None);
        let [n, _, h, w] = scene.sigma.dims();
        let device = scene.sigma.device();
        // Only the transparency buffers' channels: concat never reads the through buffers.
        let buffers: Vec<Tensor<4>> = (0..objects)
            .map(|k| buffer(k).map_or_else(|| Tensor::zeros([n, TRANSPARENT_CHANNELS, h, w], &device), |b| b.narrow(1, 0, TRANSPARENT_CHANNELS)))
            .collect();
        let mut inputs: Vec<Tensor<4>> = buffers.iter().map(|b| positional_encoding(b.clone(), self.config.encoding_frequencies)).collect();
        inputs.push(scene.sigma.clone());
        let term = self.transparency_encoder.forward(Tensor::cat(inputs, 1));
        let direct =
            buffers.iter().map(|b| glass_direct(b, false)).reduce(|a, b| a + b).unwrap_or_else(|| Tensor::zeros([n, GLASS_DIRECT_CHANNELS, h, w], &device));
        skeleton.decode(&scene, Some(Tensor::cat(vec![term, direct], 1)))
    }
}
