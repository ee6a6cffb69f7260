//! Light coverage against the exact share of each pixel that a glowing quad covers: its
//! corners projected, the quadrilateral clipped to the pixel's square, the area measured.

mod common;

use common::*;
use glam::{Vec2, Vec3};
use glassbake_raster::light_coverage::{composite, light_coverage};

const W: u32 = 32;
const H: u32 = 24;
const FACTOR: u32 = 8;
const EMISSION: Vec3 = Vec3::new(5.0, 3.0, 2.0);

/// Area of the part of convex polygon `polygon` inside the unit square at (x, y)
/// (Sutherland-Hodgman clipping, then the shoelace formula).
fn area_in_pixel(polygon: &[Vec2], x: f32, y: f32) -> f32 {
    let mut clipped = polygon.to_vec();
    let edges: [(Vec2, f32); 4] = [(Vec2::X, x), (Vec2::NEG_X, -(x + 1.0)), (Vec2::Y, y), (Vec2::NEG_Y, -(y + 1.0))];
    for (normal, offset) in edges {
        let inside = |p: Vec2| p.dot(normal) >= offset;
        let mut out = Vec::new();
        for i in 0..clipped.len() {
            let (a, b) = (clipped[i], clipped[(i + 1) % clipped.len()]);
            if inside(a) {
                out.push(a);
            }
            if inside(a) != inside(b) {
                let t = (offset - a.dot(normal)) / (b - a).dot(normal);
                out.push(a + (b - a) * t);
            }
        }
        clipped = out;
        if clipped.is_empty() {
            return 0.0;
        }
    }
    let twice: f32 = (0..clipped.len()).map(|i| clipped[i].perp_dot(clipped[(i + 1) % clipped.len()])).sum();
    twice.abs() / 2.0
}

#[test]
fn coverage_is_the_share_of_the_pixel_a_light_covers() {
    let mut scene = empty_scene("glowing quad");
    let (centre, u, v) = (Vec3::new(0.1, -0.05, 0.0), Vec3::new(0.8, 0.25, 0.0), Vec3::new(-0.2, 0.6, 0.0));
    add_quads(
        &mut scene,
        &[
            Quad { centre: Vec3::new(0.0, 0.0, -1.0), u: Vec3::X * 10.0, v: Vec3::Y * 10.0, albedo: Vec3::splat(0.5), roughness: 1.0, transparent: false },
            Quad { centre, u, v, albedo: Vec3::splat(0.5), roughness: 1.0, transparent: false },
        ],
    );
    scene.materials[1].emission = EMISSION;
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let corners = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
        .map(|(a, b)| cam.project(centre + u * a + v * b, W, H).map(|(px, py)| Vec2::new(px, py)).expect("in front of the camera"));

    let mut r = rasterizer();
    let both = light_coverage(&mut r, &scene, &cam, W, H, FACTOR).unwrap();
    // No glass: the naive G-buffer sees what the opaque one sees.
    assert_eq!(both.opaque.data(), both.naive.data());
    let image = both.opaque;
    let (coverage, light) = (image.plane(0), [image.plane(1), image.plane(2), image.plane(3)]);
    let (mut total, mut exact_total, mut edge_pixels, mut edge_error) = (0.0, 0.0, 0, 0.0);
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            let exact = area_in_pixel(&corners, x as f32, y as f32);
            let got = coverage[i];
            // A straight edge through a k x k grid of sub-samples miscounts at most one per
            // column (1/k of the pixel); a corner brings two edges.
            assert!((got - exact).abs() <= 2.0 / FACTOR as f32, "pixel ({x}, {y}): coverage {got}, exact {exact}");
            if exact > 1.0 - 1e-6 {
                assert_eq!(got, 1.0, "pixel ({x}, {y}) lies inside the light");
            }
            if exact < 1e-6 {
                assert_eq!(got, 0.0, "pixel ({x}, {y}) lies outside the light");
            }
            if exact > 1e-6 && exact < 1.0 - 1e-6 {
                edge_pixels += 1;
                edge_error += (got - exact).abs();
            }
            for (c, want) in EMISSION.to_array().into_iter().enumerate() {
                assert!((light[c][i] - got * want).abs() <= 1e-5 * want, "pixel ({x}, {y}) channel {c}: light {} for coverage {got}", light[c][i]);
            }
            total += got;
            exact_total += exact;
        }
    }
    assert!(edge_pixels > 20, "the quad's edges cross {edge_pixels} pixels");
    assert!(edge_error / (edge_pixels as f32) < 0.5 / FACTOR as f32, "mean |error| on the edges {}", edge_error / edge_pixels as f32);
    assert!((total - exact_total).abs() < 0.01 * exact_total, "covered {total} px, exactly {exact_total} px");
}

#[test]
fn the_composite_adds_the_light_over_what_the_rest_leaves() {
    // A quarter covered by a light of 4 (light 1.0 over the pixel): white whatever the rest.
    assert_eq!(composite(0.25, [1.0, 1.0, 1.0], [0.2, 0.0, 0.9]), [1.0, 1.0, 1.0]);
    // A sixteenth covered by a light of 0.8: 0.05 + 15/16 of the rest.
    let mixed = composite(1.0 / 16.0, [0.05, 0.0, 0.05], [0.4, 0.2, 0.0]);
    let want = [0.05 + 0.9375 * 0.4, 0.9375 * 0.2, 0.05];
    assert!(mixed.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6), "{mixed:?}");
    // No light: the rest, clamped.
    assert_eq!(composite(0.0, [0.0; 3], [0.3, 1.7, -0.1]), [0.3, 1.0, 0.0]);
}

#[test]
fn a_factor_of_zero_is_refused() {
    let scene = empty_scene("empty");
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let err = light_coverage(&mut rasterizer(), &scene, &cam, W, H, 0).unwrap_err().to_string();
    assert!(err.contains("factor"), "{err}");
}

#[test]
fn glass_in_front_of_a_light_hides_it_from_the_naive_coverage_only() {
    let mut scene = empty_scene("light behind glass");
    add_quads(
        &mut scene,
        &[
            Quad { centre: Vec3::new(0.0, 0.0, -1.0), u: Vec3::X * 10.0, v: Vec3::Y * 10.0, albedo: Vec3::splat(0.5), roughness: 1.0, transparent: false },
            Quad { centre: Vec3::ZERO, u: Vec3::X, v: Vec3::Y, albedo: Vec3::splat(0.5), roughness: 1.0, transparent: false },
            // Glass over the light's left half.
            Quad { centre: Vec3::new(-0.5, 0.0, 0.5), u: Vec3::X, v: Vec3::Y * 2.0, albedo: Vec3::splat(0.9), roughness: 0.0, transparent: true },
        ],
    );
    scene.materials[1].emission = EMISSION;
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let buffers = rasterizer().render(&scene, &cam, W, H).unwrap();
    let (opaque, naive) = (buffers.light_coverage.opaque.plane(0), buffers.light_coverage.naive.plane(0));
    let glass = buffers.transparent[0].plane(glassbake_core::layout::transparent::COVERAGE);
    let near = |x: u32, y: u32, want: f32| {
        (y.saturating_sub(1)..(y + 2).min(H)).all(|ny| (x.saturating_sub(1)..(x + 2).min(W)).all(|nx| glass[(ny * W + nx) as usize] == want))
    };
    let (mut hidden, mut open) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            if near(x, y, 1.0) && opaque[i] == 1.0 {
                assert_eq!(naive[i], 0.0, "pixel ({x}, {y}): the glass hides the light from the naive G-buffer");
                hidden += 1;
            }
            if near(x, y, 0.0) {
                assert_eq!(naive[i], opaque[i], "pixel ({x}, {y}): no glass, both G-buffers see the same light");
                open += (opaque[i] > 0.0) as usize;
            }
        }
    }
    assert!(hidden > 10 && open > 10, "{hidden} pixels of light behind glass, {open} in the open");
}

/// The coverage as the module defines it, reduced on the host from a G-buffer read back at
/// `factor` x `factor` the resolution: the reference the GPU's reduction is held to.
fn reduce_on_host(fine: &glassbake_core::PlanarImage, factor: usize) -> Vec<f32> {
    use glassbake_core::layout::{self, light_coverage::*, opaque};
    let (fw, w, h) = (fine.width() as usize, fine.width() as usize / factor, fine.height() as usize / factor);
    let ld = [0, 1, 2].map(|c| fine.plane(opaque::LD + c));
    let mut planes = vec![0.0f32; layout::LIGHT_COVERAGE_CHANNELS * w * h];
    let share = 1.0 / (factor * factor) as f32;
    for y in 0..h {
        for x in 0..w {
            for sy in 0..factor {
                for sx in 0..factor {
                    let sample = ld.map(|plane| plane[(y * factor + sy) * fw + x * factor + sx]);
                    if sample.iter().all(|&v| v >= 1.0) {
                        planes[COVERAGE * w * h + y * w + x] += share;
                        for c in 0..3 {
                            planes[(LIGHT + c) * w * h + y * w + x] += sample[c] * share;
                        }
                    }
                }
            }
        }
    }
    planes
}

#[test]
fn the_gpu_reduction_matches_the_host_reduction_of_the_fine_gbuffers() {
    // A light seen directly and through glass, and a wall lit strongly enough to clamp white
    // in places: every branch of the reduction, for both G-buffers.
    let mut scene = empty_scene("light, glass and a bright wall");
    add_quads(
        &mut scene,
        &[
            Quad { centre: Vec3::new(0.0, 0.0, -1.0), u: Vec3::X * 10.0, v: Vec3::Y * 10.0, albedo: Vec3::splat(0.9), roughness: 1.0, transparent: false },
            Quad {
                centre: Vec3::new(0.2, 0.1, 0.0),
                u: Vec3::new(1.1, 0.3, 0.0),
                v: Vec3::new(-0.2, 0.7, 0.0),
                albedo: Vec3::splat(0.5),
                roughness: 1.0,
                transparent: false,
            },
            Quad { centre: Vec3::new(-0.4, 0.0, 0.5), u: Vec3::X, v: Vec3::Y * 2.0, albedo: Vec3::splat(0.9), roughness: 0.0, transparent: true },
        ],
    );
    scene.materials[1].emission = EMISSION;
    let cam = camera(Vec3::new(0.3, -0.2, 3.0), Vec3::ZERO, 55.0);
    let factor = 4;
    let mut r = rasterizer();
    let both = light_coverage(&mut r, &scene, &cam, W, H, factor).unwrap();
    let mut fine = r.begin_frame(&scene, &cam, W * factor, H * factor).unwrap();
    let (opaque, naive) = (fine.opaque().unwrap(), fine.naive().unwrap());
    for (name, gpu, host) in
        [("opaque", &both.opaque, reduce_on_host(&opaque, factor as usize)), ("naive", &both.naive, reduce_on_host(&naive, factor as usize))]
    {
        assert_eq!((gpu.width(), gpu.height()), (W, H));
        let covered = host.iter().take((W * H) as usize).filter(|&&c| c > 0.0 && c < 1.0).count();
        assert!(covered > 5, "{name}: {covered} partly covered pixels; the scene should have light edges");
        for (i, (&g, &h)) in gpu.data().iter().zip(&host).enumerate() {
            // The same sums in the same order; only the GPU's rounding (fused multiply-adds) differs.
            assert!((g - h).abs() <= 1e-5 * h.abs().max(1.0), "{name} value {i}: GPU {g}, host {h}");
        }
    }
}
