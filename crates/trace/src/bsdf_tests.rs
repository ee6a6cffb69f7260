//! Known-answer tests of every BSDF: sampling against the pdf (chi-square), pdf/eval
//! consistency, and energy conservation at several roughness values.

use std::f32::consts::TAU;

use glam::Vec3;
use glassbake_scene::Transmission;

use crate::bsdf::{Bsdf, MaterialModel, SurfaceMaterial};
use crate::rng::Pcg32;

fn opaque(base: Vec3, roughness: f32, metallic: f32) -> SurfaceMaterial {
    SurfaceMaterial::new(base, roughness, metallic, None)
}

fn glass(roughness: f32, thin: bool, weight: f32) -> SurfaceMaterial {
    SurfaceMaterial::new(Vec3::ONE, roughness, 0.0, Some(Transmission { weight, ior: 1.5, thin }))
}

/// A normal that is not an axis, so the frame code is exercised too.
fn test_normal() -> Vec3 {
    Vec3::new(0.3, 0.5, 0.8).normalize()
}

/// Outgoing directions (world) at polar angles from the normal; negative cosines come from
/// inside (the back side).
fn outgoing(bsdf: &Bsdf, cos_theta: f32) -> Vec3 {
    let sin = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    bsdf.frame.to_world(Vec3::new(sin * 0.8, sin * 0.6, cos_theta))
}

/// The non-delta BSDFs the chi-square test covers, named.
fn non_delta_cases() -> Vec<(String, Bsdf)> {
    let n = test_normal();
    let mut cases = vec![("lambertian".to_string(), Bsdf::new(&opaque(Vec3::new(0.8, 0.5, 0.2), 1.0, 0.0), n, MaterialModel::Lambertian))];
    for roughness in [0.3f32, 0.6, 1.0] {
        let r = roughness;
        cases.push((format!("gltf dielectric base r={r}"), Bsdf::new(&opaque(Vec3::new(0.7, 0.6, 0.5), r, 0.0), n, MaterialModel::Gltf)));
        cases.push((format!("gltf conductor r={r}"), Bsdf::new(&opaque(Vec3::new(0.9, 0.7, 0.4), r, 1.0), n, MaterialModel::Gltf)));
        cases.push((format!("gltf half metal r={r}"), Bsdf::new(&opaque(Vec3::new(0.9, 0.7, 0.4), r, 0.5), n, MaterialModel::Gltf)));
        cases.push((format!("rough dielectric r={r}"), Bsdf::new(&glass(r, false, 1.0), n, MaterialModel::Gltf)));
        cases.push((format!("rough thin dielectric r={r}"), Bsdf::new(&glass(r, true, 1.0), n, MaterialModel::Gltf)));
        cases.push((format!("half-transmissive rough dielectric r={r}"), Bsdf::new(&glass(r, false, 0.5), n, MaterialModel::Gltf)));
        cases.push((
            format!("coloured specular layer r={r}"),
            Bsdf::new(&specular_layer(Vec3::new(0.3, 0.6, 0.5), r, 0.6, Vec3::new(8.0, 1.0, 0.2)), n, MaterialModel::Gltf),
        ));
    }
    cases
}

/// KHR_materials_specular: a dielectric base with a specular layer of weight `specular`
/// and F0 = min(0.04 x colour, 1).
fn specular_layer(base: Vec3, roughness: f32, specular: f32, specular_color: Vec3) -> SurfaceMaterial {
    SurfaceMaterial { specular, specular_color, ..opaque(base, roughness, 0.0) }
}

/// Upper tail of the chi-square distribution by the Wilson-Hilferty normal approximation,
/// returned as a z score: large positive z means the histogram does not fit.
fn chi_square_z(chi2: f64, dof: f64) -> f64 {
    let c = 2.0 / (9.0 * dof);
    ((chi2 / dof).powf(1.0 / 3.0) - (1.0 - c)) / c.sqrt()
}

const THETA_BINS: usize = 24;
const PHI_BINS: usize = 48;

/// Bin of a local direction: cos(theta) in [-1, 1] and phi, uniform, so bins have equal
/// solid angle.
fn bin_of(w: Vec3) -> usize {
    let t = (((w.z + 1.0) * 0.5) * THETA_BINS as f32).floor().clamp(0.0, THETA_BINS as f32 - 1.0) as usize;
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += TAU;
    }
    let p = ((phi / TAU) * PHI_BINS as f32).floor().clamp(0.0, PHI_BINS as f32 - 1.0) as usize;
    t * PHI_BINS + p
}

/// Integral of the pdf over each bin by a midpoint rule on a finer grid.
fn integrate_pdf(bsdf: &Bsdf, wo: Vec3) -> Vec<f64> {
    const SUB: usize = 10;
    let mut integral = vec![0.0f64; THETA_BINS * PHI_BINS];
    let d_cos = 2.0 / (THETA_BINS * SUB) as f64;
    let d_phi = std::f64::consts::TAU / (PHI_BINS * SUB) as f64;
    for i in 0..THETA_BINS * SUB {
        let cos_theta = -1.0 + (i as f64 + 0.5) * d_cos;
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        for j in 0..PHI_BINS * SUB {
            let phi = (j as f64 + 0.5) * d_phi;
            let local = Vec3::new((sin_theta * phi.cos()) as f32, (sin_theta * phi.sin()) as f32, cos_theta as f32);
            let pdf = bsdf.pdf(wo, bsdf.frame.to_world(local)) as f64;
            integral[(i / SUB) * PHI_BINS + j / SUB] += pdf * d_cos * d_phi;
        }
    }
    integral
}

#[test]
fn sampling_matches_pdf_chi_square() {
    let samples = 100_000;
    let mut failures = Vec::new();
    for (name, bsdf) in non_delta_cases() {
        for cos_o in [0.9f32, 0.4, -0.6] {
            let wo = outgoing(&bsdf, cos_o);
            let expected = integrate_pdf(&bsdf, wo);
            let total_pdf: f64 = expected.iter().sum();
            let mut observed = vec![0.0f64; expected.len()];
            let mut rng = Pcg32::new(1234, 5);
            let mut produced = 0;
            for _ in 0..samples {
                let (a, b, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
                if let Some(s) = bsdf.sample(wo, a, b, u) {
                    assert!(!s.delta, "{name}: non-delta BSDF produced a delta sample");
                    observed[bin_of(bsdf.frame.to_local(s.wi))] += 1.0;
                    produced += 1;
                }
            }
            // The pdf integrates to the fraction of draws that produce a direction.
            let produced_fraction = produced as f64 / samples as f64;
            if (total_pdf - produced_fraction).abs() > 0.01 || total_pdf > 1.005 {
                failures.push(format!("{name} cos_o={cos_o}: pdf integrates to {total_pdf:.4}, sampler produced {produced_fraction:.4}"));
                continue;
            }
            // Pool bins with small expected counts (standard practice for chi-square).
            let (mut chi2, mut dof, mut pool_e, mut pool_o) = (0.0f64, 0usize, 0.0f64, 0.0f64);
            let mut order: Vec<usize> = (0..expected.len()).collect();
            order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
            for i in order {
                let e = expected[i] * samples as f64;
                if e < 5.0 {
                    pool_e += e;
                    pool_o += observed[i];
                    continue;
                }
                chi2 += (observed[i] - e).powi(2) / e;
                dof += 1;
            }
            if pool_e >= 5.0 {
                chi2 += (pool_o - pool_e).powi(2) / pool_e;
                dof += 1;
            } else if pool_o > pool_e + 10.0 + 5.0 * pool_e.sqrt() {
                failures.push(format!("{name} cos_o={cos_o}: {pool_o} samples where the pdf expects {pool_e:.1}"));
            }
            let z = chi_square_z(chi2, (dof.max(2) - 1) as f64);
            if z > 4.5 {
                failures.push(format!("{name} cos_o={cos_o}: chi2 {chi2:.1} with {dof} bins (z = {z:.1})"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn sample_weight_and_pdf_agree_with_eval_and_pdf() {
    let mut rng = Pcg32::new(77, 3);
    for (name, bsdf) in non_delta_cases() {
        for cos_o in [0.95f32, 0.5, 0.1, -0.4] {
            let wo = outgoing(&bsdf, cos_o);
            for _ in 0..2000 {
                let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_vec2()) else { continue };
                let pdf = bsdf.pdf(wo, s.wi);
                assert!((pdf - s.pdf).abs() <= 1e-3 * pdf.max(1e-3), "{name}: pdf {pdf} vs sampled {}", s.pdf);
                let cos = s.wi.dot(bsdf.frame.normal).abs();
                let expected = bsdf.eval(wo, s.wi) * cos / pdf;
                let tol = 1e-3 * expected.max_element().max(1e-3);
                assert!((expected - s.weight).abs().max_element() <= tol, "{name}: weight {} vs {expected}", s.weight);
                assert!(s.weight.min_element() >= 0.0 && s.weight.is_finite(), "{name}: weight {}", s.weight);
            }
        }
    }
}

/// Directional albedo from wo: the mean sample weight, with the radiance scaling of
/// refraction undone (that factor moves energy between media of different IOR and is not
/// reflectance or transmittance). Returns (reflected, transmitted).
fn albedo(bsdf: &Bsdf, wo: Vec3, samples: u32, rng: &mut Pcg32) -> (Vec3, Vec3) {
    let (mut r, mut t) = (Vec3::ZERO, Vec3::ZERO);
    for _ in 0..samples {
        if let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_vec2()) {
            if s.transmitted {
                t += s.weight * s.etap * s.etap;
            } else {
                r += s.weight;
            }
        }
    }
    (r / samples as f32, t / samples as f32)
}

#[test]
fn energy_is_conserved_at_every_roughness() {
    let n = test_normal();
    let mut rng = Pcg32::new(99, 1);
    let samples = 40_000;
    for roughness in [0.05f32, 0.1, 0.25, 0.5, 0.75, 1.0] {
        let materials = [
            ("gltf dielectric base", opaque(Vec3::ONE, roughness, 0.0)),
            ("gltf conductor", opaque(Vec3::ONE, roughness, 1.0)),
            ("gltf half metal", opaque(Vec3::ONE, roughness, 0.5)),
            ("rough dielectric", glass(roughness, false, 1.0)),
            ("rough thin dielectric", glass(roughness, true, 1.0)),
            ("half-transmissive dielectric", glass(roughness, false, 0.5)),
            ("specular layer, F0 clamped to 1 in red", specular_layer(Vec3::ONE, roughness, 1.0, Vec3::new(40.0, 5.0, 1.0))),
            ("no specular layer", specular_layer(Vec3::ONE, roughness, 0.0, Vec3::ONE)),
        ];
        for (name, material) in materials {
            let bsdf = Bsdf::new(&material, n, MaterialModel::Gltf);
            for cos_o in [1.0f32, 0.7, 0.3, 0.05, -0.5, -0.9] {
                let wo = outgoing(&bsdf, cos_o);
                let (r, t) = albedo(&bsdf, wo, samples, &mut rng);
                let total = (r + t).max_element();
                // Monte Carlo noise of a mean of weights bounded by ~1: well under 0.01.
                assert!(total <= 1.01, "{name} r={roughness} cos_o={cos_o}: R+T = {total}");
                // Nor may a white conductor or a glass lose much at low roughness:
                // single-scattering GGX only loses energy to masking, which is small for
                // alpha = roughness^2 <= 0.0625 away from grazing angles. (At roughness 1
                // it loses up to 70% at normal incidence: half the reflected directions of
                // cosine-distributed microfacets point below the horizon.)
                if !name.contains("dielectric base") && !name.contains("specular") && roughness <= 0.25 && cos_o.abs() > 0.2 {
                    assert!(total > 0.9, "{name} r={roughness} cos_o={cos_o}: R+T = {total}");
                }
            }
        }
    }
    // Lambertian of albedo 1 reflects everything.
    let lambert = Bsdf::new(&opaque(Vec3::ONE, 1.0, 0.0), n, MaterialModel::Lambertian);
    let (r, t) = albedo(&lambert, outgoing(&lambert, 0.6), samples, &mut rng);
    assert!((r - Vec3::ONE).abs().max_element() < 1e-5 && t == Vec3::ZERO, "{r} {t}");
}

#[test]
fn smooth_dielectrics_conserve_energy_exactly() {
    let n = test_normal();
    let mut rng = Pcg32::new(5, 5);
    for thin in [false, true] {
        let bsdf = Bsdf::new(&glass(0.0, thin, 1.0), n, MaterialModel::Gltf);
        assert!(!bsdf.has_non_delta());
        for cos_o in [1.0f32, 0.8, 0.5, 0.2, 0.02, -0.3, -0.7, -1.0] {
            let wo = outgoing(&bsdf, cos_o);
            let (r, t) = albedo(&bsdf, wo, 20_000, &mut rng);
            let total = r + t;
            assert!((total - Vec3::ONE).abs().max_element() < 1e-4, "thin={thin} cos_o={cos_o}: R+T = {total}");
            assert_eq!(bsdf.eval(wo, -wo), Vec3::ZERO, "delta lobes have no finite value");
            assert_eq!(bsdf.pdf(wo, -wo), 0.0);
            // Reflectance is Fresnel's (or the slab's) within Monte Carlo noise.
            let exact = if thin { crate::microfacet::thin_slab_reflectance(cos_o, 1.5) } else { crate::microfacet::fresnel_dielectric(cos_o, 1.5) };
            let sigma = (exact * (1.0 - exact) / 20_000.0).sqrt();
            assert!((r.x - exact).abs() <= 5.0 * sigma + 1e-6, "thin={thin} cos_o={cos_o}: R {} vs {exact}", r.x);
        }
    }
}

#[test]
fn thin_pane_passes_light_straight_and_tinted() {
    let tint = Vec3::new(0.9, 0.5, 0.2);
    let material = SurfaceMaterial { base_color: tint, ..glass(0.0, true, 1.0) };
    let bsdf = Bsdf::new(&material, test_normal(), MaterialModel::Gltf);
    let wo = outgoing(&bsdf, 0.6);
    let mut rng = Pcg32::new(1, 1);
    let mut seen_transmission = false;
    for _ in 0..200 {
        let s = bsdf.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_vec2()).unwrap();
        if s.transmitted {
            seen_transmission = true;
            assert!(s.pass_through && s.delta);
            assert!((s.wi + wo).length() < 1e-5, "no offset, no bending");
            assert!((s.weight - tint).abs().max_element() < 1e-5);
        }
    }
    assert!(seen_transmission);
    let (attenuation, probability) = bsdf.pass_through(wo).unwrap();
    let transmitted = 1.0 - crate::microfacet::thin_slab_reflectance(0.6, 1.5);
    assert!((attenuation - tint * transmitted).abs().max_element() < 1e-6);
    assert!((probability - transmitted).abs() < 1e-6);
    // A rough pane and an opaque surface do not let shadow rays through.
    assert!(Bsdf::new(&glass(0.3, true, 1.0), test_normal(), MaterialModel::Gltf).pass_through(wo).is_none());
    assert!(Bsdf::new(&opaque(Vec3::ONE, 0.5, 0.0), test_normal(), MaterialModel::Gltf).pass_through(wo).is_none());
}

#[test]
fn rough_dielectric_refracts_around_snell_and_tends_to_smooth() {
    // At low roughness, transmitted directions cluster around the Snell direction.
    let n = Vec3::Z;
    let bsdf = Bsdf::new(&glass(0.05, false, 1.0), n, MaterialModel::Gltf);
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let (snell, _) = crate::microfacet::refract(wo, n, 1.5).unwrap();
    let mut rng = Pcg32::new(3, 3);
    let mut transmitted = 0;
    for _ in 0..2000 {
        if let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_vec2()) {
            if s.transmitted {
                transmitted += 1;
                assert!(s.wi.dot(snell) > 0.98, "{} vs {snell}", s.wi);
                assert!((s.etap - 1.5).abs() < 1e-6);
            }
        }
    }
    assert!(transmitted > 1800, "{transmitted}");
}

/// The metallic lobe against GGX written out independently (Walter et al. 2007 D,
/// height-correlated Smith G2 with Heitz 2014's Lambda, Schlick's Fresnel with a coloured
/// F0), and reciprocity f(wo, wi) = f(wi, wo).
#[test]
fn conductor_matches_an_independent_ggx_and_is_reciprocal() {
    let n = test_normal();
    let f0 = Vec3::new(0.9, 0.5, 0.2);
    for roughness in [0.3f32, 0.5, 0.8] {
        let bsdf = Bsdf::new(&opaque(f0, roughness, 1.0), n, MaterialModel::Gltf);
        let alpha = roughness * roughness;
        let lambda = |cos: f32| {
            let tan2 = (1.0 - cos * cos) / (cos * cos);
            (-1.0 + (1.0 + alpha * alpha * tan2).sqrt()) / 2.0
        };
        for (cos_o, cos_i, phi) in [(0.9f32, 0.7f32, 2.0f32), (0.5, 0.3, 0.4), (0.2, 0.95, 3.0), (0.6, 0.6, 1.0)] {
            let wo = outgoing(&bsdf, cos_o);
            let sin_i = (1.0 - cos_i * cos_i).sqrt();
            let wi = bsdf.frame.to_world(Vec3::new(sin_i * phi.cos(), sin_i * phi.sin(), cos_i));
            let h = (wo + wi).normalize();
            let cos_h = h.dot(n);
            let d = alpha * alpha / (std::f32::consts::PI * (cos_h * cos_h * (alpha * alpha - 1.0) + 1.0).powi(2));
            let g2 = 1.0 / (1.0 + lambda(cos_o) + lambda(cos_i));
            let fresnel = f0 + (Vec3::ONE - f0) * (1.0 - wo.dot(h)).powi(5);
            let expected = fresnel * d * g2 / (4.0 * cos_o * cos_i);
            let got = bsdf.eval(wo, wi);
            assert!(
                (got - expected).abs().max_element() <= 1e-3 * expected.max_element(),
                "roughness {roughness}, cos_o {cos_o}, cos_i {cos_i}: {got} vs {expected}"
            );
            let back = bsdf.eval(wi, wo);
            assert!((got - back).abs().max_element() <= 1e-4 * got.max_element(), "not reciprocal: {got} vs {back}");
        }
    }
}

/// specularFactor 0 is exactly a Lambertian surface: every direction pair evaluates to
/// albedo / pi with the cosine density, whatever the roughness.
#[test]
fn specular_factor_zero_is_lambertian() {
    let n = test_normal();
    let base = Vec3::new(0.6, 0.4, 0.2);
    let mut rng = Pcg32::new(5, 3);
    for roughness in [0.05f32, 0.5, 1.0] {
        let bsdf = Bsdf::new(&specular_layer(base, roughness, 0.0, Vec3::ONE), n, MaterialModel::Gltf);
        let lambert = Bsdf::new(&opaque(base, roughness, 0.0), n, MaterialModel::Lambertian);
        for _ in 0..200 {
            let wo = crate::sampling::cosine_hemisphere(rng.next_vec2());
            let wi = crate::sampling::cosine_hemisphere(rng.next_vec2());
            let (wo, wi) = (bsdf.frame.to_world(wo), bsdf.frame.to_world(wi));
            let (f, pdf) = bsdf.eval_pdf(wo, wi);
            let (f_lambert, pdf_lambert) = lambert.eval_pdf(wo, wi);
            assert!((f - base / std::f32::consts::PI).abs().max_element() < 1e-6, "r={roughness}: f = {f}");
            assert!((f - f_lambert).abs().max_element() < 1e-6 && (pdf - pdf_lambert).abs() < 1e-5 * pdf_lambert, "r={roughness}: {pdf} vs {pdf_lambert}");
        }
    }
}

/// The specular layer against an independent evaluation of glTF's fresnel_mix: with base
/// colour black only the layer remains, F = s (F0 + (1 - F0)(1 - wo.h)^5) with
/// F0 = min(0.04 c, 1) per channel, times the GGX lobe D G / (4 cos_o cos_i).
#[test]
fn specular_layer_matches_fresnel_mix() {
    let n = Vec3::Z;
    let (roughness, specular, color) = (0.4f32, 0.7f32, Vec3::new(10.0, 2.0, 0.5));
    let bsdf = Bsdf::new(&specular_layer(Vec3::ZERO, roughness, specular, color), n, MaterialModel::Gltf);
    let alpha = roughness * roughness;
    let ggx_d = |h: Vec3| {
        let t = h.z * h.z * (alpha * alpha - 1.0) + 1.0;
        alpha * alpha / (std::f32::consts::PI * t * t)
    };
    // Height-correlated Smith G2 for GGX.
    let lambda = |w: Vec3| {
        let tan2 = (1.0 - w.z * w.z) / (w.z * w.z);
        0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
    };
    for (wo, wi) in [
        (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.2, 0.0, 0.95).normalize()),
        (Vec3::new(0.8, 0.0, 0.2).normalize(), Vec3::new(-0.7, 0.1, 0.4).normalize()),
    ] {
        let h = (wo + wi).normalize();
        let f0 = (0.04 * color).min(Vec3::ONE);
        let fresnel = specular * (f0 + (Vec3::ONE - f0) * (1.0 - wo.dot(h)).powi(5));
        let g2 = 1.0 / (1.0 + lambda(wo) + lambda(wi));
        let expected = fresnel * ggx_d(h) * g2 / (4.0 * wo.z * wi.z);
        let f = bsdf.eval(wo, wi);
        assert!((f - expected).abs().max_element() <= 1e-4 * expected.max_element(), "{f} vs {expected}");
    }
}

/// `delta_reflection` is what `sample` returns through its delta reflection on average:
/// over a fine grid of (u_lobe, u_event), the mean of the sampled weight where the sample is
/// the mirror direction equals the fraction, and the direction is the mirror of wo.
#[test]
fn delta_reflection_is_the_sampled_reflections_mean() {
    let n = test_normal();
    let cases = [
        ("smooth glass", glass(0.0, false, 1.0)),
        ("smooth thin pane", glass(0.0, true, 1.0)),
        ("half-transmissive smooth glass", glass(0.0, false, 0.5)),
        ("half-transmissive thin pane", glass(0.0, true, 0.4)),
    ];
    for (name, material) in cases {
        let bsdf = Bsdf::new(&material, n, MaterialModel::Gltf);
        for cos_theta in [0.95f32, 0.5, 0.1, -0.3, -0.9] {
            let wo = outgoing(&bsdf, cos_theta);
            let (mirror, fraction) = bsdf.delta_reflection(wo).unwrap_or_else(|| panic!("{name}: no delta reflection"));
            assert!((mirror - (2.0 * wo.dot(n) * n - wo)).length() < 1e-5, "{name}, cos {cos_theta}: {mirror} is not wo's mirror");
            let grid = 1000;
            let (mut sum, mut largest) = (0.0f64, 0.0f64);
            for i in 0..grid {
                for j in 0..grid {
                    let (u_lobe, u_event) = ((i as f32 + 0.5) / grid as f32, (j as f32 + 0.5) / grid as f32);
                    let Some(sample) = bsdf.sample(wo, u_lobe, u_event, glam::Vec2::splat(0.5)) else { continue };
                    if sample.delta && !sample.transmitted {
                        assert!((sample.wi - mirror).length() < 1e-5, "{name}: a delta reflection off the mirror direction");
                        sum += sample.weight.y as f64;
                        largest = largest.max(sample.weight.y as f64);
                    }
                }
            }
            let mean = sum / (grid * grid) as f64;
            assert!(fraction > 0.0, "{name}, cos {cos_theta}: fraction {fraction}");
            // The grid puts each of the two thresholds (the glass lobe's, the Fresnel
            // reflectance's) within one cell of the exact one.
            let tolerance = 2.0 * largest / grid as f64;
            assert!((mean - fraction as f64).abs() <= tolerance, "{name}, cos {cos_theta}: sampled {mean} vs {fraction} (tolerance {tolerance})");
        }
    }
    for (name, material) in [("rough glass", glass(0.3, false, 1.0)), ("opaque", opaque(Vec3::splat(0.5), 0.0, 0.0))] {
        let bsdf = Bsdf::new(&material, n, MaterialModel::Gltf);
        assert!(bsdf.delta_reflection(outgoing(&bsdf, 0.7)).is_none(), "{name} has no delta reflection");
    }
}

/// Light passes smooth glass alone one way per wo: `delta_continuation` gives it (the
/// transmission, or the total internal reflection where nothing is transmitted), the mean
/// of the sampled event's weight there (its fraction of the light) and the probability
/// `sample` picks it, checked over a fine grid of u_event against `sample`, from both sides
/// and with a tint. Surfaces with a non-delta lobe have none: next-event estimation cannot
/// follow their sampled events.
#[test]
fn delta_continuation_is_the_sampled_events_mean() {
    let n = test_normal();
    let tinted = |thin| SurfaceMaterial { base_color: Vec3::new(0.9, 0.6, 0.3), ..glass(0.0, thin, 1.0) };
    // cos -0.5 and -0.3 lie past the critical angle inside solid glass (cos 0.745 at 1.5).
    let cases = [
        ("smooth glass", tinted(false), true, vec![0.95f32, 0.5, 0.1, -0.8, -0.95, -0.5, -0.3]),
        ("smooth thin pane", tinted(true), false, vec![0.95, 0.5, 0.1, -0.3, -0.9]),
    ];
    for (name, material, solid, cosines) in cases {
        let bsdf = Bsdf::new(&material, n, MaterialModel::Gltf);
        for cos_theta in cosines {
            let wo = outgoing(&bsdf, cos_theta);
            let event = bsdf.delta_continuation(wo).unwrap_or_else(|| panic!("{name}, cos {cos_theta}: no continuation"));
            let total_internal_reflection = solid && cos_theta > -0.745 && cos_theta < 0.0;
            assert_eq!(event.reflected, total_internal_reflection, "{name}, cos {cos_theta}");
            assert_eq!(event.bends, solid, "{name}, cos {cos_theta}");
            let grid = 100_000;
            let (mut sum, mut picked, mut largest) = (Vec3::ZERO.as_dvec3(), 0usize, 0.0f64);
            for j in 0..grid {
                let u_event = (j as f32 + 0.5) / grid as f32;
                let Some(sample) = bsdf.sample(wo, 0.5, u_event, glam::Vec2::splat(0.5)) else { continue };
                if sample.delta && sample.transmitted != event.reflected {
                    assert!((sample.wi - event.wi).length() < 1e-5, "{name}: an event off {}: {}", event.wi, sample.wi);
                    sum += sample.weight.as_dvec3();
                    picked += 1;
                    largest = largest.max(sample.weight.max_element() as f64);
                }
            }
            let mean = sum / grid as f64;
            let tolerance = 2.0 * largest / grid as f64;
            for c in 0..3 {
                assert!((mean[c] - event.fraction[c] as f64).abs() <= tolerance, "{name}, cos {cos_theta}: sampled {mean} vs {}", event.fraction);
            }
            let probability = picked as f64 / grid as f64;
            assert!(
                (probability - event.probability as f64).abs() <= 2.0 / grid as f64,
                "{name}, cos {cos_theta}: picked {probability} vs {}",
                event.probability
            );
        }
    }
    for (name, material) in
        [("rough glass", glass(0.3, false, 1.0)), ("half-transmissive smooth glass", glass(0.0, false, 0.5)), ("opaque", opaque(Vec3::splat(0.5), 0.0, 0.0))]
    {
        let bsdf = Bsdf::new(&material, n, MaterialModel::Gltf);
        assert!(bsdf.delta_continuation(outgoing(&bsdf, 0.7)).is_none(), "{name} has no continuation next-event estimation can follow");
    }
}
