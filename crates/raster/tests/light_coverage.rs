//! Light coverage against the exact share of each pixel that a light covers: its corners
//! projected, the quadrilateral clipped to the pixel's square, the area measured (or, where the
//! light reaches behind the camera, rays on a fine grid over the pixel). Rectangle lights get
//! the exact pass; a glowing mesh the sampled one.

mod common;

use common::*;
use glam::{Vec2, Vec3};
use glassbake_raster::light_coverage::{composite, light_coverage, CoverageMethod, LIGHT_COVERAGE_FACTOR};

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

/// The exact pass's error budget: f32 clipping of outlines a few dozen pixels across.
const EXACT: f32 = 2e-4;

/// The area of a quad light of `centre`, `u`, `v` (full edges) inside each pixel, from its
/// projected corners.
fn exact_areas(cam: &glassbake_core::Camera, centre: Vec3, u: Vec3, v: Vec3) -> Vec<f32> {
    let corners = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
        .map(|(a, b)| cam.project(centre + u * a + v * b, W, H).map(|(px, py)| Vec2::new(px, py)).expect("in front of the camera"));
    (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).map(|(x, y)| area_in_pixel(&corners, x as f32, y as f32)).collect()
}

fn rect_light(centre: Vec3, u: Vec3, v: Vec3, radiance: Vec3) -> glassbake_scene::RectLight {
    light(centre - 0.5 * (u + v), u, v, radiance)
}

fn wall() -> Quad {
    Quad { centre: Vec3::new(0.0, 0.0, -1.0), u: Vec3::X * 10.0, v: Vec3::Y * 10.0, albedo: Vec3::splat(0.5), roughness: 1.0, transparent: false }
}

#[test]
fn a_rectangle_lights_coverage_is_the_area_of_its_outline_in_each_pixel() {
    let mut scene = empty_scene("tilted rectangle light");
    add_quads(&mut scene, &[wall()]);
    // Tilted out of the image plane and turned, so that no edge runs along the pixel grid.
    let (centre, u, v) = (Vec3::new(0.1, -0.05, 0.0), Vec3::new(0.8, 0.25, 0.3), Vec3::new(-0.2, 0.6, 0.1));
    scene.rect_lights.push(rect_light(centre, u, v, EMISSION));
    assert_eq!(CoverageMethod::for_scene(&scene, LIGHT_COVERAGE_FACTOR), CoverageMethod::Exact);
    let cam = camera(Vec3::new(0.2, 0.1, 3.0), Vec3::ZERO, 50.0);
    let exact = exact_areas(&cam, centre, u, v);
    let both = rasterizer().render(&scene, &cam, W, H).unwrap().light_coverage;
    assert_eq!(both.opaque.data(), both.naive.data(), "no glass: the naive G-buffer sees what the opaque one sees");
    let image = both.opaque;
    let mut edges = 0;
    for (i, &want) in exact.iter().enumerate() {
        let got = image.plane(0)[i];
        assert!((got - want).abs() <= EXACT, "pixel {i}: coverage {got}, exact {want}");
        edges += (want > 1e-3 && want < 1.0 - 1e-3) as usize;
        for (c, radiance) in EMISSION.to_array().into_iter().enumerate() {
            assert!((image.plane(1 + c)[i] - got * radiance).abs() <= 1e-5 * radiance, "pixel {i} channel {c}");
        }
    }
    assert!(edges > 30, "the light's edges cross {edges} pixels");
    // The same coverage from the free function, which draws a frame of its own.
    let alone = light_coverage(&mut rasterizer(), &scene, &cam, W, H, LIGHT_COVERAGE_FACTOR).unwrap();
    assert_eq!(alone.opaque.data(), image.data());
}

#[test]
fn a_one_sided_light_seen_from_behind_covers_nothing() {
    let mut scene = empty_scene("the back of a light");
    add_quads(&mut scene, &[wall()]);
    // u x v points away from the camera.
    scene.rect_lights.push(rect_light(Vec3::ZERO, Vec3::Y, Vec3::X, EMISSION));
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let coverage = rasterizer().render(&scene, &cam, W, H).unwrap().light_coverage;
    assert!(coverage.opaque.data().iter().all(|&v| v == 0.0));
    scene.rect_lights[0].two_sided = true;
    let coverage = rasterizer().render(&scene, &cam, W, H).unwrap().light_coverage;
    assert!(coverage.opaque.plane(0).iter().filter(|&&c| c == 1.0).count() > 20, "a two-sided light shows its back");
}

#[test]
fn an_occluder_hides_the_light_where_it_covers_the_pixels_centre() {
    let mut scene = empty_scene("a light half behind a box");
    // The occluder's right edge runs down the middle of the light.
    let occluder = Quad { centre: Vec3::new(-0.6, 0.0, 0.5), u: Vec3::X * 1.2, v: Vec3::Y * 3.0, albedo: Vec3::splat(0.5), roughness: 1.0, transparent: false };
    add_quads(&mut scene, &[wall(), occluder]);
    let (centre, u, v) = (Vec3::ZERO, Vec3::new(1.0, 0.1, 0.0), Vec3::new(-0.1, 0.8, 0.0));
    scene.rect_lights.push(rect_light(centre, u, v, EMISSION));
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let exact = exact_areas(&cam, centre, u, v);
    let coverage = rasterizer().render(&scene, &cam, W, H).unwrap().light_coverage.opaque;
    let (mut hidden, mut open) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            let ray = cam.pixel_center_ray(x, y, W, H);
            let got = coverage.plane(0)[i];
            if occluder.hit(ray.origin, ray.direction).is_some() {
                assert_eq!(got, 0.0, "pixel ({x}, {y}): the occluder covers its centre");
                hidden += (exact[i] > 0.0) as usize;
            } else {
                assert!((got - exact[i]).abs() <= EXACT, "pixel ({x}, {y}): coverage {got}, exact {}", exact[i]);
                open += (exact[i] > 0.0) as usize;
            }
        }
    }
    assert!(hidden > 20 && open > 20, "{hidden} pixels of the light hidden, {open} open");
}

#[test]
fn a_light_reaching_behind_the_camera_covers_what_rays_through_the_pixel_reach() {
    let mut scene = empty_scene("a ceiling light over the camera");
    add_quads(&mut scene, &[wall()]);
    // A ceiling-wide panel from behind the camera to half way to the wall, facing down.
    let light = glassbake_scene::RectLight {
        corner: Vec3::new(-1.0, 0.6, 4.0),
        edge_u: Vec3::NEG_Z * 3.5,
        edge_v: Vec3::X * 2.0,
        ..light(Vec3::ZERO, Vec3::X, Vec3::Y, EMISSION)
    };
    assert!(light.normal().y < -0.99, "the panel faces down");
    scene.rect_lights.push(light.clone());
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.0, 0.1, 0.0), 70.0);
    let coverage = rasterizer().render(&scene, &cam, W, H).unwrap().light_coverage.opaque;
    let panel = Quad { centre: light.center(), u: light.edge_u, v: light.edge_v, albedo: Vec3::ZERO, roughness: 1.0, transparent: false };
    // The share of a regular grid of rays over the pixel that reach the panel: off by at most
    // one row and one column of the grid where an edge crosses the pixel.
    let grid = 48;
    let (mut full, mut partial) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let mut hits = 0;
            for sy in 0..grid {
                for sx in 0..grid {
                    let (px, py) = (x as f32 + (sx as f32 + 0.5) / grid as f32, y as f32 + (sy as f32 + 0.5) / grid as f32);
                    let ray = cam.ray(px, py, W, H);
                    hits += panel.hit(ray.origin, ray.direction).is_some() as usize;
                }
            }
            let want = hits as f32 / (grid * grid) as f32;
            let got = coverage.plane(0)[(y * W + x) as usize];
            assert!((got - want).abs() <= 2.0 / grid as f32, "pixel ({x}, {y}): coverage {got}, {want} of the rays");
            full += (want == 1.0) as usize;
            partial += (want > 0.0 && want < 1.0) as usize;
        }
    }
    assert!(full > 100 && partial > 10, "{full} pixels inside the panel, {partial} on its edge");
}

#[test]
fn glass_in_front_of_a_rectangle_light_hides_it_from_the_naive_coverage_only() {
    let mut scene = empty_scene("rectangle light behind glass");
    add_quads(
        &mut scene,
        &[wall(), Quad { centre: Vec3::new(-0.5, 0.0, 0.5), u: Vec3::X, v: Vec3::Y * 2.0, albedo: Vec3::splat(0.9), roughness: 0.0, transparent: true }],
    );
    let (centre, u, v) = (Vec3::ZERO, Vec3::X, Vec3::Y);
    scene.rect_lights.push(rect_light(centre, u, v, EMISSION));
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let exact = exact_areas(&cam, centre, u, v);
    let buffers = rasterizer().render(&scene, &cam, W, H).unwrap();
    let (opaque, naive) = (buffers.light_coverage.opaque.plane(0), buffers.light_coverage.naive.plane(0));
    let glass = buffers.transparent[0].plane(glassbake_core::layout::transparent::COVERAGE);
    let (mut hidden, mut open) = (0, 0);
    for (i, &want) in exact.iter().enumerate() {
        assert!((opaque[i] - want).abs() <= EXACT, "pixel {i}: the opaque G-buffer sees the light through the glass");
        if glass[i] == 1.0 {
            assert_eq!(naive[i], 0.0, "pixel {i}: the glass hides the light from the naive G-buffer");
            hidden += (want > 0.0) as usize;
        } else {
            assert_eq!(naive[i], opaque[i], "pixel {i}: no glass at its centre, both G-buffers see the same light");
            open += (want > 0.0) as usize;
        }
    }
    assert!(hidden > 10 && open > 10, "{hidden} pixels of light behind glass, {open} in the open");
}
