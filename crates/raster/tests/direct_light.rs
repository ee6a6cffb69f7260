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
    add_quads(
        &mut scene,
        &[Quad {
            centre: Vec3::ZERO,
            u: Vec3::X * 20.0,
            v: Vec3::NEG_Z * 20.0,
            albedo: Vec3::splat(albedo),
            roughness,
            transparent: false,
        }],
    );
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
            let x = light.corner
                + light.edge_u * ((i as f32 + 0.5) / samples as f32)
                + light.edge_v * ((j as f32 + 0.5) / samples as f32);
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

/// (pixels compared, max relative error where the reference is above `floor` x its maximum,
/// RMS error / maximum reference).
fn compare(albedo: f32, roughness: f32, metallic: f32) -> (usize, f32, f32) {
    let scene = floor_scene(albedo, roughness, metallic);
    let cam = camera(Vec3::new(0.0, 2.2, 2.6), Vec3::new(0.0, 0.0, -0.3), 55.0);
    let mut r = rasterizer();
    let b = r.render(&scene, &cam, RES, RES).unwrap();
    let diffuse = albedo * (1.0 - metallic);
    let f0 = 0.04 * (1.0 - metallic) + albedo * metallic;
    let mut rows = Vec::new();
    for y in (2..RES).step_by(4) {
        for x in (2..RES).step_by(4) {
            let p = Vec3::new(b.opaque.get(opaque::POSITION, x, y), b.opaque.get(opaque::POSITION + 1, x, y), b.opaque.get(opaque::POSITION + 2, x, y));
            if b.opaque.get(opaque::DEPTH, x, y) == 0.0 || p.y.abs() > 1e-4 {
                continue; // background, or the light's own quad
            }
            let n = Vec3::new(b.opaque.get(opaque::NORMAL, x, y), b.opaque.get(opaque::NORMAL + 1, x, y), b.opaque.get(opaque::NORMAL + 2, x, y));
            let wo = Vec3::new(b.opaque.get(opaque::WO, x, y), b.opaque.get(opaque::WO + 1, x, y), b.opaque.get(opaque::WO + 2, x, y));
            let want = reference(&scene.rect_lights[0], p, n, wo, diffuse, f0, roughness);
            let got = b.opaque.get(opaque::LD, x, y);
            // Grey everything: all three channels agree.
            assert_eq!(got, b.opaque.get(opaque::LD + 2, x, y));
            rows.push((want, got));
        }
    }
    let max_ref = rows.iter().map(|r| r.0).fold(0.0, f32::max);
    let max_rel = rows
        .iter()
        .filter(|r| r.0 > 0.1 * max_ref)
        .map(|r| (r.1 - r.0).abs() / r.0)
        .fold(0.0, f32::max);
    let rms = (rows.iter().map(|r| (r.1 - r.0).powi(2)).sum::<f32>() / rows.len() as f32).sqrt() / max_ref;
    (rows.len(), max_rel, rms)
}

#[test]
fn diffuse_plane_matches_monte_carlo_within_two_percent() {
    // Rough dielectric: diffuse dominates; the small (F0 = 0.04) specular lobe is included
    // in the reference too.
    let (n, max_rel, rms) = compare(0.8, 1.0, 0.0);
    eprintln!("diffuse plane: {n} pixels, max relative error {:.4}, rms/max {:.4}", max_rel, rms);
    assert!(n > 100, "{n}");
    assert!(max_rel < 0.02, "max relative error {max_rel}");
}

#[test]
fn ltc_specular_error_against_monte_carlo() {
    // Pure GGX (metal). The LTC is an approximation: this measures it (see docs/raster.md)
    // and fails if it gets worse than the documented bound.
    for roughness in [0.3f32, 0.5, 0.8] {
        let (n, max_rel, rms) = compare(0.9, roughness, 1.0);
        eprintln!("GGX roughness {roughness}: {n} pixels, max relative error {max_rel:.4} (where > 10% of max), rms/max {rms:.4}");
        assert!(rms < 0.05, "roughness {roughness}: rms/max {rms}");
        assert!(max_rel < 0.15, "roughness {roughness}: max relative error {max_rel}");
    }
}
