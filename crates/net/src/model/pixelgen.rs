//! The pixelgen baseline: one per-pixel MLP (`blocks::PixelGenerator`) on the encoded naive
//! G-buffer and variable planes in place of F, T, B and R, in the style of Active
//! Exploration's pixel generator. Reads the naive G-buffer only; any resolution works (no
//! U-Net).
//!
//! Saved as `pixel_generator.*`.

use burn::prelude::*;

use glassbake_core::Result;

use super::skeleton::{encoded_inputs, scene_input_channels};
use super::{check_kind, SceneModel};
use crate::blocks::PixelGenerator;
use crate::config::{ModelKind, NetConfig};

#[derive(Module, Debug)]
pub struct PixelGen {
    pub pixel_generator: PixelGenerator,
    #[module(skip)]
    pub config: NetConfig,
}

impl PixelGen {
    /// A network with weights drawn from `seed` (see `init.rs`).
    pub fn new(config: &NetConfig, seed: u64, device: &Device) -> Result<PixelGen> {
        check_kind(config, ModelKind::Pixelgen)?;
        let shape = config.pixel_generator.as_ref().expect("a checked pixelgen config has its MLP's shape");
        let net = PixelGen { pixel_generator: PixelGenerator::new(scene_input_channels(config), shape, 3, device), config: config.clone() };
        Ok(crate::init::initialize(net, seed))
    }
}

impl SceneModel for PixelGen {
    fn config(&self) -> &NetConfig {
        &self.config
    }

    fn reads_naive_gbuffer(&self) -> bool {
        true
    }

    fn reads_object_buffers(&self) -> bool {
        false
    }

    fn check_objects(&self, _objects: usize) -> Result<()> {
        Ok(())
    }

    fn forward_streaming(
        &self,
        gbuffer: Tensor<4>,
        _light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        _objects: usize,
        _buffer: &mut dyn FnMut(usize) -> Option<Tensor<4>>,
    ) -> Tensor<4> {
        self.pixel_generator.forward(encoded_inputs(&self.config, None, gbuffer, values, None))
    }
}
