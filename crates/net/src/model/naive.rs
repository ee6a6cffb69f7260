//! The naive baseline: F, B and R of GlassNet on the naive G-buffer, where the glass nearest
//! the camera overwrites what is behind it, and no transparency term. With
//! [`NetConfig::through`] (the front-through ablation) F also reads the through buffer of the
//! object in front at each pixel: GlassNet's input without its architecture.
//!
//! Saved as `scene_encoder.*`, `blending.*`, `renderer.*`, and with a position grid
//! `scene_grid.*`.

use burn::prelude::*;

use glassbake_core::{Error, Result};

use super::skeleton::{new_skeleton, reinitialize_grid, Skeleton};
use super::{check_kind, front_through, SceneCode, SceneModel};
use crate::blocks::{Renderer, UNet};
use crate::config::{ModelKind, NetConfig};
use crate::hash_grid::HashGrid;

#[derive(Module, Debug)]
pub struct Naive {
    /// F.
    pub scene_encoder: UNet,
    /// B.
    pub blending: UNet,
    /// R.
    pub renderer: Renderer,
    /// F's grid of positions, with [`NetConfig::position_grid`].
    pub scene_grid: Option<HashGrid>,
    #[module(skip)]
    pub config: NetConfig,
}

impl Naive {
    /// A network with weights drawn from `seed` (see `init.rs`).
    pub fn new(config: &NetConfig, seed: u64, device: &Device) -> Result<Naive> {
        check_kind(config, ModelKind::Naive)?;
        let (scene_encoder, blending, renderer) = new_skeleton(config, config.scene_encoder.out_channels, device);
        let net = Naive {
            scene_encoder,
            blending,
            renderer,
            scene_grid: config.position_grid.as_ref().map(|g| HashGrid::new(g, seed, device)),
            config: config.clone(),
        };
        let mut net = crate::init::initialize(net, seed);
        reinitialize_grid(net.scene_grid.as_mut(), seed, 0);
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

    /// F: the naive G-buffer, its light coverage, the variable values and, for the
    /// front-through ablation, the front-most through buffer -> sigma.
    pub fn encode_scene(&self, gbuffer: Tensor<4>, light_coverage: Option<Tensor<4>>, values: Tensor<2>, front_through: Option<Tensor<4>>) -> SceneCode {
        self.skeleton().encode_scene(gbuffer, light_coverage, values, front_through)
    }

    /// B and R on sigma: the image.
    pub fn decode(&self, scene: &SceneCode) -> Tensor<4> {
        self.skeleton().decode(scene, None)
    }
}

impl SceneModel for Naive {
    fn config(&self) -> &NetConfig {
        &self.config
    }

    fn reads_naive_gbuffer(&self) -> bool {
        true
    }

    fn reads_object_buffers(&self) -> bool {
        self.config.reads_front_through()
    }

    fn check_objects(&self, objects: usize) -> Result<()> {
        if self.config.reads_front_through() && objects != self.config.transparent_objects {
            return Err(Error::bad_input(
                "inputs",
                "transparent",
                format!(
                    "the naive baseline reading the front-most through buffer was built for {} transparency buffers, got {objects}",
                    self.config.transparent_objects
                ),
            ));
        }
        Ok(())
    }

    fn forward_streaming(
        &self,
        gbuffer: Tensor<4>,
        light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        objects: usize,
        buffer: &mut dyn FnMut(usize) -> Option<Tensor<4>>,
    ) -> Tensor<4> {
        let front = self.config.reads_front_through().then(|| {
            // Given none, it would read no glass at all: a caller that forgot the buffers.
            assert_eq!(objects, self.config.transparent_objects, "the naive baseline reading the front-most through buffer is given every transparency buffer");
            let [n, _, h, w] = gbuffer.dims();
            front_through((0..objects).filter_map(&mut *buffer), [n, h, w], &gbuffer.device())
        });
        let scene = self.encode_scene(gbuffer, light_coverage, values, front);
        self.decode(&scene)
    }
}
