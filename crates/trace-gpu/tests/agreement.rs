//! The GPU tracer against the CPU tracer it ports: the BSDF case by case on identical
//! inputs, and whole images of every built-in scene, which must agree up to Monte Carlo
//! noise (image means within 2%, 8x8-block differences consistent with the noise measured
//! from independent seeds). Runs on whatever Vulkan adapter is present (lavapipe in CI).

use std::sync::OnceLock;

use glam::{Vec2, Vec3};
use glassbake_core::PlanarImage;
use glassbake_raster::RasterizerOptions;
use glassbake_scene::builtin::{builtin, BUILTIN_NAMES};
use glassbake_scene::Transmission;
use glassbake_trace::{render, Bsdf, Integrator, MaterialModel, SurfaceMaterial, TraceSettings};
use glassbake_trace_gpu::probe::{probe_bsdf, ProbeCase};
use glassbake_trace_gpu::GpuTracer;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn tracer() -> &'static GpuTracer {
    static TRACER: OnceLock<GpuTracer> = OnceLock::new();
    TRACER.get_or_init(|| GpuTracer::new(&RasterizerOptions::default()).expect("a Vulkan adapter (lavapipe: mesa-vulkan-drivers)"))
}

fn unit(rng: &mut ChaCha8Rng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

/// Every kind of surface the CPU BSDF distinguishes.
fn materials() -> Vec<(&'static str, SurfaceMaterial)> {
    let glass =
        |roughness: f32, thin: bool| SurfaceMaterial::new(Vec3::new(0.9, 0.95, 1.0), roughness, 0.0, Some(Transmission { weight: 1.0, ior: 1.5, thin }));
    let mut specular_tinted = SurfaceMaterial::new(Vec3::new(0.7, 0.3, 0.2), 0.4, 0.0, None);
    specular_tinted.specular = 0.6;
    specular_tinted.specular_color = Vec3::new(1.0, 0.5, 2.0);
    vec![
        ("default opaque", SurfaceMaterial::new(Vec3::new(0.8, 0.6, 0.3), 0.5, 0.0, None)),
        ("glossy opaque", SurfaceMaterial::new(Vec3::new(0.2, 0.5, 0.8), 0.08, 0.0, None)),
        ("metal", SurfaceMaterial::new(Vec3::new(0.95, 0.7, 0.4), 0.3, 1.0, None)),
        ("half metal", SurfaceMaterial::new(Vec3::new(0.5, 0.5, 0.5), 0.6, 0.5, None)),
        ("specular extension", specular_tinted),
        ("smooth glass", glass(0.0, false)),
        ("rough glass", glass(0.3, false)),
        ("thin pane", glass(0.0, true)),
        ("rough thin pane", glass(0.25, true)),
        ("half transmissive", SurfaceMaterial::new(Vec3::new(0.6, 0.8, 0.6), 0.2, 0.0, Some(Transmission { weight: 0.5, ior: 1.33, thin: false }))),
    ]
}

/// |a - b| small relative to the larger magnitude (with an absolute floor for values near 0).
fn close(a: f32, b: f32, relative: f32) -> bool {
    (a - b).abs() <= relative * a.abs().max(b.abs()).max(1e-3)
}

fn close3(a: Vec3, b: Vec3, relative: f32) -> bool {
    (0..3).all(|i| close(a[i], b[i], relative))
}

/// How closely two f32 evaluations of a material's lobes can agree. GGX's D near its peak is
/// a^2 / (pi (a^2 + sin^2 theta (1 - a^2))^2): a rounding of cos^2 theta by a few ulps of 1
/// moves the denominator by that much against a^2, so the relative error of D (and of the
/// density and weight built on it) grows as eps / alpha^2 for narrow lobes.
fn tolerance(material: &SurfaceMaterial) -> f32 {
    let alpha = (material.roughness * material.roughness).max(1e-3);
    2e-3 + 16.0 * f32::EPSILON / (alpha * alpha)
}

#[test]
fn gpu_bsdf_matches_the_cpu_bsdf_on_the_same_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut cases = Vec::new();
    for (_, material) in materials() {
        for lambertian in [false, true] {
            for _ in 0..300 {
                cases.push(ProbeCase {
                    material,
                    normal: unit(&mut rng),
                    lambertian,
                    wo: unit(&mut rng),
                    wi: unit(&mut rng),
                    u_lobe: rng.random(),
                    u_event: rng.random(),
                    u: Vec2::new(rng.random(), rng.random()),
                });
            }
        }
    }
    let results = probe_bsdf(tracer(), &cases).unwrap();
    assert_eq!(results.len(), cases.len());
    let names = materials();
    // f32 rounding differs between the two compilers (and GPU sin/cos/sqrt are not libm's),
    // so values agree to `tolerance`; decisions taken on exactly those values (which lobe,
    // which side) may flip for a handful of inputs that sit on a threshold.
    let mut flipped = 0;
    let mut samples_compared = 0;
    for (k, (case, gpu)) in cases.iter().zip(&results).enumerate() {
        let name = names[k / 600].0;
        let model = if case.lambertian { MaterialModel::Lambertian } else { MaterialModel::Gltf };
        let cpu = Bsdf::new(&case.material, case.normal, model);
        let tol = tolerance(&case.material);
        let (f, pdf) = cpu.eval_pdf(case.wo, case.wi);
        assert!(close3(f, gpu.eval, tol), "{name} case {k}: eval CPU {f} GPU {}", gpu.eval);
        assert!(close(pdf, gpu.pdf, tol), "{name} case {k}: pdf CPU {pdf} GPU {}", gpu.pdf);
        match (cpu.pass_through(case.wo), gpu.pass_through) {
            (None, None) => {}
            (Some((t, p)), Some((tg, pg))) => assert!(close3(t, tg, 2e-3) && close(p, pg, 2e-3), "{name} case {k}: pass-through"),
            other => panic!("{name} case {k}: pass-through CPU/GPU {other:?}"),
        }
        match (cpu.sample(case.wo, case.u_lobe, case.u_event, case.u), gpu.sample) {
            (None, None) => {}
            (Some(c), Some(g)) => {
                let same_event = c.delta == g.delta && c.transmitted == g.transmitted && c.pass_through == g.pass_through;
                if !same_event || (c.wi - g.wi).length() > 1e-2 {
                    flipped += 1;
                    continue;
                }
                samples_compared += 1;
                assert!((c.wi - g.wi).length() < 2e-3, "{name} case {k}: wi CPU {} GPU {}", c.wi, g.wi);
                assert_eq!(c.etap, g.etap, "{name} case {k}: etap");
                // A delta event's weight and probability are smooth in wo; a lobe's density is
                // not (a narrow GGX peak turns a 1e-6 difference in the sampled direction into
                // percents), so the GPU's sample is checked against the CPU BSDF at the
                // direction the GPU drew.
                let (weight, pdf) = if c.delta {
                    (c.weight, c.pdf)
                } else {
                    let (f, pdf) = cpu.eval_pdf(case.wo, g.wi);
                    (f * g.wi.dot(case.normal).abs() / pdf, pdf)
                };
                assert!(close3(weight, g.weight, tol), "{name} case {k}: weight CPU {weight} GPU {}", g.weight);
                assert!(close(pdf, g.pdf, tol), "{name} case {k}: sample pdf CPU {pdf} GPU {}", g.pdf);
            }
            _ => flipped += 1,
        }
    }
    eprintln!("{} cases: {samples_compared} samples compared, {flipped} took another event", cases.len());
    assert!(flipped * 200 <= cases.len(), "{flipped} of {} samples took another event on the GPU", cases.len());
    assert!(samples_compared * 2 > cases.len(), "only {samples_compared} samples could be compared");
}

/// Per-pixel green-channel values.
fn green(image: &PlanarImage) -> Vec<f64> {
    let (w, h) = (image.width(), image.height());
    (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| image.get(1, x, y) as f64).collect()
}

fn mean_rgb(image: &PlanarImage) -> f64 {
    let (w, h) = (image.width(), image.height());
    let mut sum = 0.0;
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                sum += image.get(c, x, y) as f64;
            }
        }
    }
    sum / (3 * w * h) as f64
}

/// Two renders with independent seeds, as (their average, per-pixel variance of the
/// average estimated from their difference).
fn two_seeds(render_one: impl Fn(u64) -> PlanarImage) -> (Vec<f64>, Vec<f64>, f64) {
    let (a, b) = (render_one(11), render_one(12));
    let (ga, gb) = (green(&a), green(&b));
    let average = ga.iter().zip(&gb).map(|(x, y)| 0.5 * (x + y)).collect();
    // Var(a - b) = 2 s^2 for one render's variance s^2; the average has s^2 / 2.
    let variance = ga.iter().zip(&gb).map(|(x, y)| (x - y) * (x - y) / 4.0).collect();
    (average, variance, 0.5 * (mean_rgb(&a) + mean_rgb(&b)))
}

/// The largest |z| over 8x8 blocks of the difference between two images with per-pixel
/// variances, and the share of blocks beyond 3.
fn block_z(width: u32, a: &(Vec<f64>, Vec<f64>, f64), b: &(Vec<f64>, Vec<f64>, f64)) -> (f64, f64) {
    let height = a.0.len() as u32 / width;
    let (mut worst, mut beyond, mut blocks) = (0.0f64, 0, 0);
    for by in (0..height).step_by(8) {
        for bx in (0..width).step_by(8) {
            let (mut diff, mut variance, mut n) = (0.0, 0.0, 0.0);
            for y in by..(by + 8).min(height) {
                for x in bx..(bx + 8).min(width) {
                    let i = (y * width + x) as usize;
                    diff += a.0[i] - b.0[i];
                    variance += a.1[i] + b.1[i];
                    n += 1.0;
                }
            }
            blocks += 1;
            if variance <= 0.0 {
                // No noise on either side (a constant region): the values must match closely.
                assert!((diff / n).abs() < 1e-4, "noise-free block ({bx}, {by}) differs by {}", diff / n);
                continue;
            }
            let z = (diff / variance.sqrt()).abs();
            worst = worst.max(z);
            if z > 3.0 {
                beyond += 1;
            }
        }
    }
    (worst, beyond as f64 / blocks as f64)
}

fn compare_with_cpu(name: &str, integrator: Integrator) {
    let scene = builtin(name).unwrap();
    let sample = scene.sample(0, 3);
    let instance = scene.instantiate(&sample.values).unwrap();
    let (res, spp) = (48, 256);
    let settings = |seed: u64| {
        let mut s = TraceSettings::new(res, res, spp, seed);
        s.integrator = integrator;
        s
    };
    let cpu = two_seeds(|seed| render(&instance, &sample.camera, &settings(seed), None).unwrap().image);
    let gpu = two_seeds(|seed| {
        let out = tracer().render(&instance, &sample.camera, &settings(seed), None).unwrap();
        assert_eq!(out.samples, (res * res * spp) as u64);
        out.image
    });
    let (cpu_mean, gpu_mean) = (cpu.2, gpu.2);
    assert!(cpu_mean > 1e-3, "{name}: the CPU image is black");
    let ratio = gpu_mean / cpu_mean;
    let (worst, share) = block_z(res, &cpu, &gpu);
    eprintln!("{name} ({}): GPU/CPU mean {ratio:.4}, worst block |z| {worst:.2}, blocks beyond 3: {:.1}%", integrator.name(), share * 100.0);
    assert!((ratio - 1.0).abs() < 0.02, "{name}: GPU mean {gpu_mean} vs CPU {cpu_mean}");
    // Heavy-tailed noise (caustic fireflies) makes some blocks' variance estimates small;
    // under agreement a few percent of blocks may pass |z| 3, none should pass 6.
    assert!(share <= 0.08 && worst < 6.0, "{name}: blocks disagree beyond noise (worst |z| {worst:.2}, {:.1}% beyond 3)", share * 100.0);
}

#[test]
fn every_builtin_scene_matches_the_cpu_tracer() {
    for name in BUILTIN_NAMES {
        compare_with_cpu(name, Integrator::Plain);
    }
}

#[test]
fn solid_angle_light_sampling_matches_the_cpu_tracer() {
    compare_with_cpu("cornell-glass", Integrator::SolidAngle);
}

#[test]
fn images_are_deterministic_and_the_guided_estimator_is_refused() {
    let scene = builtin("cornellbox").unwrap();
    let sample = scene.sample(0, 1);
    let instance = scene.instantiate(&sample.values).unwrap();
    let settings = TraceSettings::new(24, 16, 8, 5);
    let a = tracer().render(&instance, &sample.camera, &settings, None).unwrap();
    let b = tracer().render(&instance, &sample.camera, &settings, None).unwrap();
    assert_eq!(a.image, b.image, "two renders with one seed differ");
    let other = TraceSettings { seed: 6, ..settings.clone() };
    let c = tracer().render(&instance, &sample.camera, &other, None).unwrap();
    assert_ne!(a.image, c.image, "another seed gave the same image");

    let guided = TraceSettings { integrator: Integrator::Guided, ..settings };
    let err = tracer().render(&instance, &sample.camera, &guided, None).err().expect("guided must be refused").to_string();
    assert!(err.contains("guided") && err.contains("CPU"), "{err}");
}
