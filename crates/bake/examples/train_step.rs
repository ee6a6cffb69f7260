//! Where one CPU training step of the `quick` networks goes: the whole step
//! as the training loop runs it, then forward + loss, backward and the AdamW update apart, then
//! each sub-network's forward pass and single convolutions at the shapes the step uses. Weights
//! are random and the data synthetic, so only time is measured; `tools/torch-compare` times the
//! same network in PyTorch on the same CPU.
//!
//!     cargo run --release -p glassbake-bake --example train_step -- [batch] [crop] [objects]

use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::module::{conv2d, conv_transpose2d};
use burn::tensor::ops::{ConvOptions, ConvTransposeOptions};
use burn::tensor::Distribution;
use glassbake_core::layout::{LIGHT_COVERAGE_CHANNELS, OPAQUE_CHANNELS, TRANSPARENT_CHANNELS};
use glassbake_net::blocks::positional_encoding;
use glassbake_net::burn;
use glassbake_net::loss::training_loss;
use glassbake_net::{GlassNet, ModelKind, Naive, NetConfig, NetInputs, SceneModel, Trainable};

const VARIABLES: usize = 4;

/// Median wall time of `runs` calls of `f` after two warm-up calls, in milliseconds.
fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    f();
    median(
        (0..runs)
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(|a, b| a.total_cmp(b));
    values[values.len() / 2]
}

/// Forces a tensor's computation (the backend may defer work until data is read).
fn sync(t: Tensor<4>) {
    let _ = t.sum().into_scalar::<f32>();
}

fn inputs(n: usize, side: usize, objects: usize, device: &Device) -> NetInputs {
    let uniform = |c: usize| Tensor::<4>::random([n, c, side, side], Distribution::Uniform(0.0, 1.0), device);
    NetInputs {
        gbuffer: uniform(OPAQUE_CHANNELS),
        // No light in view; the composite costs the same whatever the coverage.
        light_coverage: Some(Tensor::zeros([n, LIGHT_COVERAGE_CHANNELS, side, side], device)),
        transparent: (0..objects).map(|_| uniform(TRANSPARENT_CHANNELS)).collect(),
        values: Tensor::random([n, VARIABLES], Distribution::Uniform(0.0, 1.0), device),
    }
}

/// What one timed run trains on: `n` frames of `side` px with `objects` transparency buffers,
/// timed over `runs` steps.
#[derive(Clone, Copy)]
struct Shape {
    n: usize,
    side: usize,
    objects: usize,
    runs: usize,
}

/// Times whole training steps of `model` on synthetic data and prints them with their parts;
/// returns the model after them.
fn time_steps<M: SceneModel + Trainable>(mut model: M, Shape { n, side, objects, runs }: Shape, device: &Device) -> M {
    let params = model.num_params();
    let batch = inputs(n, side, objects, device);
    let target = Tensor::<4>::random([n, 3, side, side], Distribution::Uniform(0.0, 1.0), device);
    let mut optimizer = AdamWConfig::new().with_weight_decay(1e-4).init();

    // Each part timed inside whole steps, as training runs them: a forward pass without its
    // backward pass leaves the autodiff graph alive and is not what training costs.
    let mut parts: Vec<[f64; 4]> = Vec::new();
    for step in 0..runs + 2 {
        let start = Instant::now();
        let loss = training_loss(model.forward(&batch), target.clone(), 1.0);
        let _ = loss.clone().into_scalar::<f32>();
        let forward = start.elapsed().as_secs_f64() * 1e3;
        let gradients = GradientsParams::from_grads(loss.backward(), &model);
        let backward = start.elapsed().as_secs_f64() * 1e3 - forward;
        model = optimizer.step(1e-4, model.clone(), gradients);
        let whole = start.elapsed().as_secs_f64() * 1e3;
        if step >= 2 {
            parts.push([whole, forward, backward, whole - forward - backward]);
        }
    }
    let part = |i: usize| median(parts.iter().map(|p| p[i]).collect());
    let (whole, forward, backward, update) = (part(0), part(1), part(2), part(3));
    let pixels_per_s = (n * side * side) as f64 / (whole / 1e3);
    println!(
        "{:<8} {params:>7} params: step {whole:7.1} ms ({pixels_per_s:>6.0} px/s); medians of its parts: forward+loss {forward:6.1}, backward {backward:6.1}, AdamW {update:6.1}",
        model.kind().name(),
    );
    let prediction = Tensor::<4>::random([n, 3, side, side], Distribution::Uniform(0.0, 1.0), device).require_grad();
    let loss_ms = median_ms(runs, || {
        let _ = training_loss(prediction.clone(), target.clone(), 1.0).backward();
    });
    println!("         of it, the loss (L1 + SSIM) forward and backward {loss_ms:.1} ms");
    model
}

fn main() {
    // As the glassbake binary does.
    glassbake_net::keep_freed_memory();
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("arguments are numbers: batch crop objects")).collect();
    let (n, side, objects) = (args.first().copied().unwrap_or(4), args.get(1).copied().unwrap_or(32), args.get(2).copied().unwrap_or(4));
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("burn 0.22 flex, {threads} hardware threads; batch {n} x {side} px, {objects} transparency buffers, quick preset");
    let runs = 15;
    let quick = glassbake_bake::Preset::quick();

    for kind in [ModelKind::Glassnet, ModelKind::Naive] {
        let device = Device::flex().autodiff();
        device.seed(1);
        // tools/torch-compare builds the network without the through buffers.
        let config = NetConfig { through: false, ..NetConfig::new(&quick.network, &quick.name, kind, VARIABLES, objects).unwrap() };
        let shape = Shape { n, side, objects, runs };
        let inner = device.clone().inner();
        let batch = inputs(n, side, objects, &inner);
        let encoding_ms = median_ms(runs, || sync(positional_encoding(batch.gbuffer.clone(), config.encoding_frequencies)));
        let line = format!("         no-grad forward: positional encoding of the G-buffer {encoding_ms:.1} ms");
        // Forward passes of the parts, without autodiff.
        let line = match kind {
            ModelKind::Glassnet => {
                let net = time_steps(GlassNet::new(&config, 1, &device).unwrap(), shape, &device).valid();
                let f_ms = median_ms(runs, || sync(net.encode_scene(batch.gbuffer.clone(), batch.light_coverage.clone(), batch.values.clone()).sigma));
                let scene = net.encode_scene(batch.gbuffer.clone(), batch.light_coverage.clone(), batch.values.clone());
                let h_ms = median_ms(runs, || sync(net.transparency_term(&scene, batch.transparent[0].clone())));
                let tau = net.transparency_term(&scene, batch.transparent[0].clone());
                let decode_ms = median_ms(runs, || sync(net.decode(&scene, tau.clone())));
                format!(
                    "{line}, F {f_ms:.1} ms, h {h_ms:.1} ms per object, B+R {decode_ms:.1} ms, whole {:.1} ms",
                    median_ms(runs, || sync(net.forward(&batch)))
                )
            }
            _ => {
                let net = time_steps(Naive::new(&config, 1, &device).unwrap(), shape, &device).valid();
                let f_ms = median_ms(runs, || sync(net.encode_scene(batch.gbuffer.clone(), batch.light_coverage.clone(), batch.values.clone(), None).sigma));
                let scene = net.encode_scene(batch.gbuffer.clone(), batch.light_coverage.clone(), batch.values.clone(), None);
                let decode_ms = median_ms(runs, || sync(net.decode(&scene)));
                format!("{line}, F {f_ms:.1} ms, B+R {decode_ms:.1} ms, whole {:.1} ms", median_ms(runs, || sync(net.forward(&batch))))
            }
        };
        println!("{line}");
    }

    // Single convolutions at the shapes of the quick U-Nets' top level.
    let device = Device::flex();
    device.seed(2);
    let x = |c: usize, s: usize| Tensor::<4>::random([n, c, s, s], Distribution::Uniform(-1.0, 1.0), &device);
    let w = |o: usize, i: usize, k: usize| Tensor::<4>::random([o, i, k, k], Distribution::Uniform(-0.1, 0.1), &device);
    let shapes = [
        (12usize, 12usize, 3usize, side),
        (24, 12, 3, side),
        (24, 24, 3, side / 2),
        (48, 48, 3, side / 4),
        (157, 12, 1, side),
        (156, 12, 1, side),
        (15, 16, 5, side),
    ];
    for (cin, cout, k, s) in shapes {
        let (input, weight) = (x(cin, s), w(cout, cin, k));
        let padding = k / 2;
        let opts = ConvOptions::new([1, 1], [padding, padding], [1, 1], 1);
        let ms = median_ms(runs, || sync(conv2d(input.clone(), weight.clone(), None, opts.clone())));
        let gflops = 2.0 * (n * cout * cin * k * k * s * s) as f64 / (ms / 1e3) / 1e9;
        // The same convolution's backward pass: gradients for the input and the weights.
        let grad_device = device.clone().autodiff();
        let input_g = Tensor::<4>::random([n, cin, s, s], Distribution::Uniform(-1.0, 1.0), &grad_device).require_grad();
        let weight_g = Tensor::<4>::random([cout, cin, k, k], Distribution::Uniform(-0.1, 0.1), &grad_device).require_grad();
        let forward_backward = median_ms(runs, || {
            let _ = conv2d(input_g.clone(), weight_g.clone(), None, opts.clone()).sum().backward();
        });
        println!("conv2d {cin:>3}->{cout:<3} {k}x{k} at {s}x{s}: forward {ms:6.2} ms ({gflops:5.2} GFLOP/s), forward+backward {forward_backward:6.2} ms");
    }
    let (input, weight) = (x(24, side / 2), w(24, 12, 2));
    let opts = ConvTransposeOptions::new([2, 2], [0, 0], [0, 0], [1, 1], 1);
    let ms = median_ms(runs, || sync(conv_transpose2d(input.clone(), weight.clone(), None, opts.clone())));
    let gflops = 2.0 * (n * 24 * 12 * 4 * (side / 2) * (side / 2)) as f64 / (ms / 1e3) / 1e9;
    println!("conv_transpose2d 24->12 2x2 stride 2 from {}x{}: {ms:6.2} ms ({gflops:5.2} GFLOP/s)", side / 2, side / 2);
}
