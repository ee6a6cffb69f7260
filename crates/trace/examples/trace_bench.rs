//! Path-tracing throughput on the built-in scenes: samples (camera paths) per second with
//! one thread and with all threads, printed as a Markdown table.
//!
//! cargo run --release -p glassbake-trace --example trace_bench -- [--res 128] [--spp 32]
//!
//! Each scene is rendered as sample 0 of seed 0 (the camera and variable values the dataset
//! would use). The time includes the BVH build, as a dataset render's would. On a shared
//! machine wall-clock rates understate the code's speed, so the single-thread render is also
//! rated by the CPU time the process consumed (Linux /proc, USER_HZ = 100).

use glassbake_scene::builtin::builtin;
use glassbake_trace::{render, TraceSettings};

fn main() {
    let mut res = 128u32;
    let mut spp = 32u32;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let value = args.get(i + 1).and_then(|v| v.parse::<u32>().ok());
        match (args[i].as_str(), value) {
            ("--res", Some(v)) => res = v,
            ("--spp", Some(v)) => spp = v,
            _ => {
                eprintln!("usage: trace_bench [--res N] [--spp N]");
                std::process::exit(2);
            }
        }
        i += 2;
    }
    let all_threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("{res}x{res}, {spp} spp, sample 0 of seed 0; samples/s (camera paths per second)\n");
    println!("| scene | triangles | 1 thread | 1 thread, per CPU second | {all_threads} threads |");
    println!("|---|---|---|---|---|");
    for name in ["cornell-glass", "cornellbox", "cornellbox8", "desk", "bathroom"] {
        let scene = builtin(name).expect("built-in scene");
        let sample = scene.sample(0, 0);
        let instance = scene.instantiate(&sample.values).expect("sampled values are in range");
        let rate = |threads: usize| {
            let settings = TraceSettings { threads: Some(threads), ..TraceSettings::new(res, res, spp, 1) };
            let cpu_before = process_cpu_seconds();
            let output = render(&instance, &sample.camera, &settings, None).expect("render");
            let cpu = process_cpu_seconds().zip(cpu_before).map(|(after, before)| after - before);
            (output.samples_per_second(), cpu.map(|c| output.samples as f64 / c.max(1e-3)))
        };
        let ((one, one_cpu), (all, _)) = (rate(1), rate(all_threads));
        let one_cpu = one_cpu.map_or("n/a".to_string(), |r| format!("{r:.0}"));
        println!("| {name} | {} | {one:.0} | {one_cpu} | {all:.0} |", instance.triangle_count());
    }
}

/// User + system CPU time of this process so far (Linux only).
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}
