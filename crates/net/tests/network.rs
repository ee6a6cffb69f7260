//! GlassNet: shapes, the straight-through exact sum, permutation bit-exactness (CPU, and wgpu where an adapter exists), save/load.

mod common;

use burn::prelude::*;
use burn::tensor::TensorData;
use glassbake_net::model::SceneCode;
use glassbake_net::model_dir::{read_weights, write_weights, ModelConfig, ModelFiles, Network, FORMAT_VERSION};
use glassbake_net::sum::{snap_to_grid, TERM_BOUND};
use glassbake_net::{burn, new_model, with_new_model, GlassNet, ModelKind, ModelTask, Naive, NetConfig, NetInputs, PixelGen, SceneModel, Trainable};
use rand::seq::SliceRandom;
use rand::SeedableRng;

fn values(t: Tensor<4>) -> Vec<f32> {
    t.into_data().try_to_vec::<f32>().unwrap()
}

fn bits(t: Tensor<4>) -> Vec<u32> {
    values(t).into_iter().map(f32::to_bits).collect()
}

#[test]
fn every_model_kind_maps_a_batch_to_an_rgb_image_of_its_size() {
    let device = Device::flex();
    device.seed(3);
    let frames: Vec<_> = (0..2).map(|i| common::frame(i, 16, 3, 2)).collect();
    let batch = common::batch(&frames);
    for kind in ModelKind::ALL {
        let net = new_model(&common::small_net(kind, 2, 3), 3, &device).unwrap();
        let out = net.forward(&batch.inputs(&device));
        assert_eq!(out.dims(), [2, 3, 16, 16], "{kind:?}");
        assert!(values(out).iter().all(|v| v.is_finite()));
    }
    // A U-Net of 3 levels needs multiples of 4.
    let three_levels = glassbake_net::config::UNetConfig { base_width: 4, levels: 3, out_channels: 4 };
    let shape = glassbake_net::NetShape { scene_encoder: three_levels.clone(), blending: three_levels, ..glassbake_net::NetShape::smallest() };
    let net = GlassNet::new(&NetConfig::new(&shape, "small", ModelKind::Glassnet, 2, 3).unwrap(), 3, &device).unwrap();
    assert!(net.check_inputs(64, 64, 3).is_ok());
    assert!(net.check_inputs(66, 64, 3).unwrap_err().to_string().contains("multiple of 4"));
}

#[test]
fn pixelgen_is_a_per_pixel_mlp_with_the_input_fed_again_midway() {
    let device = Device::flex();
    let config = common::small_net(ModelKind::Pixelgen, 2, 3);
    let net = PixelGen::new(&config, 3, &device).unwrap();
    let pixel = &net.pixel_generator;
    let p = config.pixel_generator.as_ref().unwrap();
    let input = glassbake_core::layout::OPAQUE_CHANNELS * config.encoded_width() + 2;
    assert_eq!(pixel.layers.len(), p.layers);
    // Weights [out, in, 1, 1]: 1x1 convolutions only; the skip layer reads width + input.
    for (i, layer) in pixel.layers.iter().enumerate() {
        let dims = layer.conv.weight.dims();
        let expected_in = match i {
            0 => input,
            i if i == p.skip_at => p.width + input,
            _ => p.width,
        };
        assert_eq!(dims, [p.width, expected_in, 1, 1], "layer {i}");
    }
    // Any size works (no U-Net), and a pixel depends only on its own G-buffer texel: changing
    // one texel of the input changes exactly that output pixel.
    assert!(net.check_inputs(13, 7, 0).is_ok());
    let frames = vec![common::frame(7, 8, 0, 2)];
    let batch = common::batch(&frames);
    let inputs = batch.inputs(&device);
    let before = values(net.forward(&inputs));
    let mut gbuffer = values(inputs.gbuffer.clone());
    let (h, w) = (8, 8);
    let (y, x) = (3, 5);
    for c in 0..glassbake_core::layout::OPAQUE_CHANNELS {
        gbuffer[c * h * w + y * w + x] += 0.37;
    }
    let moved = NetInputs { gbuffer: Tensor::from_data(TensorData::new(gbuffer, inputs.gbuffer.dims()), &device), ..inputs };
    let after = values(net.forward(&moved));
    for c in 0..3 {
        for i in 0..h * w {
            let changed = before[c * h * w + i] != after[c * h * w + i];
            assert!(!(changed && i != y * w + x), "pixel {i} of channel {c} changed");
        }
    }
    assert!((0..3).any(|c| before[c * h * w + y * w + x] != after[c * h * w + y * w + x]), "the edited pixel must change");
}

#[test]
fn the_exact_sum_passes_gradients_straight_through_inside_its_bound() {
    let device = Device::flex().autodiff();
    let input = vec![0.3f32, -2.0, TERM_BOUND * 2.0, 5e-6];
    let x = Tensor::<4>::from_data(TensorData::new(input, [1, 1, 1, 4]), &device).require_grad();
    let r = Tensor::<4>::from_data(TensorData::new(vec![1.0f32, 2.0, 3.0, 4.0], [1, 1, 1, 4]), &device);
    let grads = (snap_to_grid(x.clone()) * r).sum().backward();
    let g = x.grad(&grads).unwrap().into_data().try_to_vec::<f32>().unwrap();
    // Identity inside the bound, zero where the clamp is active.
    assert_eq!(g, vec![1.0, 2.0, 0.0, 4.0]);
}

/// A GlassNet with every weight random, T's last layer included: a new GlassNet starts with
/// that layer at zero (tau = 0), which would make tests of how T combines objects vacuous.
fn random_glassnet(config: &NetConfig, seed: u64, device: &Device) -> GlassNet {
    glassbake_net::init::initialize(GlassNet::new(config, seed, device).unwrap(), seed)
}

/// [`random_glassnet`] for a network of any kind.
fn random_net(config: &NetConfig, seed: u64, device: &Device) -> Box<dyn SceneModel> {
    struct Randomized(u64);
    impl ModelTask for Randomized {
        type Output = Box<dyn SceneModel>;
        fn run<M: SceneModel + Trainable>(self, model: M) -> Self::Output {
            Box::new(glassbake_net::init::initialize(model, self.0))
        }
    }
    with_new_model(config, seed, device, Randomized(seed)).unwrap()
}

#[test]
fn a_new_glassnet_starts_as_the_naive_network_on_the_opaque_gbuffer_and_learns_tau() {
    let device = Device::flex();
    device.seed(4);
    let frames = vec![common::frame(50, 16, 2, 1)];
    let batch = common::batch(&frames);
    let inputs = batch.inputs(&device);
    let mut no_glass = inputs.clone();
    no_glass.transparent.clear();
    let net = GlassNet::new(&common::small_net(ModelKind::Glassnet, 1, 2), 4, &device).unwrap();
    assert_eq!(bits(net.forward(&inputs)), bits(net.forward(&no_glass)), "tau must start at zero");
    // ... but not stay there: the head of T gets a gradient.
    let train_device = Device::flex().autodiff();
    let net = GlassNet::new(&common::small_net(ModelKind::Glassnet, 1, 2), 4, &train_device).unwrap();
    let grads = net.forward(&batch.inputs(&train_device)).sum().backward();
    let head = &net.transparency_encoder.head.weight;
    let gradient: Vec<f32> = head.grad(&grads).expect("T's head has a gradient").into_data().try_to_vec::<f32>().unwrap();
    assert!(gradient.iter().any(|g| g.abs() > 1e-6), "T's head gets no gradient: {gradient:?}");
    // R's weights on the summed glass light and transmittance (its last input channels) start
    // at zero too, and get a gradient; so do its outputs that the transmittance multiplies.
    let r = &net.renderer.large.conv.weight;
    let [_, inputs, _, _] = r.dims();
    let light = glassbake_net::model::glass_direct_channels(&net.config);
    let weights: Vec<f32> = r.val().narrow(1, inputs - light, light).into_data().try_to_vec::<f32>().unwrap();
    assert!(weights.iter().all(|&w| w == 0.0), "R's glass-light weights start at {weights:?}");
    let gradient: Vec<f32> = r.grad(&grads).expect("R has a gradient").narrow(1, inputs - light, light).into_data().try_to_vec::<f32>().unwrap();
    assert!(gradient.iter().any(|g| g.abs() > 1e-6), "R's glass-light weights get no gradient");
    let head = &net.renderer.head.weight;
    let term = net.config.renderer_term_channels(0);
    let transmitted_channels = net.config.renderer_outputs() - term;
    let transmitted: Vec<f32> = head.val().narrow(0, term, transmitted_channels).into_data().try_to_vec::<f32>().unwrap();
    assert!(transmitted.iter().all(|&w| w == 0.0), "R's transmitted outputs start at {transmitted:?}");
    let gradient: Vec<f32> = head.grad(&grads).expect("R's head has a gradient").narrow(0, term, transmitted_channels).into_data().try_to_vec::<f32>().unwrap();
    assert!(gradient.iter().any(|g| g.abs() > 1e-6), "R's transmitted outputs get no gradient");
}

#[test]
fn the_transmitted_outputs_are_multiplied_by_the_product_of_the_tints_in_front() {
    // R's head set to render only b1 = 1 (then only b2 = 1): the output is the transmittance t
    // (then t^2), t = prod_k tint_k^coverage_k over the transparency buffers, computed here
    // independently in f64 from the buffers' planes.
    use glassbake_core::layout::transparent::{ALBEDO, COVERAGE};
    let device = Device::flex();
    let (size, objects) = (8, 2);
    let frames = vec![common::frame(61, size, objects, 1)];
    let batch = common::batch(&frames);
    let inputs = batch.inputs(&device);
    // R predicting RGB directly (the demodulated path is tested by its own test below).
    let config = NetConfig { demodulated: false, saturate_direct_light: false, ..common::small_net(ModelKind::Glassnet, 1, objects) };
    let mut net = random_glassnet(&config, 7, &device);
    for (power, bias) in [(1, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]), (2, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0])] {
        let head = &mut net.renderer.head;
        head.weight = head.weight.clone().map(|w| w.zeros_like());
        head.bias = Some(burn::module::Param::from_tensor(Tensor::<1>::from_floats(bias, &device)));
        let out = values(net.forward(&inputs));
        let mut checked_below_one = 0;
        for c in 0..3 {
            for i in 0..size * size {
                let log_t: f64 =
                    frames[0].transparent.iter().map(|b| b.plane(COVERAGE)[i] as f64 * (b.plane(ALBEDO + c)[i] as f64).clamp(1.0 / 256.0, 1.0).ln()).sum();
                let expected = (log_t * power as f64).exp();
                let got = out[c * size * size + i] as f64;
                assert!((got - expected).abs() <= 1e-4 * expected, "t^{power}, channel {c}, pixel {i}: {got} vs {expected}");
                checked_below_one += (expected < 0.9) as usize;
            }
        }
        assert!(checked_below_one > size * size, "the synthetic tints barely attenuate: the check would not see a missing t");
    }
}

#[test]
fn through_demodulated_transmitted_terms_multiply_the_through_albedo() {
    // R's head set so b1's light is 1 and everything else 0 (then b2's): the output is
    // t * A (then t^2 * A), A = sum_k through albedo_k * Fresnel transmittance_k * coverage_k,
    // t the tints' product, both computed here independently in f64 from the buffers' planes.
    use glassbake_core::layout::{through, transparent, TRANSPARENT_CHANNELS};
    let device = Device::flex();
    let (size, objects) = (8, 2);
    let frames = vec![common::frame(62, size, objects, 1)];
    let batch = common::batch(&frames);
    let inputs = batch.inputs(&device);
    let config = NetConfig { through_demodulated: true, ..common::small_net(ModelKind::Glassnet, 1, objects) };
    assert_eq!(config.renderer_outputs(), 3 + 6 + 6);
    let mut net = random_glassnet(&config, 8, &device);
    for power in [1, 2] {
        let mut bias = [0.0f32; 15];
        let light = if power == 1 { 3 + 3 } else { 3 + 6 + 3 };
        bias[light..light + 3].fill(1.0);
        let head = &mut net.renderer.head;
        head.weight = head.weight.clone().map(|w| w.zeros_like());
        head.bias = Some(burn::module::Param::from_tensor(Tensor::<1>::from_floats(bias, &device)));
        let out = values(net.forward(&inputs));
        let mut textured = 0;
        for c in 0..3 {
            for i in 0..size * size {
                let (mut log_t, mut albedo) = (0.0f64, 0.0f64);
                for b in &frames[0].transparent {
                    let coverage = b.plane(transparent::COVERAGE)[i] as f64;
                    log_t += coverage * (b.plane(transparent::ALBEDO + c)[i] as f64).clamp(1.0 / 256.0, 1.0).ln();
                    let fresnel = b.plane(TRANSPARENT_CHANNELS + through::TRANSMITTANCE)[i] as f64;
                    albedo += b.plane(TRANSPARENT_CHANNELS + through::ALBEDO + c)[i] as f64 * fresnel * coverage;
                }
                let expected = (log_t * power as f64).exp() * albedo;
                let got = out[c * size * size + i] as f64;
                assert!((got - expected).abs() <= 1e-4 * (1.0 + expected), "t^{power} A, channel {c}, pixel {i}: {got} vs {expected}");
                textured += (expected > 0.05) as usize;
            }
        }
        assert!(textured > size * size, "the synthetic through albedo is too faint for the check to see it");
    }
    // Only GlassNet reading through buffers has a through albedo.
    for config in [
        NetConfig { through_demodulated: true, through: false, ..common::small_net(ModelKind::Glassnet, 1, objects) },
        NetConfig { through_demodulated: true, ..common::small_net(ModelKind::Naive, 1, objects) },
    ] {
        let error = config.check("test").unwrap_err().to_string();
        assert!(error.contains("through_demodulated"), "{error}");
    }
}

/// A small position grid over the synthetic frames' positions, with hashed levels.
fn test_grid() -> glassbake_net::hash_grid::HashGridConfig {
    glassbake_net::hash_grid::HashGridConfig {
        levels: 3,
        features: 2,
        log2_table_size: 8,
        base_resolution: 2,
        finest_resolution: 12,
        bounds_min: [-1.0; 3],
        bounds_max: [2.0; 3],
    }
}

fn permutation_exactness(device: &Device, sizes: &[usize]) {
    device.seed(5);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for (&objects, grid) in sizes.iter().flat_map(|s| [(s, None), (s, Some(test_grid()))]) {
        let frames = vec![common::frame(100 + objects as u64, 16, objects, 1)];
        let batch = common::batch(&frames);
        let config = NetConfig { position_grid: grid, ..common::small_net(ModelKind::Glassnet, 1, objects) };
        let net = random_glassnet(&config, 5, device);
        if config.position_grid.is_some() {
            assert!(net.scene_grid.is_some() && net.object_grid.is_some());
        }
        let mut inputs = batch.inputs(device);
        let reference = bits(net.forward(&inputs));
        for _ in 0..4 {
            inputs.transparent.shuffle(&mut rng);
            assert_eq!(bits(net.forward(&inputs)), reference, "t = {objects}: a permutation changed the output");
        }
        inputs.transparent.reverse();
        assert_eq!(bits(net.forward(&inputs)), reference, "t = {objects}: reversing changed the output");
    }
}

#[test]
fn an_object_that_covers_no_pixel_adds_nothing_when_terms_are_masked() {
    let device = Device::flex();
    device.seed(8);
    let frames = vec![common::frame(40, 16, 3, 1)];
    let batch = common::batch(&frames);
    let mut inputs = batch.inputs(&device);
    // Object 2 keeps its other attributes but covers no pixel.
    let coverage = glassbake_core::layout::transparent::COVERAGE;
    let hidden = inputs.transparent[2].clone();
    let [n, c, h, w] = hidden.dims();
    let hidden = hidden.slice_assign([0..n, coverage..coverage + 1, 0..h, 0..w], Tensor::zeros([n, 1, h, w], &device));
    inputs.transparent[2] = hidden;
    let mut without = inputs.clone();
    without.transparent.truncate(2);
    assert_eq!(c, glassbake_core::layout::TRANSPARENT_CHANNELS + glassbake_core::layout::THROUGH_CHANNELS);
    for masked in [true, false] {
        let config = NetConfig { terms_masked_by_coverage: masked, ..common::small_net(ModelKind::Glassnet, 1, 3) };
        let net = random_net(&config, 6, &device);
        let same = bits(net.forward(&inputs)) == bits(net.forward(&without));
        // Unmasked, h of the empty buffer still adds a term that depends on sigma.
        assert_eq!(same, masked, "masked = {masked}");
    }
}

#[test]
fn glassnet_output_is_bit_identical_under_every_permutation_on_the_cpu() {
    permutation_exactness(&Device::flex(), &[1, 2, 3, 4, 5, 6, 7, 8]);
}

#[test]
fn glassnet_output_is_bit_identical_under_permutation_on_wgpu_when_an_adapter_exists() {
    if !common::wgpu_adapter_exists() {
        return;
    }
    permutation_exactness(&Device::wgpu(Default::default()), &[1, 3, 8]);
}

#[test]
fn the_concat_baseline_depends_on_object_order() {
    // The counterpart of the exactness test: a model that is not symmetric is caught by it.
    let device = Device::flex();
    device.seed(5);
    let batch = common::batch(&[common::frame(7, 16, 3, 1)]);
    let net = random_net(&common::small_net(ModelKind::Concat, 1, 3), 5, &device);
    let mut inputs = batch.inputs(&device);
    let reference = bits(net.forward(&inputs));
    inputs.transparent.reverse();
    assert_ne!(bits(net.forward(&inputs)), reference);
}

#[test]
fn weights_round_trip_through_safetensors_with_pytorch_names() {
    let device = Device::flex();
    let config = common::small_net(ModelKind::Glassnet, 2, 2);
    device.seed(1);
    let net = GlassNet::new(&config, 1, &device).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let files = ModelFiles::prepare(
        dir.path(),
        ModelConfig {
            format_version: FORMAT_VERSION,
            network: Network::Glassnet(config.clone()),
            train: common::small_training(),
            data: common::synthetic_source(),
        },
    )
    .unwrap();
    write_weights(&net, &files, 0).unwrap();
    device.seed(2);
    let mut other = GlassNet::new(&config, 2, &device).unwrap();
    let batch = common::batch(&[common::frame(1, 16, 2, 2)]);
    let expected = bits(net.forward(&batch.inputs(&device)));
    assert_ne!(bits(other.forward(&batch.inputs(&device))), expected, "a differently seeded net must differ before loading");
    read_weights(&mut other, &files.weights_path()).unwrap();
    assert_eq!(bits(other.forward(&batch.inputs(&device))), expected);

    // Names and layouts as torch.nn would have them, read with the safetensors crate itself.
    let bytes = std::fs::read(files.weights_path()).unwrap();
    let tensors = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let conv = tensors.tensor("scene_encoder.encoder.0.first.conv.weight").unwrap();
    let encoded = glassbake_core::layout::OPAQUE_CHANNELS * config.encoded_width() + 2;
    assert_eq!(conv.shape(), &[4, encoded, 1, 1], "the input stem is a 1x1 convolution");
    assert!(tensors.tensor("scene_encoder.encoder.0.first.conv.bias").is_ok());
    let up = tensors.tensor("blending.up.0.weight").unwrap();
    assert_eq!(up.shape(), &[8, 4, 2, 2], "ConvTranspose2d weights are [in, out, kh, kw] as in PyTorch");
    assert!(tensors.names().iter().all(|n| !n.contains("config")));

    // A model directory for a different network is refused with the file named.
    let wrong = Naive::new(&common::small_net(ModelKind::Naive, 2, 2), 1, &device).unwrap();
    let mut wrong = wrong;
    let err = read_weights(&mut wrong, &files.weights_path()).unwrap_err();
    assert!(err.to_string().contains("glassnet.safetensors"), "{err}");
}

/// Each model type saves exactly its own modules, under their field names (what a model
/// directory's weights file holds), and `load_model` opens each as the network it saved.
#[test]
fn each_model_saves_its_own_modules_and_opens_as_the_same_network() {
    let device = Device::flex();
    let grid = Some(test_grid());
    let cases = [
        (ModelKind::Glassnet, grid.clone(), &["blending", "object_grid", "renderer", "scene_encoder", "scene_grid", "transparency_encoder"][..]),
        (ModelKind::Naive, grid, &["blending", "renderer", "scene_encoder", "scene_grid"][..]),
        (ModelKind::Concat, None, &["blending", "renderer", "scene_encoder", "transparency_encoder"][..]),
        (ModelKind::Pixelgen, None, &["pixel_generator"][..]),
    ];
    let frames = vec![common::frame(3, 16, 2, 2)];
    let inputs = common::batch(&frames).inputs(&device);
    for (kind, position_grid, modules) in cases {
        let config = NetConfig { position_grid, ..common::small_net(kind, 2, 2) };
        let net = random_net(&config, 4, &device);
        assert_eq!(net.kind(), kind);
        let dir = tempfile::tempdir().unwrap();
        let model = ModelConfig {
            format_version: FORMAT_VERSION,
            network: Network::Glassnet(config.clone()),
            train: common::small_training(),
            data: common::synthetic_source(),
        };
        let files = ModelFiles::prepare(dir.path(), model).unwrap();
        struct Save<'a>(&'a ModelFiles);
        impl ModelTask for Save<'_> {
            type Output = ();
            fn run<M: SceneModel + Trainable>(self, model: M) {
                write_weights(&glassbake_net::init::initialize(model, 4), self.0, 0).unwrap();
            }
        }
        with_new_model(&config, 4, &device, Save(&files)).unwrap();
        let bytes = std::fs::read(files.weights_path()).unwrap();
        let tensors = safetensors::SafeTensors::deserialize(&bytes).unwrap();
        let mut saved: Vec<String> = tensors.names().iter().map(|n| n.split('.').next().unwrap().to_string()).collect();
        saved.sort();
        saved.dedup();
        assert_eq!(saved, modules, "{kind:?}");
        let opened = glassbake_net::load_model(&config, &files.weights_path(), &device).unwrap();
        assert_eq!(opened.kind(), kind);
        assert_eq!(bits(opened.forward(&inputs)), bits(net.forward(&inputs)), "{kind:?}: opened weights differ from the saved ones");
    }
}

#[test]
fn a_model_of_the_previous_format_opens_only_if_it_reads_no_transparency_buffers() {
    // Formats 1 and 2 predate the transparency buffers' L_d and L_d_far, format 3 the glass
    // transmittance in R: a GlassNet or concat model of them was built for other inputs and
    // cannot run; a naive one never read them.
    let cases = [(ModelKind::Glassnet, false), (ModelKind::Concat, false), (ModelKind::Naive, true)];
    for (version, (kind, opens)) in [1, 2, 3].into_iter().flat_map(|v| cases.map(|c| (v, c))) {
        let dir = tempfile::tempdir().unwrap();
        let config = ModelConfig {
            format_version: version,
            network: Network::Glassnet(common::small_net(kind, 1, 2)),
            train: common::small_training(),
            data: common::synthetic_source(),
        };
        std::fs::write(dir.path().join("config.json"), serde_json::to_vec(&config).unwrap()).unwrap();
        std::fs::write(dir.path().join(config.network.weights_file()), b"").unwrap();
        match ModelFiles::open(dir.path()) {
            Ok(_) => assert!(opens, "{kind:?} of format {version} must be refused"),
            Err(err) => {
                assert!(!opens, "{kind:?} of format {version} must open: {err}");
                let err = err.to_string();
                assert!(err.contains("format_version") && err.contains("retrain"), "{err}");
            }
        }
    }
}

/// A demodulated R's output is `free + albedo * light` for each term: with F's code held fixed
/// the image is affine in the G-buffer's albedo, and moves with it; without demodulation the
/// albedo reaches the image only through F.
#[test]
fn demodulated_renderer_output_is_affine_in_the_albedo() {
    let device = Device::flex();
    device.seed(5);
    let frames: Vec<_> = (0..1).map(|i| common::frame(i, 16, 2, 2)).collect();
    let batch = common::batch(&frames);
    let inputs = batch.inputs(&device);
    for kind in [ModelKind::Glassnet, ModelKind::Naive] {
        for demodulated in [true, false] {
            let config = NetConfig { demodulated, ..common::small_net(kind, 2, 2) };
            assert_eq!(config.renderer_outputs(), if kind == ModelKind::Glassnet { 9 } else { 3 } * if demodulated { 2 } else { 1 });
            // Wake the transmitted terms, which start at zero, so they are tested too.
            let wake = |r: &mut glassbake_net::blocks::Renderer| {
                r.head.weight = r.head.weight.clone().map(|w| w.clone().random_like(burn::tensor::Distribution::Normal(0.0, 0.3)));
            };
            let albedo_times = |scene: &SceneCode, scale: f32| SceneCode { albedo: scene.albedo.clone().mul_scalar(scale), ..scene.clone() };
            let with_albedo: Box<dyn Fn(f32) -> Vec<f32>> = if kind == ModelKind::Glassnet {
                let mut net = GlassNet::new(&config, 9, &device).unwrap();
                wake(&mut net.renderer);
                let scene = net.encode_scene(inputs.gbuffer.clone(), inputs.light_coverage.clone(), inputs.values.clone());
                let mut sum = glassbake_net::sum::TransparencySum::new();
                for b in &inputs.transparent {
                    sum.add(net.transparency_term(&scene, b.clone()));
                }
                let [n, _, h, w] = scene.sigma.dims();
                let tau = sum.finish([n, config.transparency_encoder.out_channels + glassbake_net::model::GLASS_DIRECT_CHANNELS, h, w], &device);
                Box::new(move |scale| values(net.decode(&albedo_times(&scene, scale), tau.clone())))
            } else {
                let mut net = Naive::new(&config, 9, &device).unwrap();
                wake(&mut net.renderer);
                let scene = net.encode_scene(inputs.gbuffer.clone(), inputs.light_coverage.clone(), inputs.values.clone(), None);
                Box::new(move |scale| values(net.decode(&albedo_times(&scene, scale))))
            };
            let (zero, one, two) = (with_albedo(0.0), with_albedo(1.0), with_albedo(2.0));
            let largest_step = zero.iter().zip(&one).map(|(a, b)| (b - a).abs()).fold(0.0f32, f32::max);
            let curvature = zero.iter().zip(&one).zip(&two).map(|((a, b), c)| (c - 2.0 * b + a).abs()).fold(0.0f32, f32::max);
            if demodulated {
                assert!(largest_step > 1e-3, "{kind:?}: the albedo must reach the image ({largest_step})");
                assert!(curvature < 1e-5 * (1.0 + largest_step), "{kind:?}: not affine in the albedo ({curvature})");
            } else {
                assert_eq!(largest_step, 0.0, "{kind:?}: without demodulation R does not read the albedo");
            }
        }
    }
}

#[test]
fn a_format_4_model_opens_with_the_direct_rgb_renderer_it_was_trained_with() {
    // Format 4 had no `demodulated` field: such a config must load as a renderer that
    // predicts RGB directly, whatever today's presets choose.
    let dir = tempfile::tempdir().unwrap();
    let config = ModelConfig {
        format_version: 4,
        network: Network::Glassnet(NetConfig { demodulated: true, ..common::small_net(ModelKind::Glassnet, 1, 2) }),
        train: common::small_training(),
        data: common::synthetic_source(),
    };
    let mut json: serde_json::Value = serde_json::to_value(&config).unwrap();
    let network = json["network"].as_object_mut().unwrap();
    assert_eq!(network.remove("demodulated"), Some(serde_json::Value::Bool(true)));
    std::fs::write(dir.path().join("config.json"), serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::write(dir.path().join(config.network.weights_file()), b"").unwrap();
    let opened = ModelFiles::open(dir.path()).unwrap();
    match opened.config.network {
        Network::Glassnet(net) => assert!(!net.demodulated),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_format_7_glassnet_that_reads_through_buffers_is_refused_and_one_that_does_not_opens() {
    // Format 8's through buffers have a channel more and are averaged over the footprint: a
    // network trained on format 7's would read them shifted by a channel.
    for through in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let config = ModelConfig {
            format_version: 7,
            network: Network::Glassnet(NetConfig { through, ..common::small_net(ModelKind::Glassnet, 1, 2) }),
            train: common::small_training(),
            data: common::synthetic_source(),
        };
        std::fs::write(dir.path().join("config.json"), serde_json::to_vec(&config).unwrap()).unwrap();
        std::fs::write(dir.path().join(config.network.weights_file()), b"").unwrap();
        match ModelFiles::open(dir.path()) {
            Ok(_) => assert!(!through, "a format-7 network reading through buffers opened"),
            Err(e) => {
                assert!(through, "a format-7 network without through buffers was refused: {e}");
                let message = e.to_string();
                assert!(message.contains("format_version") && message.contains("retrain"), "{message}");
            }
        }
    }
}

#[test]
fn position_grids_replace_the_positions_fourier_features_and_learn() {
    let device = Device::flex().autodiff();
    device.seed(6);
    let frames = vec![common::frame(70, 16, 2, 1)];
    let batch = common::batch(&frames);
    let fourier = common::small_net(ModelKind::Glassnet, 1, 2);
    let config = NetConfig { position_grid: Some(test_grid()), ..fourier.clone() };
    // F's input: 14 Fourier-encoded channels, the raw position, the grid's 6 features, 1 variable.
    assert_eq!(config.encoded_buffer_width(glassbake_core::layout::OPAQUE_CHANNELS), 14 * fourier.encoded_width() + 3 + 6);
    let net = random_glassnet(&config, 2, &device);
    let grads = net.forward(&batch.inputs(&device)).sum().backward();
    for (name, grid) in [("scene", &net.scene_grid), ("object", &net.object_grid)] {
        let table = &grid.as_ref().unwrap().table;
        let gradient: Vec<f32> = table.grad(&grads).unwrap_or_else(|| panic!("{name} grid has no gradient")).into_data().try_to_vec::<f32>().unwrap();
        assert!(gradient.iter().filter(|g| g.abs() > 1e-7).count() >= 8, "{name} grid: too few entries get a gradient");
    }
    // The naive network has F's grid only; pixelgen refuses one.
    let naive = Naive::new(&NetConfig { position_grid: Some(test_grid()), ..common::small_net(ModelKind::Naive, 1, 2) }, 2, &device).unwrap();
    assert!(naive.scene_grid.is_some());
    let pixelgen = NetConfig { position_grid: Some(test_grid()), ..common::small_net(ModelKind::Pixelgen, 1, 2) };
    assert!(pixelgen.check("test").unwrap_err().to_string().contains("position_grid"));
    let both = NetConfig { saturate_direct_light: true, ..common::small_net(ModelKind::Glassnet, 1, 2) };
    assert!(both.light_coverage && both.check("test").unwrap_err().to_string().contains("light_coverage"));
}

/// Where the G-buffer's direct light (times the glass transmittance in front) reaches 1 in
/// every channel the image is exactly 1; everywhere else it is what the network predicts.
#[test]
fn pixels_whose_direct_light_saturates_are_white_and_the_rest_untouched() {
    use glassbake_core::layout::opaque::LD;
    use glassbake_core::layout::transparent::COVERAGE;
    let device = Device::flex();
    device.seed(12);
    let size = 16;
    for kind in [ModelKind::Glassnet, ModelKind::Naive] {
        let frames = vec![common::frame(80, size, 2, 1)];
        let batch = common::batch(&frames);
        let mut inputs = batch.inputs(&device);
        // An emitter: L_d of 5 in a 4x3 block, of 5 in two channels only at one more pixel.
        let mut gbuffer = values(inputs.gbuffer.clone());
        let at = |c: usize, y: usize, x: usize| (LD + c) * size * size + y * size + x;
        for (y, x) in (2..5).flat_map(|y| (6..10).map(move |x| (y, x))) {
            for c in 0..3 {
                gbuffer[at(c, y, x)] = 5.0;
            }
        }
        gbuffer[at(0, 8, 8)] = 5.0;
        gbuffer[at(1, 8, 8)] = 5.0;
        inputs.gbuffer = Tensor::from_data(TensorData::new(gbuffer, inputs.gbuffer.dims()), &device);
        // No glass in front of the emitter (GlassNet's test: glass elsewhere keeps its tint).
        for buffer in inputs.transparent.iter_mut() {
            let [n, _, h, _] = buffer.dims();
            *buffer = buffer.clone().slice_assign([0..n, COVERAGE..COVERAGE + 1, 0..h, 6..10], Tensor::zeros([n, 1, h, 4], &device));
        }
        let plain_config = NetConfig { saturate_direct_light: false, light_coverage: false, ..common::small_net(kind, 1, 2) };
        let plain = values(random_net(&plain_config, 4, &device).forward(&inputs));
        let saturating = values(random_net(&NetConfig { saturate_direct_light: true, ..plain_config }, 4, &device).forward(&inputs));
        for c in 0..3 {
            for y in 0..size {
                for x in 0..size {
                    let i = c * size * size + y * size + x;
                    if (2..5).contains(&y) && (6..10).contains(&x) {
                        assert_eq!(saturating[i], 1.0, "{kind:?}: emitter pixel ({x}, {y})");
                        assert_ne!(plain[i], 1.0, "{kind:?}: the network alone must not already draw it white");
                    } else {
                        assert_eq!(saturating[i].to_bits(), plain[i].to_bits(), "{kind:?}: pixel ({x}, {y}) channel {c}");
                    }
                }
            }
        }
    }
}

/// With the light coverage the image is light x t + (1 - coverage) x the network's image,
/// clamped to 1 where a light is seen (t the transmittance of the glass in front, computed
/// here independently; 1 for naive), and exactly the network's image where no light is.
#[test]
fn the_light_coverage_is_composited_over_the_image() {
    use glassbake_core::layout::light_coverage::{COVERAGE, LIGHT};
    use glassbake_core::layout::transparent;
    let device = Device::flex();
    let size = 16;
    for kind in [ModelKind::Glassnet, ModelKind::Naive] {
        let frames = vec![common::frame(81, size, 2, 1)];
        let mut inputs = common::batch(&frames).inputs(&device);
        let at = |c: usize, y: usize, x: usize| c * size * size + y * size + x;
        // A light of 5 covering a 3x4 block; a dim light over a quarter of one pixel; a bright
        // one over a sixteenth of another.
        let mut coverage = vec![0.0f32; 4 * size * size];
        let mut lit = vec![(0usize, 0usize, 0.0f32, [0.0f32; 3]); 0];
        for (y, x) in (2..5).flat_map(|y| (6..10).map(move |x| (y, x))) {
            lit.push((y, x, 1.0, [5.0; 3]));
        }
        lit.push((8, 8, 0.25, [0.5, 0.1, 0.2]));
        lit.push((12, 3, 1.0 / 16.0, [100.0; 3]));
        for &(y, x, covered, light) in &lit {
            coverage[at(COVERAGE, y, x)] = covered;
            for c in 0..3 {
                coverage[at(LIGHT + c, y, x)] = light[c];
            }
        }
        inputs.light_coverage = Some(Tensor::from_data(TensorData::new(coverage, [1, 4, size, size]), &device));
        let plain_config = NetConfig { light_coverage: false, saturate_direct_light: false, ..common::small_net(kind, 1, 2) };
        let plain = values(random_net(&plain_config, 5, &device).forward(&inputs));
        let composited = values(random_net(&NetConfig { light_coverage: true, ..plain_config }, 5, &device).forward(&inputs));
        let transmittance = |c: usize, i: usize| -> f64 {
            if kind == ModelKind::Naive {
                return 1.0;
            }
            let log_t: f64 = frames[0]
                .transparent
                .iter()
                .map(|b| b.plane(transparent::COVERAGE)[i] as f64 * (b.plane(transparent::ALBEDO + c)[i] as f64).clamp(1.0 / 256.0, 1.0).ln())
                .sum();
            log_t.exp()
        };
        for c in 0..3 {
            for y in 0..size {
                for x in 0..size {
                    let i = at(c, y, x);
                    match lit.iter().find(|l| (l.0, l.1) == (y, x)) {
                        Some(&(_, _, covered, light)) => {
                            let t = transmittance(c, y * size + x);
                            let want = (light[c] as f64 * t + (1.0 - covered as f64) * plain[i] as f64).min(1.0);
                            assert!((composited[i] as f64 - want).abs() < 1e-5, "{kind:?}: pixel ({x}, {y}) channel {c}: {} vs {want}", composited[i]);
                        }
                        None => assert_eq!(composited[i].to_bits(), plain[i].to_bits(), "{kind:?}: pixel ({x}, {y}) channel {c}"),
                    }
                }
            }
        }
        // The bright light makes its pixel white, the dim one does not.
        assert_eq!(composited[at(0, 12, 3)], 1.0, "{kind:?}");
        assert!(composited[at(1, 8, 8)] < 1.0, "{kind:?}");
    }
}

/// The super-sampler composites the full-resolution light coverage over its image as GlassNet
/// does: min(1, light + (1 - coverage) x its image) where a light is seen, its image elsewhere.
#[test]
fn the_super_sampler_composites_the_light_coverage_at_full_resolution() {
    use glassbake_net::{SuperSampler, SuperSamplerConfig};
    let device = Device::flex();
    let size = 8;
    let low = Tensor::<4>::random([1, 3, size / 2, size / 2], burn::tensor::Distribution::Uniform(0.0, 1.0), &device);
    let gbuffer = Tensor::<4>::random([1, 17, size, size], burn::tensor::Distribution::Uniform(0.0, 1.0), &device);
    let mut coverage = vec![0.0f32; 4 * size * size];
    let lit = [(1usize, 2usize, 1.0f32, 3.0f32), (5, 5, 0.25, 0.4), (6, 1, 0.0625, 20.0)];
    for &(y, x, covered, light) in &lit {
        coverage[y * size + x] = covered;
        for c in 1..4 {
            coverage[c * size * size + y * size + x] = light;
        }
    }
    let coverage = Tensor::<4>::from_data(TensorData::new(coverage, [1, 4, size, size]), &device);
    let plain_config = SuperSamplerConfig { light_coverage: false, ..common::small_super_sampler() };
    let plain = values(SuperSampler::new(&plain_config, 3, &device).forward(low.clone(), gbuffer.clone(), None));
    let composited_config = SuperSamplerConfig { light_coverage: true, ..plain_config };
    let composited = values(SuperSampler::new(&composited_config, 3, &device).forward(low, gbuffer, Some(coverage)));
    for c in 0..3 {
        for y in 0..size {
            for x in 0..size {
                let i = c * size * size + y * size + x;
                match lit.iter().find(|l| (l.0, l.1) == (y, x)) {
                    Some(&(_, _, covered, light)) => {
                        let want = (light + (1.0 - covered) * plain[i]).min(1.0);
                        assert!((composited[i] - want).abs() < 1e-6, "pixel ({x}, {y}) channel {c}: {} vs {want}", composited[i]);
                    }
                    None => assert_eq!(composited[i].to_bits(), plain[i].to_bits(), "pixel ({x}, {y}) channel {c}"),
                }
            }
        }
    }
}

/// With the light coverage the network reads L_d clamped to 1: an emitter of 5 and one of 50
/// give the same image (the composite's light comes from the coverage, not from L_d).
#[test]
fn with_the_light_coverage_direct_light_above_one_reads_as_one() {
    use glassbake_core::layout::opaque::LD;
    let device = Device::flex();
    let size = 16;
    let frames = vec![common::frame(82, size, 2, 1)];
    let inputs = common::batch(&frames).inputs(&device);
    let with_emitter = |radiance: f32| {
        let mut gbuffer = values(inputs.gbuffer.clone());
        for c in 0..3 {
            for x in 4..9 {
                gbuffer[(LD + c) * size * size + 3 * size + x] = radiance;
            }
        }
        NetInputs { gbuffer: Tensor::from_data(TensorData::new(gbuffer, inputs.gbuffer.dims()), &device), ..inputs.clone() }
    };
    for kind in [ModelKind::Glassnet, ModelKind::Naive] {
        let config = common::small_net(kind, 1, 2);
        assert!(config.light_coverage);
        let net = random_net(&config, 6, &device);
        assert_eq!(bits(net.forward(&with_emitter(5.0))), bits(net.forward(&with_emitter(50.0))), "{kind:?}");
        // Without the light coverage the radiance is read as it is.
        let plain = random_net(&NetConfig { light_coverage: false, ..config }, 6, &device);
        assert_ne!(bits(plain.forward(&with_emitter(5.0))), bits(plain.forward(&with_emitter(50.0))), "{kind:?}");
    }
}

/// `inputs` with every object's through channels (after its transparency buffer) times `scale`.
fn through_scaled(inputs: &NetInputs, scale: f32) -> NetInputs {
    use glassbake_core::layout::{THROUGH_CHANNELS, TRANSPARENT_CHANNELS};
    NetInputs {
        transparent: inputs
            .transparent
            .iter()
            .map(|b| Tensor::cat(vec![b.clone().narrow(1, 0, TRANSPARENT_CHANNELS), b.clone().narrow(1, TRANSPARENT_CHANNELS, THROUGH_CHANNELS) * scale], 1))
            .collect(),
        ..inputs.clone()
    }
}

/// GlassNet with `through` reads the through buffer after each transparency buffer (a change
/// there changes the image); a network without it reads only the transparency buffer (given
/// with or without the through channels, the image is the same to the last bit).
#[test]
fn through_buffers_reach_glassnet_only_when_it_reads_them() {
    use glassbake_core::layout::TRANSPARENT_CHANNELS;
    let device = Device::flex();
    let frames = vec![common::frame(91, 16, 2, 1)];
    let inputs = common::batch(&frames).inputs(&device);
    let with_through = |scale: f32| through_scaled(&inputs, scale);
    let without_through =
        NetInputs { transparent: inputs.transparent.iter().map(|b| b.clone().narrow(1, 0, TRANSPARENT_CHANNELS)).collect(), ..inputs.clone() };
    let config = common::small_net(ModelKind::Glassnet, 1, 2);
    assert!(config.through, "GlassNet's presets read the through buffers");
    // Trained weights: at initialisation h's head and R's glass inputs are zero.
    let mut net = random_glassnet(&config, 6, &device);
    let t = &mut net.transparency_encoder;
    t.head.weight = t.head.weight.clone().map(|w| w.ones_like() * 0.05);
    let r = &mut net.renderer;
    r.large.conv.weight = r.large.conv.weight.clone().map(|w| w.clone() + w.ones_like() * 0.01);
    assert_ne!(bits(net.forward(&with_through(1.0))), bits(net.forward(&with_through(0.5))));
    for kind in [ModelKind::Glassnet, ModelKind::Naive, ModelKind::Concat] {
        let config = NetConfig { through: false, ..common::small_net(kind, 1, 2) };
        let net = random_net(&config, 6, &device);
        let image = bits(net.forward(&with_through(1.0)));
        assert_eq!(image, bits(net.forward(&with_through(0.5))), "{kind:?}");
        assert_eq!(image, bits(net.forward(&without_through)), "{kind:?}");
    }
    // GlassNet and the naive baseline (its front-through ablation) read them, no other model.
    assert!(NetConfig { through: true, ..common::small_net(ModelKind::Naive, 1, 2) }.check("test").is_ok());
    assert!(NetConfig { through: true, ..common::small_net(ModelKind::Concat, 1, 2) }.check("test").is_err());
}

/// The front-most through buffer is, at each pixel, that of the covering object of least
/// depth, whatever the order the objects come in, and zeros where no object covers the pixel.
#[test]
fn the_front_through_buffer_is_the_nearest_covering_objects() {
    use glassbake_core::layout::{transparent, THROUGH_CHANNELS, TRANSPARENT_CHANNELS};
    let device = Device::flex();
    let (h, w) = (2, 3);
    let pixels = h * w;
    // Per object, per pixel: (coverage, depth). Object 2 is nearest at pixel 1 but does not
    // cover it; pixel 5 is covered by none.
    let objects: [[(f32, f32); 6]; 3] = [
        [(1.0, 5.0), (1.0, 4.0), (0.0, 0.0), (0.5, 2.0), (1.0, 9.0), (0.0, 0.0)],
        [(1.0, 3.0), (0.0, 0.0), (1.0, 7.0), (1.0, 1.0), (1.0, 8.0), (0.0, 0.0)],
        [(0.0, 1.0), (0.0, 1.0), (1.0, 6.0), (1.0, 2.5), (0.0, 0.0), (0.0, 0.0)],
    ];
    let expected_object = [Some(1), Some(0), Some(2), Some(1), Some(1), None];
    let through_value = |k: usize, c: usize, p: usize| (100 * (k + 1) + 10 * c + p) as f32;
    let buffers: Vec<Tensor<4>> = objects
        .iter()
        .enumerate()
        .map(|(k, object)| {
            let mut data = vec![0.0f32; (TRANSPARENT_CHANNELS + THROUGH_CHANNELS) * pixels];
            for (p, &(coverage, depth)) in object.iter().enumerate() {
                data[transparent::COVERAGE * pixels + p] = coverage;
                data[transparent::DEPTH * pixels + p] = depth;
                for c in 0..THROUGH_CHANNELS {
                    data[(TRANSPARENT_CHANNELS + c) * pixels + p] = through_value(k, c, p);
                }
            }
            Tensor::<4>::from_data(TensorData::new(data, [1, TRANSPARENT_CHANNELS + THROUGH_CHANNELS, h, w]), &device)
        })
        .collect();
    for order in [[0, 1, 2], [2, 0, 1], [1, 2, 0]] {
        let front = values(glassbake_net::model::front_through(order.iter().map(|&k| buffers[k].clone()), [1, h, w], &device));
        for p in 0..pixels {
            for c in 0..THROUGH_CHANNELS {
                let want = expected_object[p].map_or(0.0, |k| through_value(k, c, p));
                assert_eq!(front[c * pixels + p], want, "order {order:?}, pixel {p}, channel {c}");
            }
        }
    }
}

/// The naive baseline with `through` reads the front-most object's through buffer: a change
/// there changes its image, and the objects' order does not.
#[test]
fn the_front_through_ablation_reads_the_front_objects_through_buffer() {
    let device = Device::flex();
    let frames = vec![common::frame(93, 16, 3, 1)];
    let inputs = common::batch(&frames).inputs(&device);
    let scaled = |scale: f32| through_scaled(&inputs, scale);
    let config = NetConfig { through: true, ..common::small_net(ModelKind::Naive, 1, 3) };
    let net = random_net(&config, 7, &device);
    let image = bits(net.forward(&scaled(1.0)));
    assert_ne!(image, bits(net.forward(&scaled(0.5))));
    let mut reversed = scaled(1.0);
    reversed.transparent.reverse();
    assert_eq!(image, bits(net.forward(&reversed)));
}

/// h reads the scene code where each through hit lands on screen: at the pixel the offset
/// names, 0 where the hit is hidden or off the frame.
#[test]
fn sigma_is_read_where_the_through_hits_land() {
    let device = Device::flex();
    let (c, h, w) = (3, 5, 6);
    let sigma_values: Vec<f32> = (0..c * h * w).map(|i| i as f32 + 1.0).collect();
    let sigma = Tensor::<4>::from_data(TensorData::new(sigma_values.clone(), [1, c, h, w]), &device);
    // Every pixel looks 2 right and 1 up; pixel (0, 0) is hidden.
    let mut screen = vec![0.0f32; 3 * h * w];
    for i in 0..h * w {
        screen[i] = 2.0;
        screen[h * w + i] = -1.0;
        screen[2 * h * w + i] = 1.0;
    }
    screen[2 * h * w] = 0.0;
    let read = values(glassbake_net::model::sigma_at_hits(sigma, Tensor::from_data(TensorData::new(screen, [1, 3, h, w]), &device)));
    for ch in 0..c {
        for y in 0..h {
            for x in 0..w {
                let (tx, ty) = (x as i64 + 2, y as i64 - 1);
                let expected = if (x, y) == (0, 0) || tx >= w as i64 || ty < 0 { 0.0 } else { sigma_values[(ch * h + ty as usize) * w + tx as usize] };
                assert_eq!(read[(ch * h + y) * w + x], expected, "channel {ch} at ({x}, {y})");
            }
        }
    }
}
