//! Whole-renderer tests with known answers: white furnaces, a diffuse plane under a
//! rectangle light against its exact irradiance, the camera convention, determinism across
//! thread counts, and the bad-input rules.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3};
use glassbake_core::{Camera, Error};
use glassbake_scene::shapes::{rect, uv_sphere};
use glassbake_scene::{Material, Mesh, Object, RectLight, Scene};
use glassbake_trace::{render, Estimator, MaterialModel, PathFilter, PreparedScene, TraceSettings};

/// Settings for the plain estimator (the path tracer alone, uniform pixels, independent
/// values): the known answers below test the path tracer itself, and the estimators that
/// build on it are tested against it.
fn plain_settings(width: u32, height: u32, spp: u32, seed: u64) -> TraceSettings {
    TraceSettings { estimator: Estimator::PLAIN, ..TraceSettings::new(width, height, spp, seed) }
}

#[test]
fn library_callers_get_the_ground_truth_estimator_by_default() {
    assert_eq!(TraceSettings::new(8, 8, 4, 0).estimator, Estimator::default());
    assert_eq!(Estimator::default().name(), "caustic+adaptive+stratified");
}

/// The exact value of a box-filtered pixel of a Lambertian `object` (albedo `albedo`, facing
/// `normal`) lit only by the polygon `corners` of radiance `radiance`: the mean over a 4x4
/// grid in the pixel. `None` unless the whole pixel, edges and corners included, sees `object`.
#[allow(clippy::too_many_arguments)]
fn exact_pixel(
    prepared: &PreparedScene,
    camera: &Camera,
    (x, y, w, h): (u32, u32, u32, u32),
    object: usize,
    normal: Vec3,
    corners: &[Vec3],
    radiance: f32,
    albedo: f32,
) -> Option<f64> {
    let hits_object = |px: f32, py: f32| {
        prepared
            .intersect(&camera.ray(px, py, w, h))
            .filter(|hit| matches!(hit.owner, glassbake_trace::geometry::Owner::Object { object: o, .. } if o as usize == object))
    };
    let whole_pixel = (0..=4).all(|sy| (0..=4).all(|sx| hits_object(x as f32 + sx as f32 / 4.0, y as f32 + sy as f32 / 4.0).is_some()));
    if !whole_pixel {
        return None;
    }
    let mut expected = 0.0f64;
    for sy in 0..4 {
        for sx in 0..4 {
            let hit = hits_object(x as f32 + (sx as f32 + 0.5) / 4.0, y as f32 + (sy as f32 + 0.5) / 4.0)?;
            expected += polygon_irradiance(hit.position, normal, corners, radiance) * albedo as f64 / PI as f64 / 16.0;
        }
    }
    Some(expected)
}

/// (exact, rendered green channel) for every pixel that sees only `object` and gets
/// noticeable direct light (see [`exact_pixel`]).
#[allow(clippy::too_many_arguments)]
fn lit_pixels(
    image: &glassbake_core::PlanarImage,
    prepared: &PreparedScene,
    camera: &Camera,
    object: usize,
    normal: Vec3,
    corners: &[Vec3],
    radiance: f32,
    albedo: f32,
) -> Vec<(f64, f32)> {
    let (w, h) = (image.width(), image.height());
    let mut pixels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if let Some(expected) = exact_pixel(prepared, camera, (x, y, w, h), object, normal, corners, radiance, albedo) {
                if expected >= 1e-3 {
                    pixels.push((expected, image.get(1, x, y)));
                }
            }
        }
    }
    pixels
}

fn empty_scene(name: &str) -> Scene {
    Scene::empty(name)
}

fn add_object(scene: &mut Scene, name: &str, mesh: Mesh, material: Material) -> usize {
    scene.meshes.push(Arc::new(mesh));
    let transparent = material.is_transmissive();
    scene.materials.push(material);
    scene.objects.push(Object {
        name: name.to_string(),
        mesh: scene.meshes.len() - 1,
        material: scene.materials.len() - 1,
        transform: Affine3A::IDENTITY,
        transparent,
    });
    scene.objects.len() - 1
}

/// A unit sphere whose outside is its inside: faces and normals point to the centre.
fn inward_sphere() -> Mesh {
    let mut mesh = uv_sphere(1.0, 48, 24);
    for t in &mut mesh.indices {
        t.swap(1, 2);
    }
    for n in &mut mesh.normals {
        *n = -*n;
    }
    mesh
}

fn mean_and_extremes(values: &[f32]) -> (f64, f32, f32) {
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64;
    let lo = values.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    (mean, lo, hi)
}

/// Inside a closed emitting enclosure of albedo a and emission Le, radiance is the same
/// everywhere: L = Le (1 + a + a^2 + ...) = Le / (1 - a), or Le * N with a = 1 and paths
/// cut at N segments.
#[test]
fn white_furnace_inside_an_emitting_sphere() {
    let camera = Camera::look_at(Vec3::ZERO, Vec3::new(0.2, 0.1, -1.0), 60.0);
    for (albedo, max_depth, rr_depth, expected) in [(0.5f32, 10_000, 5, 2.0f64), (1.0, 5, u32::MAX, 5.0)] {
        let mut scene = empty_scene("furnace");
        let material = Material { emission: Vec3::ONE, ..Material::diffuse("shell", Vec3::splat(albedo)) };
        add_object(&mut scene, "shell", inward_sphere(), material);
        let settings = TraceSettings { max_depth, rr_depth, material_model: MaterialModel::Lambertian, ..plain_settings(8, 8, 128, 3) };
        let out = render(&scene, &camera, &settings, None).unwrap();
        assert_eq!(out.discarded_samples, 0);
        for channel in 0..3 {
            let (mean, lo, hi) = mean_and_extremes(out.image.plane(channel));
            eprintln!("emitting furnace, albedo {albedo}, channel {channel}: mean {mean:.5} (expected {expected}), pixels in [{lo:.4}, {hi:.4}]");
            assert!((mean - expected).abs() < 0.01 * expected, "albedo {albedo}: mean {mean}, expected {expected}");
            assert!(lo as f64 > 0.9 * expected && (hi as f64) < 1.1 * expected, "albedo {albedo}: pixels in [{lo}, {hi}]");
        }
    }
}

/// A closed object that neither emits nor absorbs, in a uniform environment of radiance 1,
/// is invisible: every pixel is 1. Glass must be invisible too (no absorption, no tint).
#[test]
fn white_furnace_with_an_environment() {
    let camera = Camera::look_at(Vec3::new(0.0, 0.3, 3.5), Vec3::ZERO, 40.0);
    let white_glass = |roughness: f32, thin: bool| Material::glass("glass", Vec3::ONE, roughness, 1.5, thin);
    let cases: [(&str, Mesh, Material, MaterialModel, f64); 4] = [
        ("lambertian sphere", uv_sphere(1.0, 48, 24), Material::diffuse("white", Vec3::ONE), MaterialModel::Lambertian, 0.01),
        ("smooth glass sphere", uv_sphere(1.0, 48, 24), white_glass(0.0, false), MaterialModel::Gltf, 0.01),
        ("thin pane", rect(Vec3::ZERO, Vec3::new(1.5, 0.0, -1.0), Vec3::Y * 1.5, Vec2::ONE), white_glass(0.0, true), MaterialModel::Gltf, 0.01),
        ("rough thin pane", rect(Vec3::ZERO, Vec3::new(1.5, 0.0, -1.0), Vec3::Y * 1.5, Vec2::ONE), white_glass(0.3, true), MaterialModel::Gltf, 0.05),
    ];
    for (name, mesh, material, model, tolerance) in cases {
        let mut scene = empty_scene(name);
        scene.background = Vec3::ONE;
        add_object(&mut scene, name, mesh, material);
        let settings = TraceSettings { material_model: model, ..plain_settings(12, 12, 64, 9) };
        let out = render(&scene, &camera, &settings, None).unwrap();
        let (mean, lo, hi) = mean_and_extremes(out.image.plane(1));
        eprintln!("environment furnace, {name}: mean {mean:.5}, pixels in [{lo:.4}, {hi:.4}]");
        assert!((mean - 1.0).abs() < tolerance, "{name}: mean {mean}");
        assert!(lo > 0.75 && hi < 1.25, "{name}: pixels in [{lo}, {hi}]");
    }
    // A rough glass sphere loses a little energy (single-scattering microfacets) and must
    // never gain any.
    let mut scene = empty_scene("rough glass");
    scene.background = Vec3::ONE;
    add_object(&mut scene, "sphere", uv_sphere(1.0, 48, 24), white_glass(0.3, false));
    let out = render(&scene, &camera, &plain_settings(12, 12, 64, 9), None).unwrap();
    let (mean, _, _) = mean_and_extremes(out.image.plane(1));
    eprintln!("environment furnace, rough glass sphere: mean {mean:.5}");
    assert!(mean < 1.01 && mean > 0.85, "rough glass sphere: mean {mean}");
}

/// Irradiance at `p` (normal `n`) from a uniformly emitting polygon of radiance `radiance`
/// entirely above p's horizon: Lambert's formula, E = L/2 * |sum_i theta_i n.gamma_i|
/// (Arvo 1995, "Applications of Irradiance Tensors to the Simulation of Non-Lambertian
/// Phenomena", eq. 6).
fn polygon_irradiance(p: Vec3, n: Vec3, corners: &[Vec3], radiance: f32) -> f64 {
    let mut sum = 0.0f64;
    for i in 0..corners.len() {
        let a = (corners[i] - p).as_dvec3().normalize();
        let b = (corners[(i + 1) % corners.len()] - p).as_dvec3().normalize();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        let gamma = a.cross(b).normalize();
        sum += theta * gamma.dot(n.as_dvec3());
    }
    0.5 * radiance as f64 * sum.abs()
}

/// The irradiance tests' set-up: a 1 m^2 light 1 m above a plane, seen from above.
struct PlaneUnderLight {
    albedo: f32,
    radiance: f32,
    corners: [Vec3; 4],
    camera: Camera,
}

impl PlaneUnderLight {
    fn new() -> Self {
        PlaneUnderLight {
            albedo: 0.5,
            radiance: 2.0,
            corners: [Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, 0.5), Vec3::new(-0.5, 1.0, 0.5)],
            camera: Camera::look_at(Vec3::new(2.2, 1.7, 2.6), Vec3::new(0.0, 0.0, 0.0), 55.0),
        }
    }
}

#[test]
fn diffuse_plane_under_a_rectangle_light_matches_exact_irradiance() {
    let PlaneUnderLight { albedo, radiance, corners, camera } = PlaneUnderLight::new();
    let (w, h) = (32u32, 32u32);
    for (light_kind, estimator) in [
        ("rect light", "plain"),
        ("rect light", "caustic"),
        ("rect light", "caustic+adaptive"),
        ("rect light", "caustic+adaptive+stratified"),
        ("emissive mesh", "plain+stratified"),
    ] {
        let estimator = Estimator::parse(estimator).unwrap();
        let mut scene = empty_scene(light_kind);
        let plane =
            add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), Material::diffuse("plane", Vec3::splat(albedo)));
        if light_kind == "rect light" {
            scene.rect_lights.push(RectLight {
                name: "light".into(),
                corner: corners[0],
                edge_u: Vec3::X,
                edge_v: Vec3::Z,
                radiance: Vec3::splat(radiance),
                two_sided: false,
            });
        } else {
            let emitter = Material { emission: Vec3::splat(radiance), ..Material::diffuse("emitter", Vec3::ZERO) };
            // rect() faces u x v = X x Z = -Y: down, onto the plane.
            add_object(&mut scene, "emitter", rect(Vec3::new(0.0, 1.0, 0.0), Vec3::X, Vec3::Z, Vec2::ONE), emitter);
        }
        let settings = TraceSettings { material_model: MaterialModel::Lambertian, estimator, ..plain_settings(w, h, 256, 17) };
        let out = render(&scene, &camera, &settings, None).unwrap();
        assert_eq!(out.discarded_samples, 0);
        assert_eq!(out.pilot_samples > 0, estimator.adaptive);
        let prepared = PreparedScene::new(&scene);
        let light_kind = format!("{light_kind}, {estimator}");
        let (mut relative_sum, mut count, mut worst) = (0.0f64, 0, 0.0f64);
        for (expected, rendered) in lit_pixels(&out.image, &prepared, &camera, plane, Vec3::Y, &corners, radiance, albedo) {
            let relative = rendered as f64 / expected - 1.0;
            relative_sum += relative;
            worst = worst.max(relative.abs());
            count += 1;
        }
        assert!(count > 300, "{light_kind}: only {count} plane pixels");
        let bias = relative_sum / count as f64;
        eprintln!("{light_kind}: {count} pixels, mean relative error {bias:+.5}, worst {worst:.4}");
        assert!(bias.abs() < 0.01, "{light_kind}: mean relative error {bias}");
        assert!(worst < 0.2, "{light_kind}: worst pixel off by {worst}");
    }
}

/// Two lights, a large dim one high up and a small bright one close to the plane: each
/// pixel's irradiance is the sum of the two exact ones. The caustic estimator picks the light
/// to sample by its contribution at each point (`LightSampler::contributions`) and samples
/// the rectangles by solid angle, the plain one picks by power and samples by area; both must
/// match on average (plain's worst pixel, 20% off at 256 spp, is its noise under the small
/// light: measured, not asserted).
#[test]
fn diffuse_plane_under_two_lights_matches_exact_irradiance() {
    let mut worst_pixels = Vec::new();
    let PlaneUnderLight { albedo, radiance, corners, camera } = PlaneUnderLight::new();
    let (small_corner, small_side, small_radiance) = (Vec3::new(0.6, 0.35, 0.2), 0.25f32, 16.0f32);
    let small_corners =
        [small_corner, small_corner + Vec3::X * small_side, small_corner + (Vec3::X + Vec3::Z) * small_side, small_corner + Vec3::Z * small_side];
    let (w, h) = (32u32, 32u32);
    for estimator in [Estimator::PLAIN, Estimator::default()] {
        let mut scene = empty_scene("two lights");
        let plane =
            add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), Material::diffuse("plane", Vec3::splat(albedo)));
        for (name, corner, side, radiance) in [("high", corners[0], 1.0, radiance), ("low", small_corner, small_side, small_radiance)] {
            scene.rect_lights.push(RectLight {
                name: name.into(),
                corner,
                edge_u: Vec3::X * side,
                edge_v: Vec3::Z * side,
                radiance: Vec3::splat(radiance),
                two_sided: false,
            });
        }
        let settings = TraceSettings { material_model: MaterialModel::Lambertian, estimator, ..plain_settings(w, h, 256, 23) };
        let out = render(&scene, &camera, &settings, None).unwrap();
        let prepared = PreparedScene::new(&scene);
        let (mut relative_sum, mut count, mut worst) = (0.0f64, 0, 0.0f64);
        for y in 0..h {
            for x in 0..w {
                let pixel = (x, y, w, h);
                let (Some(high), Some(low)) = (
                    exact_pixel(&prepared, &camera, pixel, plane, Vec3::Y, &corners, radiance, albedo),
                    exact_pixel(&prepared, &camera, pixel, plane, Vec3::Y, &small_corners, small_radiance, albedo),
                ) else {
                    continue;
                };
                let relative = out.image.get(1, x, y) as f64 / (high + low) - 1.0;
                relative_sum += relative;
                worst = worst.max(relative.abs());
                count += 1;
            }
        }
        assert!(count > 300, "{estimator}: only {count} plane pixels");
        let bias = relative_sum / count as f64;
        eprintln!("two lights, {estimator}: {count} pixels, mean relative error {bias:+.5}, worst {worst:.4}");
        assert!(bias.abs() < 0.01, "{estimator}: mean relative error {bias}");
        worst_pixels.push(worst);
    }
    // As in the one-light test: a pixel's centre against its box-filtered value, plus noise.
    assert!(worst_pixels[1] < 0.2, "caustic: worst pixel off by {}", worst_pixels[1]);
}

/// A glTF material with specularFactor 0 (KHR_materials_specular) is Lambertian under the
/// default material model: a plane under a rectangle light matches the exact irradiance x
/// albedo / pi within 0.5% on average.
#[test]
fn specular_factor_zero_plane_matches_exact_irradiance() {
    let PlaneUnderLight { albedo, radiance, corners, camera } = PlaneUnderLight::new();
    let (w, h) = (32u32, 32u32);
    let mut scene = empty_scene("lambertian plane");
    let plane =
        add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), Material::lambertian("plane", Vec3::splat(albedo)));
    scene.rect_lights.push(RectLight {
        name: "light".into(),
        corner: corners[0],
        edge_u: Vec3::X,
        edge_v: Vec3::Z,
        radiance: Vec3::splat(radiance),
        two_sided: false,
    });
    // Direct light only: the plane sees nothing else but the black background.
    let settings = TraceSettings { max_depth: 2, ..plain_settings(w, h, 1024, 23) };
    let out = render(&scene, &camera, &settings, None).unwrap();
    let prepared = PreparedScene::new(&scene);
    let (mut relative_sum, mut count) = (0.0f64, 0);
    for (expected, rendered) in lit_pixels(&out.image, &prepared, &camera, plane, Vec3::Y, &corners, radiance, albedo) {
        relative_sum += rendered as f64 / expected - 1.0;
        count += 1;
    }
    assert!(count > 300, "only {count} plane pixels");
    let bias = relative_sum / count as f64;
    eprintln!("specularFactor 0 plane: {count} pixels, mean relative error {bias:+.5}");
    assert!(bias.abs() < 0.005, "mean relative error {bias}");
}

#[test]
fn primary_rays_follow_the_camera_convention() {
    let (w, h) = (40u32, 30u32);
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 60.0);
    let mut scene = empty_scene("convention");
    // A light in the upper left of the view, facing the camera.
    let light = RectLight {
        name: "panel".into(),
        corner: Vec3::new(-1.8, 0.3, 0.0),
        edge_u: Vec3::X * 1.2,
        edge_v: Vec3::Y * 0.8,
        radiance: Vec3::new(3.0, 2.0, 1.0),
        two_sided: false,
    };
    scene.rect_lights.push(light.clone());
    add_object(&mut scene, "backdrop", rect(Vec3::new(0.0, 0.0, -1.0), Vec3::X * 20.0, Vec3::Y * 20.0, Vec2::ONE), Material::diffuse("grey", Vec3::splat(0.5)));
    let settings = TraceSettings { max_depth: 1, ..plain_settings(w, h, 16, 1) };
    let out = render(&scene, &camera, &settings, None).unwrap();

    let inside_light = |p: Vec3| {
        let d = p - light.corner;
        let (u, v) = (d.x / 1.2, d.y / 0.8);
        (0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)
    };
    let on_light_plane = |px: f32, py: f32| {
        let ray = camera.ray(px, py, w, h);
        ray.at(-ray.origin.z / ray.direction.z)
    };
    let projected: Vec<(f32, f32)> = light.corners().iter().map(|&c| camera.project(c, w, h).unwrap()).collect();
    let (mut lit, mut dark) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32, y as f32);
            let corners_inside =
                [(fx, fy), (fx + 1.0, fy), (fx, fy + 1.0), (fx + 1.0, fy + 1.0)].iter().filter(|&&(px, py)| inside_light(on_light_plane(px, py))).count();
            let light_corner_in_pixel = projected.iter().any(|&(px, py)| px >= fx && px <= fx + 1.0 && py >= fy && py <= fy + 1.0);
            let value = [out.image.get(0, x, y), out.image.get(1, x, y), out.image.get(2, x, y)];
            if corners_inside == 4 {
                assert_eq!(value, [3.0, 2.0, 1.0], "pixel ({x}, {y}) is fully on the light");
                lit += 1;
            } else if corners_inside == 0 && !light_corner_in_pixel {
                assert_eq!(value, [0.0, 0.0, 0.0], "pixel ({x}, {y}) does not see the light");
                dark += 1;
            }
        }
    }
    assert!(lit > 20 && dark > 600, "lit {lit}, dark {dark}");
    // Row 0 is the top and x grows to the camera's right: the light is in the upper left.
    assert_eq!(out.image.get(0, 11, 10), 3.0);
    assert_eq!(out.image.get(0, w - 8, h - 6), 0.0);

    // The path tracer's primary hit at a pixel centre lies on Camera::pixel_center_ray and
    // projects back onto that pixel centre.
    let prepared = PreparedScene::new(&scene);
    for &(x, y) in &[(0u32, 0u32), (8, 6), (39, 29), (20, 15), (3, 27)] {
        let ray = camera.pixel_center_ray(x, y, w, h);
        let hit = prepared.intersect(&ray).expect("the backdrop fills the view");
        let off_ray = (hit.position - ray.origin).cross(ray.direction).length();
        assert!(off_ray < 1e-5, "({x}, {y}): {off_ray}");
        assert!((hit.position - ray.at(hit.distance)).length() < 1e-4);
        let (px, py) = camera.project(hit.position, w, h).unwrap();
        assert!((px - (x as f32 + 0.5)).abs() < 1e-3 && (py - (y as f32 + 0.5)).abs() < 1e-3, "({x}, {y}) -> ({px}, {py})");
    }
}

fn bits(image: &glassbake_core::PlanarImage) -> Vec<u32> {
    image.data().iter().map(|v| v.to_bits()).collect()
}

#[test]
fn images_are_bit_identical_whatever_the_thread_count() {
    let scene = glassbake_scene::builtin::builtin("cornell-glass").unwrap();
    let camera = scene.sample(0, 0).camera;
    // Not a multiple of the tile size, to include partial tiles.
    let base = plain_settings(24, 20, 2, 42);
    let images: Vec<Vec<u32>> = [Some(1), Some(2), Some(3)]
        .into_iter()
        .map(|threads| bits(&render(&scene, &camera, &TraceSettings { threads, ..base.clone() }, None).unwrap().image))
        .collect();
    assert_eq!(images[0], images[1]);
    assert_eq!(images[0], images[2]);
    let other_seed = bits(&render(&scene, &camera, &TraceSettings { seed: 43, threads: Some(2), ..base.clone() }, None).unwrap().image);
    assert_ne!(images[0], other_seed);
}

/// With `glass_spp`, the pixels that show glass get more samples from their own streams:
/// each pixel is bit-identical to a uniform render at its spp, and the glass pixels are where
/// the pane projects (checked against the projected corners of its rectangle, independently
/// of the tracer's ray casts).
#[test]
fn glass_pixels_get_glass_spp_and_match_a_uniform_render_at_it() {
    let scene = glassbake_scene::builtin::builtin("cornell-glass").unwrap();
    let camera = scene.sample(0, 0).camera;
    let (w, h) = (24, 20);
    let render_at = |spp: u32, glass_spp: Option<u32>| render(&scene, &camera, &TraceSettings { glass_spp, ..plain_settings(w, h, spp, 42) }, None).unwrap();
    let (low, high, mixed) = (render_at(2, None), render_at(6, None), render_at(2, Some(6)));
    let glass = glassbake_trace::glass_pixels(&PreparedScene::new(&scene), &camera, w, h);
    let glass_count = glass.iter().filter(|&&g| g).count();
    assert_eq!(mixed.samples, (w * h) as u64 * 2 + glass_count as u64 * 4);
    let (low, high, mixed) = (bits(&low.image), bits(&high.image), bits(&mixed.image));
    let pixels = (w * h) as usize;
    for (i, &is_glass) in glass.iter().enumerate() {
        for c in 0..3 {
            let expected = if is_glass { high[c * pixels + i] } else { low[c * pixels + i] };
            assert_eq!(mixed[c * pixels + i], expected, "pixel {i} (glass: {is_glass}), channel {c}");
        }
    }
    // The pane's projected rectangle: pixels wholly inside it show glass, pixels more than a
    // pixel outside do not (the scene has no other transparent object).
    let pane = scene.objects.iter().position(|o| o.transparent).unwrap();
    let corners: Vec<Vec2> = scene.world_mesh(pane).positions.iter().map(|&p| camera.project(p, w, h).map(|(x, y)| Vec2::new(x, y)).unwrap()).collect();
    assert_eq!(corners.len(), 4, "the pane is one rectangle");
    let hull = convex_hull(&corners);
    let signed_distance = |p: Vec2| -> f32 {
        // Negative inside: the largest signed distance to the hull's edges (counter-clockwise).
        (0..hull.len())
            .map(|k| {
                let (a, b) = (hull[k], hull[(k + 1) % hull.len()]);
                let edge = (b - a).normalize();
                -(edge.perp_dot(p - a))
            })
            .fold(f32::MIN, f32::max)
    };
    let (mut inside, mut outside) = (0, 0);
    for (i, &is_glass) in glass.iter().enumerate() {
        let centre = Vec2::new((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
        let d = signed_distance(centre);
        if d < -0.75 {
            assert!(is_glass, "pixel {i} lies inside the pane's projection but is not a glass pixel");
            inside += 1;
        } else if d > 1.5 {
            assert!(!is_glass, "pixel {i} lies outside the pane's projection but is a glass pixel");
            outside += 1;
        }
    }
    assert!(inside > 20 && outside > 20, "the view must show both: {inside} inside, {outside} outside");
}

/// The convex hull of a few points, counter-clockwise (gift wrapping).
fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let start = points.iter().copied().fold(points[0], |a, b| if b.x < a.x { b } else { a });
    let mut hull = vec![start];
    loop {
        let current = *hull.last().unwrap();
        let mut next = points[0];
        for &p in points {
            if next == current || (next - current).perp_dot(p - current) < 0.0 {
                next = p;
            }
        }
        if next == start {
            return hull;
        }
        hull.push(next);
    }
}

/// Sample 0 of built-in `scene` rendered with `base` on 1, 2 and 3 threads, and with the
/// plain estimator (same settings otherwise).
fn renders_on_1_2_3_threads_and_plain(scene: &str, base: &TraceSettings) -> (Vec<glassbake_trace::TraceOutput>, glassbake_trace::TraceOutput) {
    let scene = glassbake_scene::builtin::builtin(scene).unwrap();
    let sample = scene.sample(0, 0);
    let instance = scene.instantiate(&sample.values).unwrap();
    let renders = [Some(1), Some(2), Some(3)]
        .into_iter()
        .map(|threads| render(&instance, &sample.camera, &TraceSettings { threads, ..base.clone() }, None).unwrap())
        .collect();
    let plain = render(&instance, &sample.camera, &TraceSettings { estimator: Estimator::PLAIN, ..base.clone() }, None).unwrap();
    (renders, plain)
}

/// The light tracer's paths are traced in chunks of their own streams and summed in chunk
/// order: the caustic estimator's images do not depend on the thread count.
#[test]
fn caustic_images_are_bit_identical_whatever_the_thread_count() {
    // 40 x 36 x 24 camera samples, a quarter as many light paths: 8,640, three chunks of
    // 4,096, the last one short.
    let base = TraceSettings { estimator: Estimator::parse("caustic").unwrap(), ..plain_settings(40, 36, 24, 5) };
    let (renders, plain) = renders_on_1_2_3_threads_and_plain("cornellbox8", &base);
    assert_eq!(bits(&renders[0].image), bits(&renders[1].image));
    assert_eq!(bits(&renders[0].image), bits(&renders[2].image));
    assert_ne!(bits(&renders[0].image), bits(&plain.image), "the caustic estimator must differ from the plain one");
}

/// Adaptive sampling decides each pixel's count from a pilot it then sets aside, pixel by
/// pixel in a fixed order, and stratified values are a function of (seed, pixel, sample,
/// dimension): their images do not depend on the thread count, and the image's total of
/// samples is the uniform render's.
#[test]
fn adaptive_stratified_images_are_bit_identical_whatever_the_thread_count() {
    // 256 spp: a pilot of 16 per pixel, then 240 per pixel on average, 64 to 4,096 each.
    let base = TraceSettings { estimator: Estimator::default(), ..plain_settings(24, 20, 256, 5) };
    let (renders, _) = renders_on_1_2_3_threads_and_plain("desk", &base);
    assert_eq!(renders[0].pilot_samples, 24 * 20 * 16);
    assert_eq!(renders[0].samples, 24 * 20 * 256);
    assert_eq!(bits(&renders[0].image), bits(&renders[1].image));
    assert_eq!(bits(&renders[0].image), bits(&renders[2].image));
    let uniform = render_sample("desk", &TraceSettings { estimator: Estimator { adaptive: false, ..base.estimator }, threads: Some(2), ..base.clone() });
    assert_ne!(bits(&renders[0].image), bits(&uniform.image), "adaptive sampling must change the image");
    let independent = render_sample("desk", &TraceSettings { estimator: Estimator { stratified: false, ..base.estimator }, threads: Some(2), ..base.clone() });
    assert_ne!(bits(&renders[0].image), bits(&independent.image), "stratified values must change the image");
}

/// Photon merging traces its photons in chunks of their own streams and keeps them in the
/// order traced, so merged images do not depend on the thread count either.
#[test]
fn merged_images_are_bit_identical_whatever_the_thread_count() {
    let scene = glassbake_scene::builtin::builtin("cornellbox").unwrap();
    let sample = scene.sample(0, 0);
    let instance = scene.instantiate(&sample.values).unwrap();
    let base = TraceSettings { estimator: Estimator::parse("caustic+merging+adaptive+stratified").unwrap(), ..plain_settings(24, 20, 128, 5) };
    let renders: Vec<_> =
        [1, 2, 3].map(|threads| render(&instance, &sample.camera, &TraceSettings { threads: Some(threads), ..base.clone() }, None).unwrap()).into();
    // 0.1 light paths per camera sample (the pilot's samples included).
    assert_eq!(renders[0].photon_paths, (24 * 20 * 128u64).div_ceil(10));
    // The scene is lit by its lights alone, so a global map as large is traced too.
    assert_eq!(renders[0].global_photon_paths, renders[0].photon_paths);
    assert!(renders[0].merge_radius > 0.0);
    assert_eq!(bits(&renders[0].image), bits(&renders[1].image));
    assert_eq!(bits(&renders[0].image), bits(&renders[2].image));
    let unmerged = render(&instance, &sample.camera, &TraceSettings { estimator: Estimator::default(), threads: Some(2), ..base.clone() }, None).unwrap();
    assert_eq!(unmerged.photon_paths, 0);
    assert_ne!(bits(&renders[0].image), bits(&unmerged.image), "merging must change the image");
    // The desk's background lights it too, and a gather of the lights' photons would miss
    // what of that light scattered: no global map there.
    let desk = render_sample("desk", &TraceSettings { threads: Some(2), ..base.clone() });
    assert!(desk.photon_paths > 0 && desk.global_photon_paths == 0, "{} {}", desk.photon_paths, desk.global_photon_paths);
}

/// What merging is for: the light seen in or through bending glass (the bent-view part of
/// the image) is far less noisy merged than path traced, and its mean stays the unbiased
/// estimator's within the noise and a 1% allowance for the kernel's blur (each estimator from
/// renders of seeds of its own; the blur moves light between pixels and keeps nearly all of it). On cornellbox that is the
/// caustics through the frosted cylinder and the globe seen through them (merged as
/// caustics); on bathroom the shower seen through the rough partition, whose blur is wide
/// enough for its paths to take all scattered light from the global photons. And the final
/// gather: the bathroom's straight view, lit mostly by light of many bounces, takes it from
/// the global photons at its second vertex.
#[test]
fn merging_quiets_what_is_seen_through_glass_and_keeps_its_light() {
    for (name, path_filter, least_gain) in
        [("cornellbox", PathFilter::BentView, 1.5), ("bathroom", PathFilter::BentView, 2.0), ("bathroom", PathFilter::StraightView, 1.3)]
    {
        let scene = glassbake_scene::builtin::builtin(name).unwrap();
        let sample = scene.sample(0, 0);
        let instance = scene.instantiate(&sample.values).unwrap();
        // (mean of RENDERS renders, variance of that mean, a pixel's noise in one render).
        // The noise is the squared mean absolute deviation from the pixel's mean, not the
        // sample variance: a few renders' variance is decided by a few rare bright paths of
        // either estimator (cornellbox's bent view: the variance gain came out 0.8x from 4
        // renders, 1.4x from 8 and 16, 2.2x from 64), the absolute deviation by the noise
        // that fills the image.
        const RENDERS: u64 = 8;
        let estimate = |photon_merging: bool, seed_base: u64| {
            let images: Vec<_> = (seed_base..seed_base + RENDERS)
                .map(|seed| {
                    let estimator = Estimator { transport: glassbake_trace::Transport::Caustic { photon_merging }, ..Estimator::default() };
                    let settings = TraceSettings { estimator, path_filter, ..plain_settings(32, 32, 256, seed) };
                    render(&instance, &sample.camera, &settings, None).unwrap().image
                })
                .collect();
            let n = images[0].data().len();
            let r = RENDERS as f64;
            let (mut total, mut variance_sum, mut deviation_sum) = (0.0f64, 0.0f64, 0.0f64);
            for i in 0..n {
                let values: Vec<f64> = images.iter().map(|image| image.data()[i] as f64).collect();
                let mean = values.iter().sum::<f64>() / r;
                total += mean;
                variance_sum += values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (r - 1.0);
                deviation_sum += values.iter().map(|v| (v - mean).abs()).sum::<f64>() / r;
            }
            let n = n as f64;
            (total / n, variance_sum / (n * n) / r, (deviation_sum / n).powi(2))
        };
        let (traced, traced_error, traced_noise) = estimate(false, 80);
        let (merged, merged_error, merged_noise) = estimate(true, 90);
        let z = (merged - traced).abs() / (traced_error + merged_error).sqrt();
        let gain = traced_noise / merged_noise;
        eprintln!("{name} {path_filter:?}, 32 px 256 spp: mean traced {traced:.5}, merged {merged:.5} (z {z:.2}); squared mean deviation traced {traced_noise:.3e}, merged {merged_noise:.3e} ({gain:.1}x)");
        assert!(traced > 0.0, "{name}: the bent view carries light");
        // Merging is biased by design (the kernel's blur): the light is kept when the means
        // agree within the noise plus 1% (measured: the bathroom's bent view 0.2-0.5% darker
        // merged, 8 renders of three seed sets).
        let allowed = 4.0 * (traced_error + merged_error).sqrt() + 0.01 * traced;
        assert!((merged - traced).abs() < allowed, "{name}: merged mean {merged} vs traced {traced}: z = {z:.2}, beyond the noise and 1%");
        assert!(gain > least_gain, "{name}: merged {merged_noise:.3e} vs traced {traced_noise:.3e}");
    }
}

/// The path filters split the image exactly: the bent-view and straight-view parts add up
/// to the full image pixel by pixel (the same samples, each contribution counted in one part,
/// the light tracer's splats in the straight part, adaptive sampling's allocation from the
/// whole image), and on cornellbox, whose frosted cylinder and glass globe bend the view,
/// both parts carry light.
#[test]
fn path_filters_split_the_image_exactly() {
    let base = TraceSettings { estimator: Estimator::default(), ..plain_settings(24, 20, 256, 3) };
    let [all, bent, straight] = [PathFilter::All, PathFilter::BentView, PathFilter::StraightView]
        .map(|path_filter| render_sample("cornellbox", &TraceSettings { path_filter, ..base.clone() }).image);
    let (mut bent_sum, mut straight_sum) = (0.0f64, 0.0f64);
    for c in 0..3 {
        for y in 0..20 {
            for x in 0..24 {
                let (a, b, s) = (all.get(c, x, y), bent.get(c, x, y), straight.get(c, x, y));
                assert!((a - (b + s)).abs() <= 1e-4 * a.abs().max(1.0), "pixel ({x}, {y}) channel {c}: {a} != {b} + {s}");
                bent_sum += b as f64;
                straight_sum += s as f64;
            }
        }
    }
    assert!(bent_sum > 0.0 && straight_sum > 0.0, "bent {bent_sum}, straight {straight_sum}");
    assert!(bent_sum < straight_sum, "the view bends on a few glass objects only: bent {bent_sum}, straight {straight_sum}");
}

/// The light tracer's budget follows where it pays: on cornell-glass (a light seen in a
/// pane, caustics over most of the floor) the balanced budget is several times the desk's
/// (small glass objects whose caustics are a few pixels), and the image's samples and light
/// paths are reported.
#[test]
fn the_light_tracing_budget_follows_where_it_pays() {
    let settings = TraceSettings { estimator: Estimator::parse("caustic+stratified").unwrap(), ..plain_settings(32, 32, 128, 7) };
    let rate = |scene: &str| {
        let output = render_sample(scene, &settings);
        assert_eq!(output.samples, 32 * 32 * 128);
        assert!(output.light_pilot_paths >= 1024, "{scene}: pilot of {} light paths", output.light_pilot_paths);
        output.light_paths as f64 / output.samples as f64
    };
    let (glass, desk) = (rate("cornell-glass"), rate("desk"));
    assert!(desk >= 1.0 / 64.0 && glass <= 1.0, "rates {glass}, {desk} outside the bounds");
    assert!(glass > 3.0 * desk, "light paths per camera sample: cornell-glass {glass:.3}, desk {desk:.3}");
}

/// Stratified values pay where the integrand is smooth: a plane under a rectangle light
/// (soft direct light, pixel footprints) has far less variance at equal spp than with
/// independent random numbers. Variances from two independent renders each.
#[test]
fn stratified_sampling_lowers_the_variance_of_direct_light() {
    let PlaneUnderLight { albedo, radiance, corners, camera } = PlaneUnderLight::new();
    let mut scene = empty_scene("stratified");
    add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), Material::diffuse("plane", Vec3::splat(albedo)));
    scene.rect_lights.push(RectLight {
        name: "light".into(),
        corner: corners[0],
        edge_u: Vec3::X,
        edge_v: Vec3::Z,
        radiance: Vec3::splat(radiance),
        two_sided: false,
    });
    let variance = |stratified: bool| {
        let [a, b] = [3u64, 4].map(|seed| {
            let estimator = Estimator { stratified, ..Estimator::PLAIN };
            let settings = TraceSettings { material_model: MaterialModel::Lambertian, estimator, ..plain_settings(32, 32, 64, seed) };
            render(&scene, &camera, &settings, None).unwrap().image
        });
        a.data().iter().zip(b.data()).map(|(&x, &y)| (x as f64 - y as f64).powi(2) / 2.0).sum::<f64>() / a.data().len() as f64
    };
    let (independent, stratified) = (variance(false), variance(true));
    eprintln!("plane under a light, 32 px 64 spp: variance independent {independent:.3e}, stratified {stratified:.3e} ({:.1}x)", independent / stratified);
    assert!(stratified < 0.5 * independent, "stratified {stratified:.3e} vs independent {independent:.3e}");
}

/// Sample 0 of built-in `scene` rendered with `settings`.
fn render_sample(scene: &str, settings: &TraceSettings) -> glassbake_trace::TraceOutput {
    let scene = glassbake_scene::builtin::builtin(scene).unwrap();
    let sample = scene.sample(0, 0);
    let instance = scene.instantiate(&sample.values).unwrap();
    render(&instance, &sample.camera, settings, None).unwrap()
}

/// Adaptive sampling is worth its pilot where the noise is uneven: on the desk (the glass
/// objects and the brass pen are far noisier than the wood) the image's variance as the
/// metrics see it (clamped to [0, 1]) at equal samples falls well below the uniform
/// render's. Variances from two independent renders each.
#[test]
fn adaptive_sampling_lowers_the_variance_of_an_uneven_image() {
    let clamped_variance = |adaptive: bool| {
        let [a, b] = [11u64, 12].map(|seed| {
            let estimator = Estimator { adaptive, ..Estimator::parse("caustic").unwrap() };
            render_sample("desk", &TraceSettings { estimator, ..plain_settings(32, 32, 256, seed) }).image
        });
        let clamp = |v: f32| v.clamp(0.0, 1.0) as f64;
        a.data().iter().zip(b.data()).map(|(&x, &y)| (clamp(x) - clamp(y)).powi(2) / 2.0).sum::<f64>() / a.data().len() as f64
    };
    let (uniform, adaptive) = (clamped_variance(false), clamped_variance(true));
    eprintln!("desk 32 px 256 spp: clamped variance uniform {uniform:.3e}, adaptive {adaptive:.3e} ({:.2}x)", uniform / adaptive);
    assert!(adaptive < 0.75 * uniform, "adaptive {adaptive:.3e} vs uniform {uniform:.3e}");
}

/// No bias: on every built-in scene the caustic estimator (also with adaptive sampling and
/// stratified values) converges to the plain one's image, in every region and channel: the
/// pixels that show glass, the pixels lit through glass (the surface seen at the pixel's
/// centre reaches a rectangle light's centre only through a transparent object: where the
/// light tracer's caustics land), the other pixels of each image quadrant, and the whole
/// image.
///
/// A Welch t-test on the region means of independent renders. The standard error comes from
/// the spread between whole renders, not from per-pixel differences: the `caustic`
/// estimator's light paths splat across the image and its light-path budget is set per
/// image, so its pixels' errors are correlated and a per-pixel estimate understates the
/// error of an image mean about 2x (16 renders of cornellbox8: 0.74% between renders against
/// 0.39% from pixel pairs).
///
/// The threshold, t < 7 with about 8 degrees of freedom each side, keeps the chance of a
/// false alarm over all the tests here small while a bias of a few percent in a region
/// (a 20% bias over 15% of the image is 3% of the whole mean and more in its quadrant) is
/// many standard errors.
#[test]
fn every_estimator_converges_to_the_same_image_in_every_region() {
    const RENDERS: u64 = 6;
    const SIZE: u32 = 32;
    let mut scenes_lit_through_glass = 0;
    for name in glassbake_scene::builtin::BUILTIN_NAMES {
        let scene = glassbake_scene::builtin::builtin(name).unwrap();
        let sample = scene.sample(0, 0);
        let instance = scene.instantiate(&sample.values).unwrap();
        let prepared = PreparedScene::new(&instance);
        let glass = glassbake_trace::glass_pixels(&prepared, &sample.camera, SIZE, SIZE);
        let transparent = |hit: &glassbake_trace::SurfaceHit| matches!(hit.owner, glassbake_trace::geometry::Owner::Object { object, .. } if instance.objects[object as usize].transparent);
        let lit_through_glass: Vec<bool> = (0..SIZE * SIZE)
            .map(|index| {
                let ray = sample.camera.ray((index % SIZE) as f32 + 0.5, (index / SIZE) as f32 + 0.5, SIZE, SIZE);
                let Some(hit) = prepared.intersect(&ray).filter(|hit| !transparent(hit)) else { return false };
                instance.rect_lights.iter().any(|light| {
                    let centre = light.corner + 0.5 * (light.edge_u + light.edge_v);
                    let direction = (centre - hit.position).normalize();
                    let origin = glassbake_trace::prepared::offset_origin(hit.position, hit.geometric_normal, direction);
                    prepared.intersect(&glassbake_core::Ray { origin, direction }).is_some_and(|blocker| transparent(&blocker))
                })
            })
            .collect();
        let lit_pixels = lit_through_glass.iter().filter(|&&lit| lit).count();
        eprintln!("{name}: {} glass pixels, {lit_pixels} lit through glass", glass.iter().filter(|&&g| g).count());
        scenes_lit_through_glass += (lit_pixels >= 16) as usize;
        // Region of each pixel: 0 glass, 1 lit through glass, 2-5 the image quadrants' other
        // pixels.
        let region_of = |index: usize| {
            let (x, y) = (index as u32 % SIZE, index as u32 / SIZE);
            if glass[index] {
                0
            } else if lit_through_glass[index] {
                1
            } else {
                2 + (x >= SIZE / 2) as usize + 2 * (y >= SIZE / 2) as usize
            }
        };
        let labels = ["glass pixels", "lit through glass", "top-left", "top-right", "bottom-left", "bottom-right", "whole image"];
        const REGIONS: usize = 7;
        const WHOLE: usize = REGIONS - 1;
        // Per region (and the whole image last) and channel: the mean over the renders of the
        // region mean, and the variance of that mean. Each estimator gets seeds of its own:
        // shared random streams would correlate the errors and hide a bias.
        let estimate = |estimator: Estimator, seed_base: u64| {
            let region_means: Vec<[[f64; 3]; REGIONS]> = (seed_base..seed_base + RENDERS)
                .map(|seed| {
                    let settings = TraceSettings { estimator, ..plain_settings(SIZE, SIZE, 256, seed) };
                    let image = render(&instance, &sample.camera, &settings, None).unwrap().image;
                    let plane = (SIZE * SIZE) as usize;
                    let mut sums = [[0.0f64; 3]; REGIONS];
                    let mut counts = [0usize; REGIONS];
                    for index in 0..plane {
                        for region in [region_of(index), WHOLE] {
                            counts[region] += 1;
                            for (c, sum) in sums[region].iter_mut().enumerate() {
                                *sum += image.data()[c * plane + index] as f64;
                            }
                        }
                    }
                    std::array::from_fn(|r| sums[r].map(|s| s / counts[r].max(1) as f64))
                })
                .collect();
            let counts: [usize; REGIONS] =
                std::array::from_fn(|r| if r == WHOLE { 1 } else { (0..(SIZE * SIZE) as usize).filter(|&i| region_of(i) == r).count() });
            let n = RENDERS as f64;
            std::array::from_fn::<_, REGIONS, _>(|r| {
                std::array::from_fn::<_, 3, _>(|c| {
                    let mean = region_means.iter().map(|m| m[r][c]).sum::<f64>() / n;
                    let variance = region_means.iter().map(|m| (m[r][c] - mean).powi(2)).sum::<f64>() / (n - 1.0);
                    (mean, variance / n, counts[r])
                })
            })
        };
        let plain = estimate(Estimator::PLAIN, 20);
        let others = [("caustic", 50), ("caustic+adaptive", 60), ("caustic+adaptive+stratified", 70)];
        for (label, seed_base) in others {
            let other = estimate(Estimator::parse(label).unwrap(), seed_base);
            let mut worst = (0.0f64, String::new());
            for r in 0..REGIONS {
                if other[r][0].2 == 0 {
                    continue;
                }
                for c in 0..3 {
                    let ((p, p_var, _), (o, o_var, _)) = (plain[r][c], other[r][c]);
                    let standard_error = (p_var + o_var).sqrt();
                    let t = if standard_error > 0.0 {
                        (o - p).abs() / standard_error
                    } else if o == p {
                        0.0
                    } else {
                        f64::INFINITY
                    };
                    let line = format!(
                        "{}, channel {c}: plain {p:.5}, {label} {o:.5} ({:+.2}%, standard error {:.2}%), t {t:.2}",
                        labels[r],
                        100.0 * (o / p - 1.0),
                        100.0 * standard_error / p
                    );
                    if r == WHOLE && c == 1 {
                        eprintln!("{name}: {line}");
                    }
                    assert!(t < 7.0, "{name}: {line}");
                    if t > worst.0 {
                        worst = (t, line);
                    }
                }
            }
            eprintln!("{name}: {label}: largest t {:.2} ({})", worst.0, worst.1);
        }
    }
    // The region the light tracer carries must be there to be tested: the Cornell boxes' floors
    // under their glass, the bathroom's shower behind its partition (measured: 21-98 pixels of
    // 1024 on four scenes, 15 on desk).
    assert!(scenes_lit_through_glass >= 3, "only {scenes_lit_through_glass} scenes have 16 pixels lit through glass");
}

#[test]
fn bad_input_is_refused() {
    let scene = glassbake_scene::builtin::builtin("cornell-glass").unwrap();
    let camera = scene.camera.middle();
    let glass_below_spp = TraceSettings { glass_spp: Some(32), ..plain_settings(8, 8, 64, 0) };
    let huge = plain_settings(100_000, 8, 4, 0);
    for settings in [plain_settings(0, 8, 4, 0), plain_settings(8, 0, 4, 0), plain_settings(8, 8, 0, 0), glass_below_spp, huge] {
        match render(&scene, &camera, &settings, None) {
            Err(e @ Error::BadInput { .. }) => assert!(e.is_user_error()),
            Err(e) => panic!("expected bad input, got {e}"),
            Ok(_) => panic!("{settings:?} was accepted"),
        }
    }
    let looking_up = Camera { target: camera.position + Vec3::Y, ..camera };
    for degenerate in [Camera { target: camera.position, ..camera }, looking_up, Camera { fov_x_deg: 0.0, ..camera }] {
        assert!(matches!(render(&scene, &degenerate, &plain_settings(4, 4, 1, 0), None), Err(Error::BadInput { .. })), "{degenerate:?}");
    }
}

#[test]
fn a_scene_without_lights_renders_black_with_a_warning() {
    let mut scene = empty_scene("dark");
    add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, Vec2::ONE), Material::diffuse("grey", Vec3::splat(0.5)));
    let camera = Camera::look_at(Vec3::new(0.0, 1.0, 1.0), Vec3::ZERO, 50.0);
    let out = render(&scene, &camera, &plain_settings(8, 8, 4, 0), None).unwrap();
    assert!(out.image.data().iter().all(|&v| v == 0.0));
    assert!(out.warnings.iter().any(|w| w.contains("no light")), "{:?}", out.warnings);
}

#[test]
fn non_finite_samples_are_discarded_and_counted() {
    let mut scene = empty_scene("nan sky");
    scene.background = Vec3::new(f32::NAN, 1.0, 1.0);
    // Half the view is a lit plane, half the NaN sky.
    add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X * 50.0, Vec3::NEG_Z * 50.0, Vec2::ONE), Material::diffuse("grey", Vec3::splat(0.5)));
    scene.rect_lights.push(RectLight {
        name: "light".into(),
        corner: Vec3::new(-0.5, 2.0, -0.5),
        edge_u: Vec3::X,
        edge_v: Vec3::Z,
        radiance: Vec3::ONE,
        two_sided: false,
    });
    let camera = Camera::look_at(Vec3::new(0.0, 1.0, 3.0), Vec3::new(0.0, 1.0, 0.0), 60.0);
    let settings = TraceSettings { max_depth: 1, ..plain_settings(8, 8, 4, 0) };
    let out = render(&scene, &camera, &settings, None).unwrap();
    assert!(out.image.data().iter().all(|v| v.is_finite()));
    // With max depth 1, exactly the camera rays that miss everything are NaN: the upper half.
    assert!(out.discarded_samples >= 4 * 8 * 3 && out.discarded_samples <= 4 * 8 * 5, "{}", out.discarded_samples);
    assert!(out.warnings.iter().any(|w| w.contains("discarded")));
}

#[test]
fn builtin_scenes_render_finite_and_lit() {
    for name in glassbake_scene::builtin::BUILTIN_NAMES {
        let scene = glassbake_scene::builtin::builtin(name).unwrap();
        let sample = scene.sample(7, 0);
        let instance = scene.instantiate(&sample.values).unwrap();
        let out = render(&instance, &sample.camera, &plain_settings(8, 8, 2, 1), None).unwrap();
        assert_eq!(out.discarded_samples, 0, "{name}");
        let mean: f32 = out.image.data().iter().sum::<f32>() / out.image.data().len() as f32;
        assert!(mean > 0.01 && mean.is_finite(), "{name}: mean {mean}");
    }
}

/// Direct light through a smooth thin pane: shadow rays cross it (attenuated by the slab's
/// transmittance T'(theta) and the tint) and BSDF samples cross it too; MIS must weigh the
/// two consistently for the sum to be unbiased. The exact answer integrates the plane's own
/// BSDF times the light's radiance times T' over the light, by quadrature.
#[test]
fn direct_light_through_a_thin_pane_matches_quadrature() {
    use glassbake_trace::microfacet::thin_slab_reflectance;
    use glassbake_trace::{Bsdf, SurfaceMaterial};
    let radiance = 3.0f32;
    let tint = Vec3::new(0.9, 0.6, 0.3);
    let mut scene = empty_scene("pane");
    let plane_material = Material { roughness: 0.6, ..Material::diffuse("plane", Vec3::splat(0.5)) };
    add_object(&mut scene, "plane", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), plane_material.clone());
    add_object(
        &mut scene,
        "pane",
        rect(Vec3::new(0.0, 0.8, 0.0), Vec3::X * 10.0, Vec3::NEG_Z * 10.0, Vec2::ONE),
        Material::glass("pane", tint, 0.0, 1.5, true),
    );
    let light = RectLight {
        name: "light".into(),
        corner: Vec3::new(-0.5, 1.5, -0.5),
        edge_u: Vec3::X,
        edge_v: Vec3::Z,
        radiance: Vec3::splat(radiance),
        two_sided: false,
    };
    scene.rect_lights.push(light.clone());
    // Below the pane, so camera rays reach the plane directly.
    let camera = Camera::look_at(Vec3::new(1.2, 0.6, 1.4), Vec3::new(0.0, 0.0, 0.0), 60.0);
    let (w, h) = (16u32, 16u32);
    // Direct light only: camera -> plane -> pane -> light is three segments (a pane
    // crossing counts, as in Mitsuba). With two the plane receives nothing through the pane.
    let two_segments = render(&scene, &camera, &TraceSettings { max_depth: 2, ..plain_settings(w, h, 64, 6) }, None).unwrap();
    assert!(two_segments.image.data().iter().all(|&v| v == 0.0), "max_depth 2 must not reach the light through the pane");
    let settings = TraceSettings { max_depth: 3, ..plain_settings(w, h, 4096, 6) };
    let out = render(&scene, &camera, &settings, None).unwrap();
    let surface = SurfaceMaterial::new(Vec3::splat(0.5), 0.6, 0.0, None);
    let bsdf = Bsdf::new(&surface, Vec3::Y, MaterialModel::Gltf);
    // The exact value of a box-filtered pixel: the average over a 4x4 grid of points in it,
    // each integrated over a 32x32 grid on the light.
    let n = 32;
    let exact = |px: f32, py: f32| -> Option<Vec3> {
        let ray = camera.ray(px, py, w, h);
        let t = -ray.origin.y / ray.direction.y;
        if t <= 0.0 {
            return None;
        }
        let (p, wo) = (ray.at(t), -ray.direction);
        let mut sum = Vec3::ZERO;
        for i in 0..n {
            for j in 0..n {
                let q = light.corner + light.edge_u * ((i as f32 + 0.5) / n as f32) + light.edge_v * ((j as f32 + 0.5) / n as f32);
                let d = q - p;
                let distance2 = d.length_squared();
                let wi = d / distance2.sqrt();
                let pane_transmittance = tint * (1.0 - thin_slab_reflectance(wi.y, 1.5));
                // cos at the plane (normal +y) times cos at the light (normal -y), dA = 1/n^2.
                let geometry = wi.y * wi.y / distance2 / (n * n) as f32;
                sum += bsdf.eval(wo, wi) * pane_transmittance * radiance * geometry;
            }
        }
        Some(sum)
    };
    let (mut relative_sum, mut count, mut worst) = (0.0f64, 0, 0.0f64);
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            let mut expected = Vec3::ZERO;
            let mut on_plane = true;
            for sy in 0..4 {
                for sx in 0..4 {
                    match exact(x as f32 + (sx as f32 + 0.5) / 4.0, y as f32 + (sy as f32 + 0.5) / 4.0) {
                        Some(v) => expected += v / 16.0,
                        None => on_plane = false,
                    }
                }
            }
            // Near the horizon a pixel spans metres of floor; leave those out.
            if !on_plane || expected.min_element() < 0.01 {
                continue;
            }
            for channel in 0..3 {
                let relative = out.image.get(channel, x, y) as f64 / expected[channel] as f64 - 1.0;
                relative_sum += relative;
                worst = worst.max(relative.abs());
                count += 1;
            }
        }
    }
    let bias = relative_sum / count as f64;
    eprintln!("thin pane: {count} pixel channels, mean relative error {bias:+.5}, worst {worst:.4}");
    assert!(count > 100, "{count}");
    // 4096 spp leave ~0.1% noise on the mean; a pass-through MIS that BSDF sampling cannot
    // follow at the depth limit showed up here as -0.5%.
    assert!(bias.abs() < 0.003, "mean relative error {bias}");
    assert!(worst < 0.05, "worst pixel off by {worst}");
}

/// A rectangle light facing down lights a ceiling above it only when it is two-sided, and
/// then exactly as its lower face lights a floor (direct light only: max depth 2).
#[test]
fn rectangle_lights_emit_from_their_back_only_when_two_sided() {
    let albedo = 0.5f32;
    let radiance = 2.0f32;
    let corners = [Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, 0.5), Vec3::new(-0.5, 1.0, 0.5)];
    // The mirror image of the floor test's camera, looking up at a ceiling at y = 2.
    let camera = Camera::look_at(Vec3::new(2.2, 0.3, 2.6), Vec3::new(0.0, 2.0, 0.0), 55.0);
    let (w, h) = (24u32, 24u32);
    for two_sided in [false, true] {
        let mut scene = empty_scene("ceiling");
        // rect() faces u x v = X x Z = -Y: down, towards the camera.
        let ceiling = add_object(
            &mut scene,
            "ceiling",
            rect(Vec3::Y * 2.0, Vec3::X * 20.0, Vec3::Z * 20.0, Vec2::ONE),
            Material::diffuse("ceiling", Vec3::splat(albedo)),
        );
        scene.rect_lights.push(RectLight {
            name: "light".into(),
            corner: corners[0],
            edge_u: Vec3::X,
            edge_v: Vec3::Z,
            radiance: Vec3::splat(radiance),
            two_sided,
        });
        assert!(scene.rect_lights[0].normal().y < 0.0, "the light's front faces down");
        let settings = TraceSettings { material_model: MaterialModel::Lambertian, max_depth: 2, ..plain_settings(w, h, 128, 5) };
        let out = render(&scene, &camera, &settings, None).unwrap();
        let prepared = PreparedScene::new(&scene);
        let (mut relative_sum, mut count, mut largest) = (0.0f64, 0, 0.0f32);
        // Pixels that see any of the light itself (its front faces the camera) are left out.
        for (expected, rendered) in lit_pixels(&out.image, &prepared, &camera, ceiling, Vec3::NEG_Y, &corners, radiance, albedo) {
            largest = largest.max(rendered);
            relative_sum += rendered as f64 / expected - 1.0;
            count += 1;
        }
        assert!(count > 100, "only {count} ceiling pixels");
        if two_sided {
            let bias = relative_sum / count as f64;
            assert!(bias.abs() < 0.01, "two-sided light: mean relative error {bias}");
        } else {
            assert_eq!(largest, 0.0, "the back of a one-sided light emits nothing");
        }
    }
}

/// A caustic with an exact answer: a small light faces up at a large thin pane, whose
/// reflection is all that lights the floor below (direct light only: max depth 3). Only the
/// `caustic` estimator's light tracer carries these paths (floor -> bending glass -> light),
/// so the test checks its camera importance, emission and cone densities and the pane's
/// reflection weight against quadrature: the floor's BSDF times the light's radiance times the
/// slab reflectance R'(theta), over the light mirrored in the pane.
#[test]
fn a_light_reflected_by_a_thin_pane_matches_quadrature() {
    use glassbake_trace::microfacet::thin_slab_reflectance;
    use glassbake_trace::{Bsdf, SurfaceMaterial};
    // A high index of refraction reflects more, for a less noisy test.
    const ETA: f32 = 3.0;
    let radiance = 40.0f32;
    let pane_height = 1.5f32;
    let mut scene = empty_scene("mirror pane");
    let floor_material = Material { roughness: 0.6, ..Material::diffuse("floor", Vec3::splat(0.5)) };
    add_object(&mut scene, "floor", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), floor_material);
    add_object(
        &mut scene,
        "pane",
        rect(Vec3::new(0.0, pane_height, 0.0), Vec3::X * 10.0, Vec3::NEG_Z * 10.0, Vec2::ONE),
        Material::glass("pane", Vec3::new(0.9, 0.6, 0.3), 0.0, ETA, true),
    );
    // edge_u x edge_v = Z x X = +Y: the light faces the pane, its black back the floor.
    let light = RectLight {
        name: "light".into(),
        corner: Vec3::new(-0.2, 1.0, -0.2),
        edge_u: Vec3::Z * 0.4,
        edge_v: Vec3::X * 0.4,
        radiance: Vec3::splat(radiance),
        two_sided: false,
    };
    scene.rect_lights.push(light.clone());
    // Looking down and away from the shadow that the light casts on the floor in the reflection.
    let camera = Camera::look_at(Vec3::new(2.8, 1.3, 2.2), Vec3::new(2.0, 0.0, 1.5), 60.0);
    let (w, h) = (16u32, 16u32);
    // Four independent renders: the spread of their totals gives the standard error (a
    // light path lands in one pixel or another, so pixels' errors are not independent).
    let totals: Vec<f64> = (0..4u64)
        .map(|seed| {
            let settings = TraceSettings { max_depth: 3, estimator: Estimator::parse("caustic").unwrap(), ..plain_settings(w, h, 4096, 8 + seed) };
            let out = render(&scene, &camera, &settings, None).unwrap();
            (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| out.image.get(1, x, y) as f64).sum()
        })
        .collect();
    let plain = render(&scene, &camera, &TraceSettings { max_depth: 3, ..plain_settings(w, h, 64, 20) }, None).unwrap();
    let bsdf = Bsdf::new(&SurfaceMaterial::new(Vec3::splat(0.5), 0.6, 0.0, None), Vec3::Y, MaterialModel::Gltf);
    let blocked_by_light = |p: Vec3, wi: Vec3| {
        let t = (light.corner.y - p.y) / wi.y;
        let q = p + wi * t;
        (-0.2..=0.2).contains(&q.x) && (-0.2..=0.2).contains(&q.z)
    };
    let n = 24;
    let light_area = light.edge_u.cross(light.edge_v).length();
    let exact = |px: f32, py: f32| -> Option<Vec3> {
        let ray = camera.ray(px, py, w, h);
        let t = -ray.origin.y / ray.direction.y;
        if t <= 0.0 {
            return None;
        }
        let (p, wo) = (ray.at(t), -ray.direction);
        let mut sum = Vec3::ZERO;
        for i in 0..n {
            for j in 0..n {
                let q = light.corner + light.edge_u * ((i as f32 + 0.5) / n as f32) + light.edge_v * ((j as f32 + 0.5) / n as f32);
                // The light's mirror image in the pane's plane.
                let mirrored = Vec3::new(q.x, 2.0 * pane_height - q.y, q.z);
                let d = mirrored - p;
                let distance2 = d.length_squared();
                let wi = d / distance2.sqrt();
                if blocked_by_light(p, wi) {
                    continue;
                }
                let geometry = wi.y * wi.y / distance2 * light_area / (n * n) as f32;
                sum += bsdf.eval(wo, wi) * thin_slab_reflectance(wi.y, ETA) * radiance * geometry;
            }
        }
        Some(sum)
    };
    let mut expected_total = 0.0f64;
    let mut plain_total = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let mut expected = 0.0f64;
            for sy in 0..4 {
                for sx in 0..4 {
                    let value = exact(x as f32 + (sx as f32 + 0.5) / 4.0, y as f32 + (sy as f32 + 0.5) / 4.0).expect("every pixel sees the floor");
                    expected += value.y as f64 / 16.0;
                }
            }
            expected_total += expected;
            plain_total += plain.image.get(1, x, y) as f64;
        }
    }
    let n = totals.len() as f64;
    let mean = totals.iter().sum::<f64>() / n;
    let standard_error = (totals.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt() / expected_total;
    let bias = mean / expected_total - 1.0;
    eprintln!(
        "reflected light: rendered total {mean:.5} vs exact {expected_total:.5}: {bias:+.5} (standard error {standard_error:.5}); plain at 64 spp: {:+.4}",
        plain_total / expected_total - 1.0
    );
    assert!(standard_error < 0.01, "too noisy to test: standard error {standard_error}");
    assert!(bias.abs() < 4.0 * standard_error.max(0.001), "relative error {bias}, standard error {standard_error}");
}

/// A thin smooth pane below a light that fills every mirror direction: each pixel is the
/// pane's reflectance times the light's radiance, averaged over the pixel (nothing comes
/// through the pane: the scene below is empty and black). The default estimator takes the
/// reflected light at every sample, so its pixels match that to rounding at 256 spp, while
/// the plain path tracer picks the reflection with the reflectance's probability and is
/// noisy; over all pixels both agree with it.
#[test]
fn a_light_seen_in_a_pane_is_exact_with_the_default_estimator() {
    use glassbake_trace::microfacet::thin_slab_reflectance;
    const ETA: f32 = 1.5;
    let radiance = 5.0f32;
    let mut scene = empty_scene("light in a pane");
    // Centred on the origin; rect() faces u x v = X x -Z = +Y: up, towards the camera and
    // the light.
    add_object(&mut scene, "pane", rect(Vec3::ZERO, Vec3::X * 20.0, Vec3::NEG_Z * 20.0, Vec2::ONE), Material::glass("pane", Vec3::ONE, 0.0, ETA, true));
    // edge_u x edge_v = X x Z = -Y: the light faces the pane.
    scene.rect_lights.push(RectLight {
        name: "sky".into(),
        corner: Vec3::new(-20.0, 3.0, -20.0),
        edge_u: Vec3::X * 40.0,
        edge_v: Vec3::Z * 40.0,
        radiance: Vec3::splat(radiance),
        two_sided: false,
    });
    // Every camera ray goes down (22 to 52 degrees below the horizon) and meets the pane
    // within 4 units; every mirror ray meets the light.
    let camera = Camera::look_at(Vec3::new(0.0, 1.5, 2.0), Vec3::ZERO, 30.0);
    let (w, h) = (16u32, 16u32);
    let exact = |x: u32, y: u32| -> f64 {
        let n = 16;
        let mut sum = 0.0f64;
        for sy in 0..n {
            for sx in 0..n {
                let ray = camera.ray(x as f32 + (sx as f32 + 0.5) / n as f32, y as f32 + (sy as f32 + 0.5) / n as f32, w, h);
                assert!(ray.direction.y < -0.3, "every pixel sees the pane");
                sum += (thin_slab_reflectance(-ray.direction.y, ETA) * radiance) as f64;
            }
        }
        sum / (n * n) as f64
    };
    let default = render(&scene, &camera, &TraceSettings::new(w, h, 256, 3), None).unwrap();
    let plain = render(&scene, &camera, &plain_settings(w, h, 1024, 4), None).unwrap();
    let (mut exact_total, mut plain_total, mut worst_default, mut worst_plain) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            let expected = exact(x, y);
            exact_total += expected;
            plain_total += plain.image.get(1, x, y) as f64;
            worst_default = worst_default.max((default.image.get(1, x, y) as f64 / expected - 1.0).abs());
            worst_plain = worst_plain.max((plain.image.get(1, x, y) as f64 / expected - 1.0).abs());
        }
    }
    eprintln!("light in a pane: worst pixel {worst_default:.2e} (default, 256 spp) vs {worst_plain:.2e} (plain, 1024 spp)");
    assert!(worst_default < 1e-3, "the default estimator's worst pixel is {worst_default} off");
    assert!(worst_plain > 0.1, "plain's worst pixel is only {worst_plain} off: the test no longer tells the two apart");
    // Plain picks the reflection in about 4-9% of 262,144 samples: its total's relative
    // standard error is under 1%.
    let plain_error = plain_total / exact_total - 1.0;
    assert!(plain_error.abs() < 0.03, "plain's total is {plain_error} off the exact one");
}

/// A floor seen through solid glass (a cuboid of half extents `half`, called `name`)
/// standing just above it, lit from above: every light path to the camera is
/// specular-diffuse-specular, which the light tracer cannot take (no connection reaches the
/// camera through the glass). The default estimator follows its shadow rays through the
/// glass instead: it must agree with the plain path tracer there, and at equal samples its
/// pixel variance must be below `max_noise_ratio` of plain's.
fn check_floor_under_glass(name: &str, half: Vec3, camera: &Camera, max_noise_ratio: f64) {
    let mut scene = empty_scene("floor under glass");
    add_object(&mut scene, "floor", rect(Vec3::ZERO, Vec3::X * 8.0, Vec3::NEG_Z * 8.0, Vec2::ONE), Material::diffuse("floor", Vec3::splat(0.5)));
    let mut block = glassbake_scene::shapes::cuboid(half);
    for p in &mut block.positions {
        *p += Vec3::Y * (half.y + 0.02);
    }
    add_object(&mut scene, "block", block, Material::glass("block", Vec3::ONE, 0.0, 1.5, false));
    // On the camera's side of the glass (+z), so that the glass's top does not mirror it
    // into the camera: only light through the glass reaches the floor it sees.
    scene.rect_lights.push(RectLight {
        name: "light".into(),
        corner: Vec3::new(-1.5, 3.0, 0.5),
        edge_u: Vec3::X * 3.0,
        edge_v: Vec3::Z * 3.0,
        radiance: Vec3::splat(5.0),
        two_sided: false,
    });
    const SIZE: u32 = 16;
    const RENDERS: u64 = 4;
    // Per estimator: the mean over the renders of the image mean, its variance, and the
    // mean over pixels of a pixel's variance across renders.
    let statistics = |estimator: Estimator, spp: u32, seed_base: u64| {
        let images: Vec<Vec<f64>> = (seed_base..seed_base + RENDERS)
            .map(|seed| {
                let settings = TraceSettings { estimator, ..plain_settings(SIZE, SIZE, spp, seed) };
                let image = render(&scene, camera, &settings, None).unwrap().image;
                (0..SIZE * SIZE).map(|i| image.get(1, i % SIZE, i / SIZE) as f64).collect()
            })
            .collect();
        let n = RENDERS as f64;
        let pixels = (SIZE * SIZE) as usize;
        let image_means: Vec<f64> = images.iter().map(|image| image.iter().sum::<f64>() / pixels as f64).collect();
        let mean = image_means.iter().sum::<f64>() / n;
        let mean_variance = image_means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1.0) / n;
        let pixel_variance = (0..pixels)
            .map(|i| {
                let m = images.iter().map(|image| image[i]).sum::<f64>() / n;
                images.iter().map(|image| (image[i] - m).powi(2)).sum::<f64>() / (n - 1.0)
            })
            .sum::<f64>()
            / pixels as f64;
        (mean, mean_variance, pixel_variance)
    };
    let (plain, plain_var, plain_noise) = statistics(Estimator::PLAIN, 1024, 10);
    let (default, default_var, default_noise) = statistics(Estimator::default(), 256, 20);
    let t = (default - plain).abs() / (plain_var + default_var).sqrt();
    // At equal samples: plain's at 1024 spp, scaled.
    let plain_noise = plain_noise * 4.0;
    eprintln!("floor under a {name}: plain {plain:.5} (pixel variance {plain_noise:.3e}), default {default:.5} ({default_noise:.3e}), t {t:.2}");
    assert!(plain > 0.05, "the floor under the {name} is dark ({plain}): the scene no longer tests light through glass");
    assert!(t < 5.0, "the default estimator's mean {default} differs from plain's {plain} by {t:.1} standard errors");
    assert!(
        default_noise < max_noise_ratio * plain_noise,
        "the default estimator's pixel variance {default_noise:.3e} is not below {max_noise_ratio} of plain's {plain_noise:.3e}"
    );
}

/// Through a slab the shadow ray is shifted, not turned.
#[test]
fn a_floor_under_a_glass_slab_is_lit_through_it_without_bias() {
    let camera = Camera::look_at(Vec3::new(0.0, 2.0, 0.5), Vec3::ZERO, 30.0);
    check_floor_under_glass("slab", Vec3::new(1.0, 0.1, 1.0), &camera, 0.1);
}

/// Under a tall glass column most of the light comes down by total internal reflection off
/// its walls, which the shadow ray follows too. Less gain than under a slab: after an odd
/// number of reflections the shadow ray leaves the top away from the light it was sent to
/// (measured: plain 7.0e-3, the default 4.1e-3; 5.7e-3 when the shadow ray stops at total
/// internal reflection, 5.9e-3 without following glass at all).
#[test]
fn a_floor_under_a_glass_column_is_lit_through_it_without_bias() {
    // Every pixel sees the floor through the column's top (a wider view would also show the
    // floor beside it, whose caustic is the light tracer's).
    let camera = Camera::look_at(Vec3::new(0.0, 2.0, 0.2), Vec3::ZERO, 5.0);
    check_floor_under_glass("column", Vec3::new(0.12, 0.5, 0.12), &camera, 0.7);
}
