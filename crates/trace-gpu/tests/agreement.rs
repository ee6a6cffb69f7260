//! The GPU tracer against the CPU tracer it ports: the BSDF case by case on identical
//! inputs, and whole images of every built-in scene with the plain estimator, which must
//! agree up to Monte Carlo noise: image means within 2%, 8x8-block differences consistent with
//! the noise measured from independent seeds, region means (the pixels that show glass, the
//! rest) consistent on every channel, and the same noise (a change that only adds or removes
//! variance fails). Runs on whatever Vulkan adapter is present (lavapipe in CI).

use std::sync::OnceLock;

use glam::{Vec2, Vec3};
use glassbake_core::PlanarImage;
use glassbake_raster::RasterizerOptions;
use glassbake_scene::builtin::{builtin, BUILTIN_NAMES};
use glassbake_scene::Transmission;
use glassbake_trace::{glass_pixels, render, transparent_object_per_pixel, Bsdf, Estimator, MaterialModel, PreparedScene, SurfaceMaterial, TraceSettings};
use glassbake_trace_gpu::probe::{probe_bsdf, probe_lights, LightProbeCase, ProbeCase};
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

/// The GPU light sampler against the CPU's (the plain estimator's: by area, picked by power)
/// on identical inputs: from points on the surfaces each built-in scene's camera sees, the
/// same emitter, point, direction, radiance and density, and `light_pdf` (what MIS reads for
/// a BSDF-sampled hit of the light) equal to the sample's density.
#[test]
fn gpu_light_sampling_matches_the_cpu_light_sampler() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for name in BUILTIN_NAMES {
        let scene = builtin(name).unwrap();
        let sample = scene.sample(0, 2);
        let instance = scene.instantiate(&sample.values).unwrap();
        let prepared = PreparedScene::new(&instance);
        let cases: Vec<LightProbeCase> = (0..2000)
            .filter_map(|_| {
                let ray = sample.camera.ray(rng.random_range(0.0..64.0), rng.random_range(0.0..64.0), 64, 64);
                let hit = prepared.intersect(&ray)?;
                let shading_point = glassbake_trace::prepared::offset_origin(hit.position, hit.geometric_normal, -ray.direction);
                Some(LightProbeCase { shading_point, u_select: rng.random(), u: Vec2::new(rng.random(), rng.random()) })
            })
            .collect();
        let gpu = probe_lights(tracer(), &instance, &cases).unwrap();
        let (mut compared, mut flipped) = (0, 0);
        for (case, gpu) in cases.iter().zip(&gpu) {
            let cpu = prepared.lights.sample(case.shading_point, case.u_select, case.u);
            let (Some(cpu), Some(g)) = (cpu, gpu.sample) else {
                // A sample right at a light's horizon may be drawn on one side only.
                flipped += (cpu.is_some() != gpu.sample.is_some()) as usize;
                continue;
            };
            compared += 1;
            let scale = case.shading_point.abs().max_element().max(1.0);
            let what = format!("{name}, {case:?}: CPU {cpu:?}, GPU {g:?}");
            assert!((cpu.point - g.point).length() < 1e-4 * scale, "point: {what}");
            assert!(cpu.wi.dot(g.wi) > 1.0 - 1e-5, "direction: {what}");
            assert!(close3(cpu.radiance, g.radiance, 1e-5), "radiance: {what}");
            assert!(close(cpu.pdf, g.pdf, 1e-3), "pdf: {what}");
            assert!(close(g.pdf_at_point, g.pdf, 1e-3), "light_pdf at the sampled point: {what}");
            let cpu_pdf_at_point = prepared.lights.pdf(gpu.emitter, case.shading_point, cpu.point);
            assert!(close(cpu_pdf_at_point, cpu.pdf, 1e-3), "the GPU picked emitter {} but the CPU another: {what}", gpu.emitter);
        }
        eprintln!("{name}: {} light samples, {compared} compared, {flipped} drawn on one side only", cases.len());
        assert!(compared * 2 > cases.len(), "{name}: only {compared} of {} samples could be compared", cases.len());
        assert!(flipped * 200 <= cases.len(), "{name}: {flipped} samples drawn on one side only");
    }
}

/// Two renders with independent seeds: per channel and pixel, their average and the variance
/// of that average estimated from their difference; and the image's mean over all channels.
struct TwoSeeds {
    average: [Vec<f64>; 3],
    variance: [Vec<f64>; 3],
    mean: f64,
}

fn two_seeds(render_one: impl Fn(u64) -> PlanarImage) -> TwoSeeds {
    let (a, b) = (render_one(11), render_one(12));
    let plane = |image: &PlanarImage, c: usize| -> Vec<f64> { image.plane(c).iter().map(|&v| v as f64).collect() };
    let average = std::array::from_fn(|c| plane(&a, c).iter().zip(plane(&b, c)).map(|(x, y)| 0.5 * (x + y)).collect());
    // Var(a - b) = 2 s^2 for one render's variance s^2; the average has s^2 / 2.
    let variance = std::array::from_fn(|c| plane(&a, c).iter().zip(plane(&b, c)).map(|(x, y)| (x - y) * (x - y) / 4.0).collect());
    let mean = (0..3).map(|c| plane(&a, c).iter().chain(&plane(&b, c)).sum::<f64>()).sum::<f64>() / (6 * a.plane(0).len()) as f64;
    TwoSeeds { average, variance, mean }
}

/// The largest |z| over 8x8 blocks of the green channels' difference, and the share of blocks
/// beyond 3.
fn block_z(width: u32, a: &TwoSeeds, b: &TwoSeeds) -> (f64, f64) {
    let height = a.average[1].len() as u32 / width;
    let (mut worst, mut beyond, mut blocks) = (0.0f64, 0, 0);
    for by in (0..height).step_by(8) {
        for bx in (0..width).step_by(8) {
            let (mut diff, mut variance, mut n) = (0.0, 0.0, 0.0);
            for y in by..(by + 8).min(height) {
                for x in bx..(bx + 8).min(width) {
                    let i = (y * width + x) as usize;
                    diff += a.average[1][i] - b.average[1][i];
                    variance += a.variance[1][i] + b.variance[1][i];
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

/// Pixels a region needs before its noise is compared: the trimmed mean below has a relative
/// spread of about 0.8 / sqrt(pixels) per render, 5% at 256 pixels.
const MIN_NOISE_PIXELS: usize = 256;

/// Per region of `in_region` pixels and channel: the z of the region means' difference, and
/// the ratio of the two tracers' noise, each the mean over the region of |seed 11 - seed 12|
/// with the largest 2% left out (a firefly must not decide it); `None` for the ratio of a
/// region under [`MIN_NOISE_PIXELS`], and for a region without pixels.
fn region_agreement(a: &TwoSeeds, b: &TwoSeeds, in_region: &[bool]) -> Option<[(f64, Option<f64>); 3]> {
    let pixels: Vec<usize> = (0..in_region.len()).filter(|&i| in_region[i]).collect();
    if pixels.is_empty() {
        return None;
    }
    let trimmed_noise = |renders: &TwoSeeds, c: usize| {
        // |x - y| = 2 sqrt(variance of the average).
        let mut spread: Vec<f64> = pixels.iter().map(|&i| 2.0 * renders.variance[c][i].sqrt()).collect();
        spread.sort_by(f64::total_cmp);
        let kept = &spread[..spread.len() - spread.len() / 50];
        kept.iter().sum::<f64>() / kept.len() as f64
    };
    Some(std::array::from_fn(|c| {
        let (mut diff, mut variance) = (0.0, 0.0);
        for &i in &pixels {
            diff += a.average[c][i] - b.average[c][i];
            variance += a.variance[c][i] + b.variance[c][i];
        }
        let z = if variance > 0.0 { (diff / variance.sqrt()).abs() } else { diff.abs() * 1e4 };
        let noise_ratio = (pixels.len() >= MIN_NOISE_PIXELS).then(|| {
            let (noise_a, noise_b) = (trimmed_noise(a, c), trimmed_noise(b, c));
            if noise_a > 0.0 {
                noise_b / noise_a
            } else if noise_b == 0.0 {
                1.0
            } else {
                f64::INFINITY
            }
        });
        (z, noise_ratio)
    }))
}

/// Compares the two tracers on built-in scene `name`; returns how many region noise ratios
/// were compared.
fn compare_with_cpu(name: &str) -> usize {
    let scene = builtin(name).unwrap();
    let sample = scene.sample(0, 3);
    let instance = scene.instantiate(&sample.values).unwrap();
    let (res, spp) = (48, 256);
    let settings = |seed: u64| TraceSettings { estimator: Estimator::PLAIN, ..TraceSettings::new(res, res, spp, seed) };
    let cpu = two_seeds(|seed| render(&instance, &sample.camera, &settings(seed), None).unwrap().image);
    let gpu = two_seeds(|seed| {
        let out = tracer().render(&instance, &sample.camera, &settings(seed), None).unwrap();
        assert_eq!(out.samples, (res * res * spp) as u64);
        out.image
    });
    assert!(cpu.mean > 1e-3, "{name}: the CPU image is black");
    let ratio = gpu.mean / cpu.mean;
    let (worst, share) = block_z(res, &cpu, &gpu);
    eprintln!("{name}: GPU/CPU mean {ratio:.4}, worst block |z| {worst:.2}, blocks beyond 3: {:.1}%", share * 100.0);
    assert!((ratio - 1.0).abs() < 0.02, "{name}: GPU mean {} vs CPU {}", gpu.mean, cpu.mean);
    // Heavy-tailed noise (caustic fireflies) makes some blocks' variance estimates small;
    // under agreement a few percent of blocks may pass |z| 3, none should pass 6.
    assert!(share <= 0.08 && worst < 6.0, "{name}: blocks disagree beyond noise (worst |z| {worst:.2}, {:.1}% beyond 3)", share * 100.0);
    // Regions: the pixels that show glass; those whose centre sees each transparent object
    // first (a bias through one object is diluted in all the glass pixels: a 13% one through
    // a cube of 100 pixels was |z| 3.8 there); the rest.
    let prepared = PreparedScene::new(&instance);
    let glass = glass_pixels(&prepared, &sample.camera, res, res);
    let first_seen = transparent_object_per_pixel(&prepared, &sample.camera, res, res);
    let mut regions = vec![("glass pixels".to_string(), glass.clone()), ("other pixels".to_string(), glass.iter().map(|g| !g).collect())];
    for (k, object) in instance.objects.iter().enumerate().filter(|(_, o)| o.transparent) {
        regions.push((format!("seen through {}", object.name), first_seen.iter().map(|&o| o == Some(k as u32)).collect()));
    }
    let mut noise_compared = 0;
    for (region, in_region) in &regions {
        let Some(channels) = region_agreement(&cpu, &gpu, in_region) else { continue };
        for (c, (z, noise_ratio)) in channels.into_iter().enumerate() {
            eprintln!("{name}, {region}, channel {c}: |z| {z:.2}, GPU/CPU noise {noise_ratio:.3?}");
            // Up to a dozen regions and three channels per scene, five scenes: |z| 4.5 is a
            // false alarm about once in 1000 runs, while a 5% bias through a glass object here
            // is many standard errors.
            assert!(z < 4.5, "{name}, {region}, channel {c}: region means differ by {z:.2} standard errors");
            // The ratio's own spread is 5-7% at 256 pixels, less on larger regions; a change
            // that halves or doubles the samples moves it by 1.41x.
            if let Some(ratio) = noise_ratio {
                assert!((0.8..1.25).contains(&ratio), "{name}, {region}, channel {c}: GPU noise {ratio:.3}x the CPU's");
                noise_compared += 1;
            }
        }
    }
    noise_compared
}

#[test]
fn every_builtin_scene_matches_the_cpu_tracer() {
    let noise_compared: usize = BUILTIN_NAMES.iter().map(|name| compare_with_cpu(name)).sum();
    // The rest of every scene is large enough, and some scenes' glass too.
    assert!(noise_compared > 3 * BUILTIN_NAMES.len(), "only {noise_compared} noise ratios compared");
}

#[test]
fn images_are_deterministic_and_cpu_only_estimators_are_refused() {
    let scene = builtin("cornellbox").unwrap();
    let sample = scene.sample(0, 1);
    let instance = scene.instantiate(&sample.values).unwrap();
    let settings = TraceSettings { estimator: Estimator::PLAIN, ..TraceSettings::new(24, 16, 8, 5) };
    let a = tracer().render(&instance, &sample.camera, &settings, None).unwrap();
    let b = tracer().render(&instance, &sample.camera, &settings, None).unwrap();
    assert_eq!(a.image, b.image, "two renders with one seed differ");
    let other = TraceSettings { seed: 6, ..settings.clone() };
    let c = tracer().render(&instance, &sample.camera, &other, None).unwrap();
    assert_ne!(a.image, c.image, "another seed gave the same image");

    for name in ["caustic", "plain+adaptive", "plain+stratified"] {
        let cpu_only = TraceSettings { estimator: Estimator::parse(name).unwrap(), ..settings.clone() };
        let err = tracer().render(&instance, &sample.camera, &cpu_only, None).err().expect("CPU-only estimators must be refused").to_string();
        assert!(err.contains(name) && err.contains("CPU"), "{err}");
    }
}
