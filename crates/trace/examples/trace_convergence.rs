//! Convergence of the path tracer's estimators on the built-in scenes at equal spp:
//! per-pixel variance (from two renders with independent seeds), seconds, and efficiency =
//! 1 / (variance x seconds), on surface pixels, on transparent pixels, on pixels lit through
//! glass, and on all pixels as the metrics see them (clamped to [0, 1]).
//! Prints a Markdown table; with --out DIR also writes each render as PNG and EXR, and the
//! transparent-pixel mask and the first object each pixel sees (ids, with a legend) as PGMs.
//!
//! cargo run --release -p glassbake-trace --example trace_convergence -- \
//!     [--res 128] [--spp 256] [--glass-spp G] [--sample 0] [--scenes cornellbox,desk] [--out DIR]
//!     [--estimators plain,caustic,caustic+adaptive+stratified] [--max-depth N] [--rr-depth N]
//!     [--paths all|bent-view|straight-view] [--seeds 2]
//!
//! Estimators are named as `glassbake trace --estimator` names them (`glassbake_trace::Estimator`):
//! a transport, `plain` or `caustic`, then `+merging` (photon merging of what is seen through
//! glass, biased: its row is followed by its squared bias against the last unbiased estimator
//! listed before it, and its efficiency by error = variance + squared bias), `+adaptive` and
//! `+stratified`.
//! `--paths bent-view` renders only the paths whose view from the camera bends at glass,
//! `straight-view` the rest (`PathFilter`; the two add up to the image): where the noise is.
//!
//! Variance of a pixel's estimate is the sample variance of its value over `--seeds`
//! independent renders (for 2: E[(a - b)^2] / 2), averaged over the pixel's RGB channels and
//! then over the pixels of a mask.
//! "Transparent" pixels see a transmissive object first; "lit through glass" pixels see an
//! opaque surface first whose straight line to the centre of some rectangle light crosses a
//! transmissive object (the paths plain NEE cannot take). "Transparent, clamped" is the
//! transparent set as T.MAE/T.PSNR see it. `--glass-spp` traces the pixels that show glass at
//! G samples (`TraceSettings::glass_spp`), as a dataset's test split does. Seconds are wall
//! time of one render with all threads, BVH build included.

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use glassbake_core::{Camera, PlanarImage, Ray};
use glassbake_scene::builtin::builtin;
use glassbake_scene::Scene;
use glassbake_trace::geometry::Owner;
use glassbake_trace::{render, Estimator, PathFilter, PreparedScene, TraceSettings};

struct Args {
    res: u32,
    spp: u32,
    glass_spp: Option<u32>,
    sample: u64,
    scenes: Vec<String>,
    out: Option<PathBuf>,
    max_depth: u32,
    rr_depth: u32,
    paths: PathFilter,
    /// Independent renders per estimator (seeds 1 to N), at least 2.
    seeds: u64,
    estimators: Vec<Estimator>,
}

fn parse_args() -> Args {
    let mut args = Args {
        res: 128,
        spp: 256,
        glass_spp: None,
        sample: 0,
        scenes: ["cornell-glass", "cornellbox", "cornellbox8", "desk", "bathroom"].map(String::from).to_vec(),
        out: None,
        max_depth: TraceSettings::DEFAULT_MAX_DEPTH,
        rr_depth: TraceSettings::DEFAULT_RR_DEPTH,
        paths: PathFilter::All,
        seeds: 2,
        estimators: ["plain", "caustic", "caustic+adaptive+stratified"].into_iter().map(|e| Estimator::parse(e).expect("a known estimator")).collect(),
    };
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let usage = || -> ! {
        eprintln!("usage: trace_convergence [--res N] [--spp N] [--glass-spp G] [--sample I] [--scenes a,b] [--estimators plain,caustic,caustic+adaptive+stratified] [--out DIR] [--max-depth N] [--rr-depth N] [--paths all|bent-view|straight-view] [--seeds N]");
        std::process::exit(2)
    };
    let mut i = 0;
    while i < argv.len() {
        let value = argv.get(i + 1).cloned().unwrap_or_else(|| usage());
        match argv[i].as_str() {
            "--res" => args.res = value.parse().unwrap_or_else(|_| usage()),
            "--spp" => args.spp = value.parse().unwrap_or_else(|_| usage()),
            "--glass-spp" => args.glass_spp = Some(value.parse().unwrap_or_else(|_| usage())),
            "--sample" => args.sample = value.parse().unwrap_or_else(|_| usage()),
            "--scenes" => args.scenes = value.split(',').map(String::from).collect(),
            "--out" => args.out = Some(PathBuf::from(value)),
            "--max-depth" => args.max_depth = value.parse().unwrap_or_else(|_| usage()),
            "--rr-depth" => args.rr_depth = value.parse().unwrap_or_else(|_| usage()),
            "--seeds" => args.seeds = value.parse().ok().filter(|&n| n >= 2).unwrap_or_else(|| usage()),
            "--paths" => args.paths = PathFilter::parse(&value).unwrap_or_else(|| usage()),
            "--estimators" => {
                args.estimators = value.split(',').map(|e| Estimator::parse(e).unwrap_or_else(|_| usage())).collect();
            }
            _ => usage(),
        }
        i += 2;
    }
    args
}

fn is_transmissive(scene: &Scene, owner: Owner) -> bool {
    match owner {
        Owner::Object { material, .. } => scene.materials[material as usize].transmission.is_some_and(|t| t.weight > 0.0),
        Owner::RectLight { .. } => false,
    }
}

/// Whether the first surface on the segment from `from` to `to` is transmissive.
fn first_blocker_is_glass(prepared: &PreparedScene, scene: &Scene, from: Vec3, to: Vec3) -> bool {
    let to_target = to - from;
    let distance = to_target.length();
    let direction = to_target / distance;
    match prepared.intersect(&Ray { origin: from + direction * 1e-4, direction }) {
        Some(hit) => hit.distance < distance - 2e-4 && is_transmissive(scene, hit.owner),
        None => false,
    }
}

/// (surfaces, transparent, lit through glass) per pixel. "Surfaces" leaves out pixels with
/// an emitter or the background in their 3x3 neighbourhood: their variance is the box
/// filter's over a bright edge, the same for every estimator, and would swamp the mean.
fn masks(scene: &Scene, camera: &Camera, res: u32) -> (Vec<bool>, Vec<bool>, Vec<bool>) {
    let prepared = PreparedScene::new(scene);
    let mut transparent = Vec::new();
    let mut through_glass = Vec::new();
    let mut sees_surface = Vec::new();
    for y in 0..res {
        for x in 0..res {
            let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5, res, res);
            let hit = prepared.intersect(&ray);
            sees_surface.push(matches!(hit, Some(h) if h.emitter.is_none() && matches!(h.owner, Owner::Object { .. })));
            let (t, g) = match hit {
                Some(h) if is_transmissive(scene, h.owner) => (true, false),
                Some(h) if matches!(h.owner, Owner::Object { .. }) => {
                    let lit = scene.rect_lights.iter().any(|l| first_blocker_is_glass(&prepared, scene, h.position + h.geometric_normal * 1e-4, l.center()));
                    (false, lit)
                }
                _ => (false, false),
            };
            transparent.push(t);
            through_glass.push(g);
        }
    }
    let r = res as i64;
    let surfaces = (0..r * r)
        .map(|i| {
            let (x, y) = (i % r, i / r);
            (-1..=1).all(|dy| {
                (-1..=1).all(|dx| {
                    let (nx, ny) = ((x + dx).clamp(0, r - 1), (y + dy).clamp(0, r - 1));
                    sees_surface[(ny * r + nx) as usize]
                })
            })
        })
        .collect();
    (surfaces, transparent, through_glass)
}

/// A square 8-bit greyscale image (binary PGM), row-major.
fn write_pgm(path: &std::path::Path, res: u32, values: impl Iterator<Item = u8>) {
    let mut pgm = format!("P5 {res} {res} 255\n").into_bytes();
    pgm.extend(values);
    std::fs::write(path, pgm).expect("write PGM");
}

/// Each pixel's sample variance over independent renders (n - 1 degrees of freedom), the
/// mean of its RGB channels.
fn pixel_variances(images: &[PlanarImage], tone: fn(f32) -> f32) -> Vec<f64> {
    let (width, height) = (images[0].width(), images[0].height());
    let n = images.len() as f64;
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            (0..3)
                .map(|c| {
                    let values = images.iter().map(|image| tone(image.get(c, x, y)) as f64);
                    let mean = values.clone().sum::<f64>() / n;
                    values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
                })
                .sum::<f64>()
                / 3.0
        })
        .collect()
}

/// Per pixel, the squared bias of estimator A's clamped value against an unbiased B's, from
/// renders paired by seed (which share random streams, so their errors correlate): with d_k
/// the difference of the k-th pair, E[mean(d)^2] = bias^2 + var(d) / N, so mean(d)^2 less the
/// sample variance of d over N is an unbiased estimate of bias^2 (averaged over RGB; noisy
/// per pixel, negative values kept so that averages over pixels stay unbiased).
fn squared_bias(images: &[PlanarImage], reference: &[PlanarImage]) -> Vec<f64> {
    let (width, height) = (images[0].width(), images[0].height());
    let n = images.len().min(reference.len()) as f64;
    let tone = |v: f32| glassbake_core::color::tonemap_clamp(v) as f64;
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            (0..3)
                .map(|c| {
                    let d: Vec<f64> = images.iter().zip(reference).map(|(a, b)| tone(a.get(c, x, y)) - tone(b.get(c, x, y))).collect();
                    let mean = d.iter().sum::<f64>() / n;
                    let variance = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
                    mean * mean - variance / n
                })
                .sum::<f64>()
                / 3.0
        })
        .collect()
}

fn masked_mean(values: &[f64], mask: Option<&[bool]>) -> Option<f64> {
    let (sum, count) = values.iter().enumerate().filter(|(i, _)| mask.is_none_or(|m| m[*i])).fold((0.0, 0usize), |(s, c), (_, v)| (s + v, c + 1));
    (count > 0).then(|| sum / count as f64)
}

fn image_mean(images: &[PlanarImage]) -> f64 {
    let (width, height) = (images[0].width(), images[0].height());
    let mut sum = 0.0;
    for image in images {
        for c in 0..3 {
            for y in 0..height {
                for x in 0..width {
                    sum += image.get(c, x, y) as f64;
                }
            }
        }
    }
    sum / (width as f64 * height as f64 * 3.0 * images.len() as f64)
}

fn main() {
    let args = parse_args();
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).expect("create --out");
    }
    println!(
        "{}x{}, {} spp, sample {} of seed 0, seeds 1 to {}; variance of a pixel's estimate (mean of RGB); efficiency = 1 / (variance x seconds), relative to plain\n",
        args.res, args.res, args.spp, args.sample, args.seeds
    );
    println!("| scene | estimator | seconds | image mean | surface px | variance | efficiency | transparent px | variance | efficiency | lit through glass px | variance | efficiency | all px, clamped | variance | efficiency | transparent, clamped | variance | efficiency |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for name in &args.scenes {
        let scene = builtin(name).unwrap_or_else(|| panic!("no built-in scene {name}"));
        let sample = scene.sample(0, args.sample);
        let instance = scene.instantiate(&sample.values).expect("sampled values are in range");
        let (surfaces, transparent, through_glass) = masks(&instance, &sample.camera, args.res);
        if let Some(out) = &args.out {
            // The transparent-pixel mask, for comparing the renders elsewhere.
            write_pgm(&out.join(format!("{name}_transparent_mask.pgm")), args.res, transparent.iter().map(|&t| if t { 255 } else { 0 }));
            // Which object each pixel's centre sees first (1 + its index, 0: a light or nothing),
            // with the names in a legend, to split the variance by object.
            let prepared = PreparedScene::new(&instance);
            let ids = (0..args.res * args.res).map(|i| {
                let (x, y) = (i % args.res, i / args.res);
                match prepared.intersect(&sample.camera.ray(x as f32 + 0.5, y as f32 + 0.5, args.res, args.res)).map(|h| h.owner) {
                    Some(Owner::Object { object, .. }) => (object + 1).min(255) as u8,
                    _ => 0,
                }
            });
            write_pgm(&out.join(format!("{name}_first_object.pgm")), args.res, ids);
            let legend: String = instance.objects.iter().enumerate().map(|(i, o)| format!("{} {}\n", i + 1, o.name)).collect();
            std::fs::write(out.join(format!("{name}_first_object.txt")), legend).expect("write legend");
        }
        let mut plain_efficiency = [None; 5];
        // The last unbiased estimator's renders: what a biased one's squared bias is measured
        // against.
        let mut unbiased: Option<(String, Vec<PlanarImage>)> = None;
        for estimator in &args.estimators {
            let estimator = *estimator;
            let label = estimator.name();
            let mut images = Vec::new();
            let mut seconds = 0.0;
            for seed in 1..=args.seeds {
                let settings = TraceSettings {
                    estimator,
                    max_depth: args.max_depth,
                    rr_depth: args.rr_depth,
                    path_filter: args.paths,
                    glass_spp: args.glass_spp,
                    ..TraceSettings::new(args.res, args.res, args.spp, seed)
                };
                let start = Instant::now();
                let output = render(&instance, &sample.camera, &settings, None).expect("render");
                seconds += start.elapsed().as_secs_f64() / args.seeds as f64;
                let camera_samples = output.samples - output.pilot_samples;
                eprintln!(
                    "{name} {label} seed {seed}: {:.3} camera rays per sample (pilot included), {:.4} light paths per camera sample",
                    output.camera_rays as f64 / output.samples as f64,
                    output.light_paths as f64 / camera_samples as f64
                );
                if let Some(out) = &args.out {
                    let path = out.join(format!("{name}_{label}_{}spp_seed{seed}.png", args.spp));
                    output.image.write_png_rgb(&path, [0, 1, 2]).expect("write png");
                    output.image.write_exr(&path.with_extension("exr"), glassbake_core::image::ExrPrecision::F32).expect("write exr");
                }
                images.push(output.image);
            }
            let variances = pixel_variances(&images, |v| v);
            let clamped = pixel_variances(&images, glassbake_core::color::tonemap_clamp);
            let mut cells = Vec::new();
            let sets = [
                (&variances, Some(&surfaces[..])),
                (&variances, Some(&transparent[..])),
                (&variances, Some(&through_glass[..])),
                (&clamped, None),
                (&clamped, Some(&transparent[..])),
            ];
            for (k, (variances, mask)) in sets.into_iter().enumerate() {
                let count = mask.map_or(variances.len(), |m| m.iter().filter(|&&b| b).count());
                let variance = masked_mean(variances, mask);
                let efficiency = variance.map(|v| 1.0 / (v * seconds));
                if estimator == Estimator::PLAIN {
                    plain_efficiency[k] = efficiency;
                }
                let relative = match (efficiency, plain_efficiency[k]) {
                    (Some(e), Some(p)) => format!("{:.2}x", e / p),
                    _ => "n/a".into(),
                };
                cells.push(count.to_string());
                cells.push(variance.map_or("n/a".into(), |v| format!("{v:.3e}")));
                cells.push(relative);
            }
            println!("| {name} | {label} | {seconds:.1} | {:.4} | {} |", image_mean(&images), cells.join(" | "));
            if estimator.photon_merging() {
                match &unbiased {
                    Some((reference, reference_images)) => {
                        let bias2 = squared_bias(&images, reference_images);
                        // Mean over a pixel set, with its standard error (pixels taken as independent).
                        let summary = |mask: Option<&[bool]>| {
                            let values: Vec<f64> = bias2.iter().enumerate().filter(|(i, _)| mask.is_none_or(|m| m[*i])).map(|(_, v)| *v).collect();
                            let n = values.len().max(1) as f64;
                            let mean = values.iter().sum::<f64>() / n;
                            let spread = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0) / n).sqrt();
                            (mean, spread)
                        };
                        let ((all, all_error), (glass, glass_error)) = (summary(None), summary(Some(&transparent[..])));
                        let variance = masked_mean(&clamped, None).unwrap_or(0.0);
                        // A negative estimate is a bias below what the renders can detect: counted as 0.
                        let relative = plain_efficiency[3].map_or("n/a".into(), |p| format!("{:.2}x", 1.0 / ((variance + all.max(0.0)) * seconds) / p));
                        println!(
                            "|   | {label}: squared bias vs {reference} (clamped), all {all:.2e} +- {all_error:.1e}, transparent {glass:.2e} +- {glass_error:.1e}; error (variance + squared bias) efficiency over plain, all {relative} |"
                        );
                    }
                    None => eprintln!("{name} {label}: no unbiased estimator before it to measure its bias against"),
                }
            } else {
                unbiased = Some((label.clone(), images));
            }
        }
    }
}
