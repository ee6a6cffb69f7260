//! L_d against Monte Carlo integration of the same BRDF over the rectangle light (computed on
//! the CPU here): the diffuse plane within 2 %, and the measured error of the LTC specular
//! lobe.

mod common;

use common::*;
use glam::Vec3;
use glassbake_core::layout::opaque;
use glassbake_raster::ltc;
use glassbake_scene::{RectLight, Scene};

const RES: u32 = 64;

fn floor_scene(albedo: f32, roughness: f32, metallic: f32) -> Scene {
    let mut scene = empty_scene("floor");
    add_quads(&mut scene, &[Quad { centre: Vec3::ZERO, u: Vec3::X * 20.0, v: Vec3::NEG_Z * 20.0, albedo: Vec3::splat(albedo), roughness, transparent: false }]);
    scene.materials[0].metallic = metallic;
    // Emits downwards (edge_u x edge_v = x x z = -y).
    scene.rect_lights.push(light(Vec3::new(-0.5, 1.0, -0.3), Vec3::X, Vec3::Z * 0.6, Vec3::splat(4.0)));
    scene
}

/// Monte Carlo (stratified over the light's area) of the radiance reflected towards `wo` at
/// `p` with normal `n`: diffuse albedo / pi plus GGX with Schlick Fresnel, as the shader.
fn reference(light: &RectLight, p: Vec3, n: Vec3, wo: Vec3, diffuse: f32, f0: f32, roughness: f32) -> f32 {
    let alpha = (roughness * roughness).max(ltc::MIN_ALPHA);
    let t1 = (wo - n * wo.dot(n)).normalize_or(n.any_orthonormal_vector());
    let t2 = n.cross(t1);
    let local = |d: Vec3| Vec3::new(d.dot(t1), d.dot(t2), d.dot(n));
    let v = local(wo);
    let ln = light.normal();
    let samples = 400;
    let da = light.area() / (samples * samples) as f32;
    let mut sum = 0.0f64;
    for i in 0..samples {
        for j in 0..samples {
            let x = light.corner + light.edge_u * ((i as f32 + 0.5) / samples as f32) + light.edge_v * ((j as f32 + 0.5) / samples as f32);
            let d = x - p;
            let dist2 = d.length_squared();
            let l = d / dist2.sqrt();
            let cos_light = -l.dot(ln);
            let cos_surface = l.dot(n);
            if cos_light <= 0.0 || cos_surface <= 0.0 {
                continue;
            }
            let (spec, w) = ltc::ggx_cos(alpha, v, local(l));
            let f = diffuse / std::f32::consts::PI * cos_surface + spec * (f0 + (1.0 - f0) * w);
            sum += (f * cos_light / dist2 * da) as f64;
        }
    }
    light.radiance.x * sum as f32
}

/// (pixels compared, max relative error where the reference is above 10 % of its maximum,
/// max relative error where above 50 %, RMS error / maximum reference).
fn compare(albedo: f32, roughness: f32, metallic: f32) -> (usize, f32, f32, f32) {
    let scene = floor_scene(albedo, roughness, metallic);
    let cam = camera(Vec3::new(0.0, 2.2, 2.6), Vec3::new(0.0, 0.0, -0.3), 55.0);
    compare_on(&scene, &cam, albedo, roughness, metallic, |p| p.y.abs() <= 1e-4)
}

fn compare_on(
    scene: &Scene,
    cam: &glassbake_core::Camera,
    albedo: f32,
    roughness: f32,
    metallic: f32,
    on_surface: impl Fn(Vec3) -> bool,
) -> (usize, f32, f32, f32) {
    let mut r = rasterizer();
    let b = r.render(scene, cam, RES, RES).unwrap();
    let diffuse = albedo * (1.0 - metallic);
    let f0 = 0.04 * (1.0 - metallic) + albedo * metallic;
    let mut rows = Vec::new();
    let mut points = Vec::new();
    for y in (2..RES).step_by(4) {
        for x in (2..RES).step_by(4) {
            let p = Vec3::new(b.opaque.get(opaque::POSITION, x, y), b.opaque.get(opaque::POSITION + 1, x, y), b.opaque.get(opaque::POSITION + 2, x, y));
            if b.opaque.get(opaque::DEPTH, x, y) == 0.0 || !on_surface(p) {
                continue; // background, the light's own quad, another surface
            }
            let n = Vec3::new(b.opaque.get(opaque::NORMAL, x, y), b.opaque.get(opaque::NORMAL + 1, x, y), b.opaque.get(opaque::NORMAL + 2, x, y));
            let wo = Vec3::new(b.opaque.get(opaque::WO, x, y), b.opaque.get(opaque::WO + 1, x, y), b.opaque.get(opaque::WO + 2, x, y));
            let want = reference(&scene.rect_lights[0], p, n, wo, diffuse, f0, roughness);
            let got = b.opaque.get(opaque::LD, x, y);
            // Grey everything: all three channels agree.
            assert_eq!(got, b.opaque.get(opaque::LD + 2, x, y));
            rows.push((want, got));
            points.push(p);
        }
    }
    let max_ref = rows.iter().map(|r| r.0).fold(0.0, f32::max);
    if let Some((i, r)) = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.0 > 0.1 * max_ref)
        .max_by(|a, b| ((a.1 .1 - a.1 .0).abs() / a.1 .0).total_cmp(&((b.1 .1 - b.1 .0).abs() / b.1 .0)))
    {
        eprintln!("  worst pixel at {}: L_d {} vs Monte Carlo {} (max {max_ref})", points[i], r.1, r.0);
    }
    let max_rel = |floor: f32| rows.iter().filter(|r| r.0 > floor * max_ref).map(|r| (r.1 - r.0).abs() / r.0).fold(0.0, f32::max);
    let rms = (rows.iter().map(|r| (r.1 - r.0).powi(2)).sum::<f32>() / rows.len() as f32).sqrt() / max_ref;
    (rows.len(), max_rel(0.1), max_rel(0.5), rms)
}

#[test]
fn diffuse_plane_matches_monte_carlo_within_two_percent() {
    // Rough dielectric: diffuse dominates; the small (F0 = 0.04) specular lobe is included
    // in the reference too.
    let (n, max_rel, _, rms) = compare(0.8, 1.0, 0.0);
    eprintln!("diffuse plane: {n} pixels, max relative error {max_rel:.4} (where > 10% of max), rms/max {rms:.4}");
    assert!(n > 100, "{n}");
    assert!(max_rel < 0.02, "max relative error {max_rel}");
}

#[test]
fn ltc_specular_error_against_monte_carlo() {
    // Pure GGX (metal). The LTC is an approximation: this measures it (see docs/raster.md)
    // and fails if it gets worse than the documented bound.
    for roughness in [0.3f32, 0.5, 0.8] {
        let (n, max_rel, max_rel_peak, rms) = compare(0.9, roughness, 1.0);
        eprintln!(
            "GGX roughness {roughness}: {n} pixels, max relative error {max_rel:.4} where > 10% of max, \
             {max_rel_peak:.4} where > 50% of max, rms/max {rms:.4}"
        );
        // Bounds from the measurement (docs/raster.md) with some margin: 0.034 / 0.163 /
        // 0.138, 0.004 / 0.025 / 0.036, 0.0009 / 0.0083 / 0.0084 for roughness 0.3 / 0.5 / 0.8.
        assert!(n > 100, "{n}");
        assert!(rms < 0.02, "roughness {roughness}: rms/max {rms}");
        assert!(max_rel_peak < 0.05, "roughness {roughness}: max relative error near the peak {max_rel_peak}");
        assert!(max_rel < 0.2, "roughness {roughness}: max relative error {max_rel}");
    }
}

#[test]
fn diffuse_wall_with_the_light_across_its_horizon_matches_monte_carlo() {
    // A wall at x = 0.2 facing -x cuts through the light (x in [-0.5, 0.5]): for points on
    // the wall the polygon straddles the horizon and must be clipped.
    let mut scene = floor_scene(0.8, 1.0, 0.0);
    add_quads(
        &mut scene,
        &[Quad { centre: Vec3::new(0.2, 1.0, -0.3), u: Vec3::Z * 6.0, v: Vec3::Y * 2.0, albedo: Vec3::splat(0.8), roughness: 1.0, transparent: false }],
    );
    let cam = camera(Vec3::new(-1.6, 0.7, 1.6), Vec3::new(0.2, 0.6, -0.4), 60.0);
    // Points within 5 cm of the light's plane are left out: there the 1/r^2 integrand is
    // nearly singular and the 400^2-sample stratified reference itself is off by a few
    // percent (checked against the closed form in double precision at the worst point).
    let on_wall = |p: Vec3| (p.x - 0.2).abs() <= 1e-4 && p.y > 0.01 && p.y < 0.95;
    let (n, max_rel, _, rms) = compare_on(&scene, &cam, 0.8, 1.0, 0.0, on_wall);
    eprintln!("diffuse wall across the horizon: {n} pixels, max relative error {max_rel:.4} (where > 10% of max), rms/max {rms:.4}");
    assert!(n > 50, "{n}");
    assert!(max_rel < 0.02, "max relative error {max_rel}");
}

#[test]
fn a_sharp_highlight_is_the_mean_over_the_pixel() {
    // A nearly mirror-like metal floor reflects a small light as a highlight a few pixels
    // wide. The path tracer box-filters each pixel, so L_d must be the pixel's mean, not the
    // value at its centre: compare L_d at RES with the 4 x 4 block means of L_d at 4 x RES,
    // and with the value at one of the four sub-pixels around each centre (what a single
    // centre sample would give).
    let mut scene = floor_scene(0.9, 0.1, 1.0);
    scene.rect_lights[0] = light(Vec3::new(-0.1, 1.0, -0.36), Vec3::X * 0.2, Vec3::Z * 0.12, Vec3::splat(4.0));
    let cam = camera(Vec3::new(0.0, 0.6, 2.0), Vec3::new(0.0, 0.0, -0.3), 40.0);
    let mut r = rasterizer();
    let coarse = r.render(&scene, &cam, RES, RES).unwrap().opaque;
    let fine = r.render(&scene, &cam, 4 * RES, 4 * RES).unwrap().opaque;
    let peak = (0..RES * RES).map(|i| coarse.get(opaque::LD, i % RES, i / RES)).fold(0.0, f32::max);
    let (mut err_mean, mut err_centre, mut sum_coarse, mut sum_fine, mut lit) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0);
    for y in 0..RES {
        for x in 0..RES {
            let block: f32 = (0..16).map(|i| fine.get(opaque::LD, 4 * x + i % 4, 4 * y + i / 4)).sum::<f32>() / 16.0;
            let centre = fine.get(opaque::LD, 4 * x + 2, 4 * y + 2);
            let got = coarse.get(opaque::LD, x, y);
            if block.max(got) > 0.05 * peak {
                lit += 1;
                err_mean += (got - block).abs() as f64;
                err_centre += (centre - block).abs() as f64;
                sum_coarse += got as f64;
                sum_fine += block as f64;
            }
        }
    }
    eprintln!(
        "highlight: {lit} pixels, L1 error of L_d vs the block means {:.4}, of a centre sample {:.4}, energy ratio {:.4}",
        err_mean / sum_fine,
        err_centre / sum_fine,
        sum_coarse / sum_fine
    );
    assert!((4..200).contains(&lit), "the highlight covers {lit} pixels: not a sharp highlight");
    assert!(err_mean / sum_fine < 0.1, "L_d is not the pixel mean: relative L1 error {}", err_mean / sum_fine);
    assert!(err_mean * 2.0 < err_centre, "no better than a centre sample: {err_mean} vs {err_centre}");
    assert!((sum_coarse / sum_fine - 1.0).abs() < 0.05, "energy ratio {}", sum_coarse / sum_fine);
}
