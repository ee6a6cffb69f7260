//! Path-tracing throughput of the GPU tracer beside the CPU tracer on the built-in scenes:
//! samples (camera paths) per second, printed as a Markdown table.
//!
//! cargo run --release -p glassbake-trace-gpu --example gpu_trace_bench -- [--res 128] [--spp 64] [--no-cpu]
//!
//! Each scene is rendered as sample 0 of seed 0 (the camera and variable values a dataset
//! would use), with the plain estimator, all CPU threads. Times include the scene's upload
//! (GPU) or BVH build (CPU), as a dataset frame's would; the GPU kernel is compiled and
//! warmed up on one small render first. The adapter is the rasterizer's choice
//! (`WGPU_ADAPTER_NAME` picks another).

use glassbake_raster::RasterizerOptions;
use glassbake_scene::builtin::{builtin, BUILTIN_NAMES};
use glassbake_trace::{render, Estimator, TraceSettings};
use glassbake_trace_gpu::GpuTracer;

fn main() {
    let mut res = 128u32;
    let mut spp = 64u32;
    let mut with_cpu = true;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        if args[i] == "--no-cpu" {
            with_cpu = false;
            i += 1;
            continue;
        }
        let value = args.get(i + 1).and_then(|v| v.parse::<u32>().ok());
        match (args[i].as_str(), value) {
            ("--res", Some(v)) => res = v,
            ("--spp", Some(v)) => spp = v,
            _ => {
                eprintln!("usage: gpu_trace_bench [--res N] [--spp N] [--no-cpu]");
                std::process::exit(2);
            }
        }
        i += 2;
    }
    let tracer = GpuTracer::new(&RasterizerOptions::default()).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1);
    });
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("{res}x{res}, {spp} spp, sample 0 of seed 0, plain estimator; samples/s (camera paths per second)");
    println!("GPU: {}; CPU: {threads} threads\n", tracer.adapter_name());
    println!("| scene | GPU samples/s | GPU s | CPU samples/s | CPU s | GPU / CPU |");
    println!("|---|---|---|---|---|---|");
    for name in BUILTIN_NAMES {
        let scene = builtin(name).expect("built-in scene");
        let sample = scene.sample(0, 0);
        let instance = scene.instantiate(&sample.values).expect("sampled values are in range");
        let warm_up = TraceSettings { estimator: Estimator::PLAIN, ..TraceSettings::new(16, 16, 1, 1) };
        tracer.render(&instance, &sample.camera, &warm_up, None).expect("GPU render");
        let settings = TraceSettings { estimator: Estimator::PLAIN, ..TraceSettings::new(res, res, spp, 1) };
        let gpu = tracer.render(&instance, &sample.camera, &settings, None).expect("GPU render");
        let (gpu_rate, gpu_s) = (gpu.samples_per_second(), gpu.elapsed.as_secs_f64());
        if with_cpu {
            let cpu = render(&instance, &sample.camera, &settings, None).expect("CPU render");
            let (cpu_rate, cpu_s) = (cpu.samples_per_second(), cpu.elapsed.as_secs_f64());
            println!("| {name} | {gpu_rate:.0} | {gpu_s:.2} | {cpu_rate:.0} | {cpu_s:.2} | {:.2} |", gpu_rate / cpu_rate);
        } else {
            println!("| {name} | {gpu_rate:.0} | {gpu_s:.2} | - | - | - |");
        }
    }
}
