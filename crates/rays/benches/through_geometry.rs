//! The BVH work a real-time frame does when a variable moves an object or a light: the
//! through rays' BVHs built anew against refit to the new positions, for the CPU caster and
//! for the GPU pass (its host side and upload, on the first Vulkan adapter, lavapipe on a
//! machine without a GPU). `cargo bench -p glassbake-rays --bench through_geometry`.

use criterion::{criterion_group, criterion_main, Criterion};
use glassbake_rays::through::ThroughScene;
use glassbake_rays::through_gpu::GpuThroughPass;
use glassbake_scene::builtin::builtin;
use glassbake_scene::Scene;

/// The scene at either end of its variables' ranges: every translation at its other end.
fn two_instances(name: &str) -> (Scene, Scene) {
    let base = builtin(name).expect("a built-in scene");
    let (low, high): (Vec<f32>, Vec<f32>) = base.variables.iter().map(|v| (v.min, v.max)).unzip();
    (base.instantiate(&low).unwrap(), base.instantiate(&high).unwrap())
}

fn gpu_pass() -> Option<(GpuThroughPass, wgpu::Device, wgpu::Queue)> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor { backends: wgpu::Backends::VULKAN, ..wgpu::InstanceDescriptor::new_without_display_handle() });
    let adapter = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN)).into_iter().next()?;
    let descriptor = wgpu::DeviceDescriptor { required_limits: adapter.limits(), ..Default::default() };
    let (device, queue) = pollster::block_on(adapter.request_device(&descriptor)).ok()?;
    Some((GpuThroughPass::new(device.clone(), queue.clone()).ok()?, device, queue))
}

fn through_geometry(c: &mut Criterion) {
    let pass = gpu_pass();
    if pass.is_none() {
        eprintln!("no Vulkan adapter: the GPU pass's rows are left out");
    }
    // cornellbox8: glass, an opaque sphere and the light move; desk: only hues change.
    for name in ["cornellbox8", "desk"] {
        let (a, b) = two_instances(name);
        let mut group = c.benchmark_group(name);
        group.sample_size(20);
        group.bench_function("CPU BVHs built", |bench| bench.iter(|| ThroughScene::build(&b)));
        let mut kept = Some(ThroughScene::build(&a));
        let mut flip = false;
        group.bench_function("CPU BVHs refit", |bench| {
            bench.iter(|| {
                flip = !flip;
                kept = Some(kept.take().expect("kept").refit_or_build(if flip { &b } else { &a }));
            })
        });
        if let Some((pass, device, queue)) = &pass {
            // An empty submission sends the staged writes, so they do not pile up.
            let flush = || queue.submit([]);
            group.bench_function("GPU BVHs built and uploaded", |bench| {
                bench.iter(|| {
                    let uploaded = pass.upload(&b).unwrap();
                    flush();
                    uploaded
                })
            });
            let mut kept = Some(pass.upload(&a).unwrap());
            group.bench_function("GPU BVHs refit and written", |bench| {
                bench.iter(|| {
                    flip = !flip;
                    kept = Some(pass.upload_reusing(if flip { &b } else { &a }, kept.take()).unwrap());
                    flush();
                })
            });
            device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
        }
        group.finish();
    }
}

criterion_group!(benches, through_geometry);
criterion_main!(benches);
