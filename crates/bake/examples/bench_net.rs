//! GlassNet speed: one training step (batch 1) and one inference frame at each resolution and
//! transparent-object count, median over repeats after a warm-up, plus the peak heap the
//! streaming inference allocates beyond its inputs (constant in t is the point of T).
//!
//! cargo run --release -p glassbake-bake --example bench_net -- [--device cpu|wgpu]
//!     [--preset quick] [--res 128,256] [--objects 1,2,4,8] [--repeats 5]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use burn::prelude::*;
use burn::tensor::Distribution;
use glassbake_core::layout::{LIGHT_COVERAGE_CHANNELS, OPAQUE_CHANNELS};
use glassbake_net::loss::training_loss;
use glassbake_net::{burn, select_device, DeviceChoice, GlassNet, ModelKind, NetConfig, NetInputs, SceneModel};

fn arg<'a>(args: &'a [String], name: &str, default: &'a str) -> &'a str {
    args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).map_or(default, |s| s.as_str())
}

fn list(text: &str) -> Vec<usize> {
    text.split(',').map(|s| s.trim().parse().expect("a comma-separated list of numbers")).collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

/// Counts heap bytes so the bench can report the peak of one inference (CPU backend: tensors
/// live on the Rust heap).
struct CountingAllocator;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = CURRENT.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn mib(bytes: usize) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let choice = DeviceChoice::parse(arg(&args, "--device", "cpu")).unwrap();
    let preset = match args.iter().position(|a| a == "--preset").and_then(|i| args.get(i + 1)) {
        Some(name) => glassbake_bake::Preset::named(name).unwrap(),
        None => glassbake_bake::Preset::quick(),
    };
    let resolutions = list(arg(&args, "--res", "128,256"));
    let objects = list(arg(&args, "--objects", "1,2,4,8"));
    let repeats: usize = arg(&args, "--repeats", "5").parse().unwrap();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("GlassNet ({} preset) on {} ({threads} hardware threads), median of {repeats} after 1 warm-up", preset.name, choice.name());
    println!("| res | t | train step (ms, batch 1) | inference (ms/frame) | inference FPS | inference peak heap above inputs (MiB) |");
    println!("|---|---|---|---|---|---|");
    for &res in &resolutions {
        for &t in &objects {
            let config = NetConfig::new(&preset.network, &preset.name, ModelKind::Glassnet, 4, t).unwrap();
            let train_device = select_device(choice, 0, true);
            let net = GlassNet::new(&config, 0, &train_device).unwrap();
            let inputs = |device: &Device| NetInputs {
                gbuffer: Tensor::random([1, OPAQUE_CHANNELS, res, res], Distribution::Uniform(0.0, 1.0), device),
                // No light in view; the composite costs the same whatever the coverage.
                light_coverage: Some(Tensor::zeros([1, LIGHT_COVERAGE_CHANNELS, res, res], device)),
                transparent: (0..t).map(|_| Tensor::random([1, config.object_channels(), res, res], Distribution::Uniform(0.0, 1.0), device)).collect(),
                values: Tensor::random([1, 4], Distribution::Uniform(0.0, 1.0), device),
            };
            let train_inputs = inputs(&train_device);
            let target = Tensor::<4>::random([1, 3, res, res], Distribution::Uniform(0.0, 1.0), &train_device);
            let mut train_times = Vec::new();
            for i in 0..=repeats {
                let start = Instant::now();
                let loss = training_loss(net.forward(&train_inputs), target.clone(), 1.0);
                let grads = loss.backward();
                drop(grads);
                train_device.sync().unwrap();
                if i > 0 {
                    train_times.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            drop(train_inputs);
            let device = select_device(choice, 0, false);
            let net = net.valid();
            let frame = inputs(&device);
            let mut infer_times = Vec::new();
            let mut peak_above_inputs = 0;
            for i in 0..=repeats {
                let baseline = CURRENT.load(Ordering::Relaxed);
                PEAK.store(baseline, Ordering::Relaxed);
                let start = Instant::now();
                // The streaming path: one transparency buffer alive at a time.
                let image = net.forward_streaming(frame.gbuffer.clone(), frame.light_coverage.clone(), frame.values.clone(), t, &mut |k| {
                    Some(frame.transparent[k].clone())
                });
                let _ = image.into_data();
                if i > 0 {
                    infer_times.push(start.elapsed().as_secs_f64() * 1e3);
                    peak_above_inputs = peak_above_inputs.max(PEAK.load(Ordering::Relaxed) - baseline);
                }
            }
            let (train_ms, infer_ms) = (median(train_times), median(infer_times));
            println!("| {res} | {t} | {train_ms:.1} | {infer_ms:.1} | {:.1} | {:.1} |", 1e3 / infer_ms, mib(peak_above_inputs));
        }
    }
}
