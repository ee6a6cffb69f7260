//! GlassNet (paper 3.4) and its three baselines, one type each behind [`SceneModel`]:
//!
//! - [`GlassNet`]: F, the scene encoder (U-Net), maps the encoded G-buffer and variable planes
//!   to sigma; T sums h(encoded b_i, sigma) over the transparent objects' buffers b_i, h one CNN
//!   shared by all of them, exactly and in any order (`sum.rs`); B, the blending U-Net, maps
//!   (sigma, tau) to phi; R, the rendering network, maps (phi, L_d) to linear RGB. R also
//!   reads the glass light and the glass transmittance (see [`GLASS_DIRECT_CHANNELS`]), and
//!   the transmittance multiplies part of its output.
//! - [`Naive`]: F, B and R on the naive G-buffer (glass overwrites what is behind it).
//! - [`Concat`]: T replaced by one CNN over every buffer concatenated in a fixed order.
//! - [`PixelGen`]: one per-pixel MLP on the encoded naive G-buffer and variable planes.
//!
//! Each type is a burn module whose field names are its weights' SafeTensors names, and says
//! in its docs what it reads and how it is saved. [`with_new_model`] is the one place a
//! config's [`ModelKind`] becomes a type; [`load_model`] opens saved weights behind the trait.
//! F, B and R are shared code (`skeleton.rs`), not a shared module, so the names stay flat.

mod concat;
mod glassnet;
mod naive;
mod pixelgen;
mod skeleton;

use std::path::Path;

use burn::module::Module;
use burn::prelude::*;
use burn::store::ModuleSnapshot;

use glassbake_core::layout::{self, TRANSPARENT_CHANNELS};
use glassbake_core::{Error, Result};

pub use concat::Concat;
pub use glassnet::GlassNet;
pub use naive::Naive;
pub use pixelgen::PixelGen;

use crate::batch::HostBatch;
use crate::blocks::{PlainCnn, Renderer};
use crate::config::{ModelKind, NetConfig};
use crate::train::Trainable;

/// A network that renders a frame from its buffers: GlassNet or a baseline.
pub trait SceneModel {
    fn config(&self) -> &NetConfig;

    fn kind(&self) -> ModelKind {
        self.config().model
    }

    /// Whether the model reads the naive G-buffer (the glass nearest the camera overwrites
    /// what is behind it) instead of the opaque one.
    fn reads_naive_gbuffer(&self) -> bool;

    /// Whether the model reads the transparent objects' buffers (each transparency buffer,
    /// followed by its through buffer where [`NetConfig::through`] says).
    fn reads_object_buffers(&self) -> bool;

    /// Checks that `objects` transparency buffers are what the model takes.
    fn check_objects(&self, objects: usize) -> Result<()>;

    /// Checks that a frame of `width` x `height` with `objects` transparency buffers fits.
    fn check_inputs(&self, width: usize, height: usize, objects: usize) -> Result<()> {
        let m = self.config().size_multiple();
        if !width.is_multiple_of(m) || !height.is_multiple_of(m) || width == 0 || height == 0 {
            return Err(Error::bad_input(
                "inputs",
                "resolution",
                format!("{width}x{height} is not a multiple of {m} (the U-Nets halve it {} times)", m.trailing_zeros()),
            ));
        }
        self.check_objects(objects)
    }

    /// The whole network, asking `buffer(k)` for transparency buffer k of `objects` only when
    /// it is needed, so GlassNet holds at most one at a time. `None` is an object out of view:
    /// it adds nothing to GlassNet's sum and is zeros for `concat`. Returns the unclamped
    /// [N, 3, H, W] image.
    fn forward_streaming(
        &self,
        gbuffer: Tensor<4>,
        light_coverage: Option<Tensor<4>>,
        values: Tensor<2>,
        objects: usize,
        buffer: &mut dyn FnMut(usize) -> Option<Tensor<4>>,
    ) -> Tensor<4>;

    /// Whether an object that covers no pixel adds exactly nothing to the image, forward and
    /// backward, so that a batch that does not show it may leave its buffer out: GlassNet with
    /// its terms masked by coverage ([`NetConfig::terms_masked_by_coverage`]), whose term is
    /// then 0 and whose sum is exact.
    fn unseen_objects_add_nothing(&self) -> bool {
        false
    }

    /// The whole network on a batch.
    fn forward(&self, inputs: &NetInputs) -> Tensor<4> {
        let transparent = &inputs.transparent;
        self.forward_streaming(inputs.gbuffer.clone(), inputs.light_coverage.clone(), inputs.values.clone(), transparent.len(), &mut |k| {
            Some(transparent[k].clone())
        })
    }
}

impl<M: SceneModel + Module + ModuleSnapshot + Clone + 'static> Trainable for M {
    /// Objects the batch does not show are left out where that changes nothing
    /// ([`SceneModel::unseen_objects_add_nothing`]): a training batch of 32 px crops shows few of
    /// a scene's objects, and each costs h forward and backward. Where it shows none, the first
    /// is kept: its term is 0 and h's gradient then 0, as the whole network's, where leaving h
    /// out of the graph would give it no gradient, and AdamW moves a parameter with a zero
    /// gradient (momentum, weight decay) but not one without.
    fn predict(&self, batch: &HostBatch, device: &Device) -> Tensor<4> {
        if !self.unseen_objects_add_nothing() {
            return self.forward(&batch.inputs(device));
        }
        let shown: Vec<bool> = (0..batch.objects()).map(|k| batch.shows_object(k)).collect();
        let none_shown = !shown.contains(&true);
        self.forward_streaming(batch.gbuffer_tensor(device), batch.light_coverage_tensor(device), batch.values_tensor(device), batch.objects(), &mut |k| {
            (shown[k] || (none_shown && k == 0)).then(|| batch.transparent_tensor(k, device))
        })
    }

    fn target(&self, batch: &HostBatch, device: &Device) -> Result<Tensor<4>> {
        batch.target(device).ok_or_else(|| Error::Internal("a training batch without ground truth".into()))
    }
}

/// Work on a new network of a type [`with_new_model`] picks: a generic function that a
/// config's kind, known only at run time, can call (training, loading, benchmarks).
pub trait ModelTask {
    type Output;
    fn run<M: SceneModel + Trainable>(self, model: M) -> Self::Output;
}

/// Builds the network of `config` (of its kind, weights drawn from `seed`) and hands it to
/// `task`.
pub fn with_new_model<T: ModelTask>(config: &NetConfig, seed: u64, device: &Device, task: T) -> Result<T::Output> {
    Ok(match config.model {
        ModelKind::Glassnet => task.run(GlassNet::new(config, seed, device)?),
        ModelKind::Naive => task.run(Naive::new(config, seed, device)?),
        ModelKind::Concat => task.run(Concat::new(config, seed, device)?),
        ModelKind::Pixelgen => task.run(PixelGen::new(config, seed, device)?),
    })
}

/// The network of `config` with its weights read from `weights` (a model directory's
/// SafeTensors file), on `device`.
pub fn load_model(config: &NetConfig, weights: &Path, device: &Device) -> Result<Box<dyn SceneModel>> {
    let bytes = std::fs::read(weights).map_err(|e| Error::io(weights, e))?;
    load_model_from_bytes(config, bytes, &weights.display().to_string(), device)
}

/// [`load_model`] from the weights file's bytes; `label` names the file in errors.
pub fn load_model_from_bytes(config: &NetConfig, weights: Vec<u8>, label: &str, device: &Device) -> Result<Box<dyn SceneModel>> {
    struct Load<'a>(Vec<u8>, &'a str);
    impl ModelTask for Load<'_> {
        type Output = Result<Box<dyn SceneModel>>;
        fn run<M: SceneModel + Trainable>(self, mut model: M) -> Self::Output {
            crate::model_dir::read_weights_from_bytes(&mut model, self.0, self.1)?;
            Ok(Box::new(model))
        }
    }
    with_new_model(config, 0, device, Load(weights, label))?
}

/// The network of `config` as a trait object, weights drawn from `seed`.
pub fn new_model(config: &NetConfig, seed: u64, device: &Device) -> Result<Box<dyn SceneModel>> {
    struct Boxed;
    impl ModelTask for Boxed {
        type Output = Box<dyn SceneModel>;
        fn run<M: SceneModel + Trainable>(self, model: M) -> Self::Output {
            Box::new(model)
        }
    }
    with_new_model(config, seed, device, Boxed)
}

/// Refuses a config of another kind than the type being built, or one that fails its checks.
fn check_kind(config: &NetConfig, kind: ModelKind) -> Result<()> {
    config.check("config")?;
    if config.model != kind {
        return Err(Error::Internal(format!("a {} network built from a {} config", kind.name(), config.model.name())));
    }
    Ok(())
}

/// T's last layer (or concat's CNN's) starts at zero, so tau = 0 and a new GlassNet is the
/// naive network on the opaque G-buffer; tau grows where it lowers the loss. With random
/// weights tau starts as noise B must first learn to ignore: on cornellbox (1,500 steps)
/// GlassNet's validation loss was 0.144 from random, 0.135 from zero (naive: 0.138).
fn start_tau_at_zero(t: &mut PlainCnn) {
    t.head.weight = t.head.weight.clone().map(|w| {
        let outputs = w.dims()[0];
        zero_last(w, 0, outputs)
    });
}

/// R's weights on the glass light and transmittance (its last input channels) start at zero,
/// and so do its two transmitted outputs (all but the first term), so a new network that
/// reads transparency buffers still renders what the naive one would.
fn start_glass_inputs_at_zero(r: &mut Renderer, config: &NetConfig) {
    let glass_direct = glass_direct_channels(config);
    let transmitted = config.renderer_outputs() - config.renderer_term_channels(0);
    r.large.conv.weight = r.large.conv.weight.clone().map(|w| zero_last(w, 1, glass_direct));
    r.head.weight = r.head.weight.clone().map(|w| zero_last(w, 0, transmitted));
    r.head.bias = r.head.bias.take().map(|b| b.map(|b| zero_last(b, 0, transmitted)));
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
pub(crate) fn glass_direct(buffer: &Tensor<4>, through: bool) -> Tensor<4> {
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
