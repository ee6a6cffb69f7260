//! The through pass against Snell's law and the Fresnel equations in closed form (f64, written
//! out here rather than taken from the crate's optics).

use std::sync::Arc;

use glam::{Affine3A, DVec3, Vec2, Vec3};
use glassbake_rays::through::{trace_through, ThroughScene};
use glassbake_scene::model::{Material, Object, Scene};
use glassbake_scene::shapes;

const IOR: f64 = 1.5;
/// The wall behind everything: the plane z = WALL_Z, facing +z.
const WALL_Z: f64 = -3.0;

fn add(scene: &mut Scene, name: &str, mesh: glassbake_scene::model::Mesh, material: Material, at: Vec3, transparent: bool) {
    scene.meshes.push(Arc::new(mesh));
    scene.materials.push(material);
    scene.objects.push(Object {
        name: name.into(),
        mesh: scene.meshes.len() - 1,
        material: scene.materials.len() - 1,
        transform: Affine3A::from_translation(at),
        transparent,
    });
}

/// A glass object (IOR 1.5) in front of a large grey wall.
fn scene_with(glass: glassbake_scene::model::Mesh, thin: bool) -> Scene {
    let mut scene = Scene::empty("through");
    let wall = shapes::rect(Vec3::new(0.0, 0.0, WALL_Z as f32), Vec3::X * 40.0, Vec3::Y * 40.0, Vec2::ONE);
    add(&mut scene, "wall", wall, Material::diffuse("wall", Vec3::splat(0.5)), Vec3::ZERO, false);
    add(&mut scene, "glass", glass, Material::glass("glass", Vec3::ONE, 0.0, IOR as f32, thin), Vec3::ZERO, true);
    scene
}

/// Unpolarised Fresnel reflectance from the cosines of incidence and transmission, going from
/// index n1 into n2 (Hecht, Optics, 4.42-4.43).
fn fresnel(n1: f64, n2: f64, cos_i: f64, cos_t: f64) -> f64 {
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i);
    0.5 * (rs * rs + rp * rp)
}

/// Vector form of Snell's law for unit `d` meeting unit normal `n` (against `d`) from index n1
/// into n2: (direction, cos_i, cos_t).
fn snell(d: DVec3, n: DVec3, n1: f64, n2: f64) -> (DVec3, f64, f64) {
    let cos_i = -d.dot(n);
    let ratio = n1 / n2;
    let cos_t = (1.0 - ratio * ratio * (1.0 - cos_i * cos_i)).sqrt();
    (ratio * d + (ratio * cos_i - cos_t) * n, cos_i, cos_t)
}

fn wall_hit(p: DVec3, d: DVec3) -> DVec3 {
    p + d * ((WALL_Z - p.z) / d.z)
}

fn close(a: Vec3, b: DVec3, tolerance: f64) -> bool {
    (a.as_dvec3() - b).length() <= tolerance
}

/// A ray from `origin` along unit `d` through a ball of `radius` at the origin: where it enters
/// and leaves, the direction it leaves in, and the cosines of incidence and transmission at
/// the entry and the exit.
struct BallPath {
    entry: DVec3,
    exit: DVec3,
    out: DVec3,
    cosines: [f64; 4],
}

fn through_ball(origin: DVec3, d: DVec3, radius: f64) -> BallPath {
    // |o + t d| = r, nearer root.
    let b = origin.dot(d);
    let entry = origin + d * (-b - (b * b - origin.length_squared() + radius * radius).sqrt());
    let (inside, cos_i, cos_t) = snell(d, entry / radius, 1.0, IOR);
    // The chord from `entry` along `inside` ends at t = -2 (entry . inside).
    let exit = entry + inside * (-2.0 * entry.dot(inside));
    let (out, cos_i2, cos_t2) = snell(inside, -exit / radius, IOR, 1.0);
    BallPath { entry, exit, out, cosines: [cos_i, cos_t, cos_i2, cos_t2] }
}

#[test]
fn a_slab_shifts_the_ray_sideways_as_snell_says() {
    let half_thickness = 0.5;
    let scene = scene_with(shapes::cuboid(Vec3::new(3.0, 3.0, half_thickness as f32)), false);
    let geometry = ThroughScene::build(&scene);
    for (origin, target) in [(DVec3::new(2.0, -0.2, 3.0), DVec3::new(-0.4, 0.1, 0.0)), (DVec3::new(-1.0, 1.5, 3.0), DVec3::new(0.2, 0.0, 0.0))] {
        let d = (target - origin).normalize();
        let entry = origin + d * ((half_thickness - origin.z) / d.z);
        let (inside, cos_i, cos_t) = snell(d, DVec3::Z, 1.0, IOR);
        let exit = entry + inside * ((-2.0 * half_thickness) / inside.z);
        let (out, cos_i2, cos_t2) = snell(inside, DVec3::Z, IOR, 1.0);
        assert!((out - d).length() < 1e-12, "a slab's faces are parallel: the ray leaves as it came");
        let expected = wall_hit(exit, out);
        let transmittance = (1.0 - fresnel(1.0, IOR, cos_i, cos_t)) * (1.0 - fresnel(IOR, 1.0, cos_i2, cos_t2));

        let hit = trace_through(&scene, &geometry, 0, origin.as_vec3(), d.as_vec3()).expect("the ray reaches the wall");
        assert!(close(hit.position, expected, 1e-4), "{} vs {expected}", hit.position);
        assert!((hit.transmittance as f64 - transmittance).abs() < 1e-5, "{} vs {transmittance}", hit.transmittance);
        assert!((hit.length as f64 - (exit - entry).length()).abs() < 1e-5);
        assert_eq!(hit.interfaces, 2);
        assert!(close(hit.normal, DVec3::Z, 1e-6) && close(hit.albedo, DVec3::splat(0.5), 1e-6));
        // Without the glass the ray would land elsewhere: the test sees the refraction.
        assert!((wall_hit(origin, d) - expected).length() > 0.05);
    }
}

#[test]
fn a_sphere_focuses_the_ray_as_snell_says() {
    let radius = 1.0;
    // Finely tessellated, so its flat triangles are within 1e-4 of the sphere.
    let scene = scene_with(shapes::uv_sphere(radius as f32, 512, 256), false);
    let geometry = ThroughScene::build(&scene);
    let origin = DVec3::new(0.0, 0.0, 5.0);
    for target in [DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 0.45, 0.0), DVec3::new(0.05, -0.6, 0.0)] {
        let d = (target - origin).normalize();
        let BallPath { entry, exit, out, cosines: [cos_i, cos_t, cos_i2, cos_t2] } = through_ball(origin, d, radius);
        let expected = wall_hit(exit, out);
        let transmittance = (1.0 - fresnel(1.0, IOR, cos_i, cos_t)) * (1.0 - fresnel(IOR, 1.0, cos_i2, cos_t2));

        let hit = trace_through(&scene, &geometry, 0, origin.as_vec3(), d.as_vec3()).expect("the ray reaches the wall");
        // The wall is 3 radii behind the sphere: a normal off by 1e-4 moves the hit ~1e-3.
        assert!(close(hit.position, expected, 5e-3), "{} vs {expected}", hit.position);
        assert!((hit.transmittance as f64 - transmittance).abs() < 1e-3, "{} vs {transmittance}", hit.transmittance);
        assert!((hit.length as f64 - (exit - entry).length()).abs() < 1e-3);
        assert_eq!(hit.interfaces, 2);
        assert!((wall_hit(origin, d) - expected).length() > 0.1, "the sphere bends the ray");
    }
}

#[test]
fn a_thin_pane_lets_the_ray_through_unbent() {
    let pane = shapes::rect(Vec3::ZERO, Vec3::X * 4.0, Vec3::Y * 4.0, Vec2::ONE);
    let scene = scene_with(pane, true);
    let geometry = ThroughScene::build(&scene);
    let origin = DVec3::new(0.2, 0.1, 2.0);
    let d = (DVec3::new(-0.5, 0.3, 0.0) - origin).normalize();
    let hit = trace_through(&scene, &geometry, 0, origin.as_vec3(), d.as_vec3()).unwrap();
    assert!(close(hit.position, wall_hit(origin, d), 1e-4));
    let cos_i = -d.z;
    let cos_t = (1.0 - (1.0 - cos_i * cos_i) / (IOR * IOR)).sqrt();
    let r = fresnel(1.0, IOR, cos_i, cos_t);
    // Both faces with every inter-reflection: T = (1 - R)^2 / (1 - R^2) = (1 - R) / (1 + R).
    assert!((hit.transmittance as f64 - (1.0 - r) / (1.0 + r)).abs() < 1e-5);
    assert_eq!(hit.length, 0.0);
}

#[test]
fn other_transparent_objects_are_ignored() {
    let mut scene = scene_with(shapes::uv_sphere(1.0, 64, 32), false);
    let geometry = ThroughScene::build(&scene);
    let origin = Vec3::new(0.0, 0.0, 5.0);
    let d = (Vec3::new(0.3, 0.1, 0.0) - origin).normalize();
    let alone = trace_through(&scene, &geometry, 0, origin, d).unwrap();
    // A second glass block in front of the sphere, on the ray.
    add(&mut scene, "block", shapes::cuboid(Vec3::splat(0.5)), Material::glass("block", Vec3::ONE, 0.0, 1.5, false), Vec3::new(0.1, 0.0, 2.5), true);
    let geometry = ThroughScene::build(&scene);
    assert_eq!(trace_through(&scene, &geometry, 0, origin, d).unwrap(), alone);
    // Buffer 1, the block, sees the wall through the block alone.
    let through_block = trace_through(&scene, &geometry, 1, origin, d).unwrap();
    assert_ne!(through_block.position, alone.position);
    assert_eq!(through_block.interfaces, 2);
}

/// A ray that leaves the scene ends on the background, which it sees from where it left the
/// glass: near the sphere's axis (off the vertices of its mesh), almost straight through both
/// faces (Fresnel at normal incidence, R = ((n - 1) / (n + 1))^2, at each; the mesh's facets lie
/// within 0.5% of the sphere).
#[test]
fn a_ray_that_leaves_the_scene_ends_on_the_background() {
    let mut scene = scene_with(shapes::uv_sphere(1.0, 64, 32), false);
    scene.background = Vec3::new(0.2, 0.3, 0.4);
    let geometry = ThroughScene::build(&scene);
    let hit = trace_through(&scene, &geometry, 0, Vec3::new(0.011, 0.007, -2.0), Vec3::Z).expect("the background ends the ray");
    assert!(hit.background && hit.is_light);
    assert_eq!(hit.emitted, scene.background);
    assert_eq!(hit.albedo, Vec3::ZERO);
    assert!(close(hit.position, DVec3::Z, 1e-2), "where it left the sphere: {}", hit.position);
    assert!(hit.normal.dot(Vec3::Z) < -0.999 && (hit.normal.length() - 1.0).abs() < 1e-5, "faces back along the ray: {}", hit.normal);
    let r = ((IOR - 1.0) / (IOR + 1.0)).powi(2);
    assert!((hit.transmittance as f64 - (1.0 - r) * (1.0 - r)).abs() < 1e-4, "{}", hit.transmittance);
    assert!((hit.length - 2.0).abs() < 1e-2, "{}", hit.length);
    assert_eq!(hit.interfaces, 2);
    // One that never meets the glass sees the background from where it starts.
    let origin = Vec3::new(0.0, 0.0, 5.0);
    let missed = trace_through(&scene, &geometry, 0, origin, Vec3::Z).unwrap();
    assert!(missed.background && missed.position == origin && missed.transmittance == 1.0 && missed.interfaces == 0);
}

/// A frame's through buffer: nothing where the object covers nothing; where it does, the
/// hit's screen offset is where the camera projects it, and the G-buffer's L_d is read there
/// exactly where a ray from the camera reaches the hit (a comb of thin posts behind a thick
/// slab hides some of the wall the slab shows, and the slab's sideways shift lets rays pass
/// the posts that the camera's straight view meets).
/// A glass slab in front of a row of 20 white posts (half extents `post`, centres `posts`)
/// between it and the wall, which hide parts of the wall from the camera.
fn slab_before_posts() -> (Scene, Vec3, Vec<Vec3>) {
    let mut scene = scene_with(shapes::cuboid(Vec3::new(3.0, 2.0, 0.8)), false);
    let post = Vec3::new(0.05, 2.0, 0.05);
    let posts: Vec<Vec3> = (0..20).map(|i| Vec3::new(-4.0 + 0.3 * i as f32, 0.0, -1.5)).collect();
    for (i, &at) in posts.iter().enumerate() {
        add(&mut scene, &format!("post{i}"), shapes::cuboid(post), Material::diffuse("post", Vec3::ONE), at, false);
    }
    (scene, post, posts)
}

#[test]
fn a_frame_reads_the_gbuffer_light_only_where_the_camera_sees_the_hit() {
    use glassbake_core::camera::Camera;
    use glassbake_core::image::PlanarImage;
    use glassbake_core::layout::{self, opaque, through, transparent};
    use glassbake_rays::through::through_buffer;

    let (scene, post, posts) = slab_before_posts();
    let geometry = ThroughScene::build(&scene);
    let camera = Camera::look_at(Vec3::new(3.0, 0.3, 4.0), Vec3::new(0.0, 0.0, -1.0), 60.0);
    let (w, h) = (40u32, 30u32);
    // The object covers the left half; the G-buffer's L_d is the pixel's index, so the test
    // sees which pixel was read.
    let mut coverage = PlanarImage::new(w, h, layout::transparent_channel_names(0));
    let mut gbuffer = PlanarImage::new(w, h, layout::opaque_channel_names());
    for y in 0..h {
        for x in 0..w {
            coverage.set(transparent::COVERAGE, x, y, f32::from(u8::from(x < w / 2)));
            for c in 0..3 {
                gbuffer.set(opaque::LD + c, x, y, (y * w + x) as f32 + 0.25 * c as f32);
            }
        }
    }
    let cast = through_buffer(&scene, &geometry, 0, &camera, &gbuffer, coverage.plane(transparent::COVERAGE));
    assert_eq!(cast.channels(), layout::through_channel_names(0).as_slice());
    // Independently: whether the straight segment from the camera to `p` crosses a post.
    let hidden_from_camera = |p: Vec3| {
        let d = p - camera.position;
        posts.iter().any(|&centre| {
            let (lo, hi) = (centre - post, centre + post);
            let (mut t0, mut t1) = (0.0f32, 1.0f32 - 1e-3);
            for a in 0..3 {
                let (ta, tb) = ((lo[a] - camera.position[a]) / d[a], (hi[a] - camera.position[a]) / d[a]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            t0 <= t1
        })
    };
    // Where a hit projects in the frame, if it does.
    let pixel_of =
        |p: Vec3| camera.project(p, w, h).filter(|&(px, py)| px >= 0.0 && py >= 0.0 && px < w as f32 && py < h as f32).map(|(px, py)| (px as u32, py as u32));
    let (mut seen, mut hidden) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let get = |c: usize| cast.get(c, x, y);
            if x >= w / 2 {
                assert!((0..layout::THROUGH_CHANNELS).all(|c| get(c) == 0.0), "({x}, {y})");
                continue;
            }
            let ray = camera.pixel_center_ray(x, y, w, h);
            let Some(hit) = trace_through(&scene, &geometry, 0, ray.origin, ray.direction) else { continue };
            assert_eq!(Vec3::new(get(through::POSITION), get(through::POSITION + 1), get(through::POSITION + 2)), hit.position);
            // L_d is the footprint's: each of its rays reads the G-buffer where its own hit
            // projects if the camera sees that hit there, else adds 0, weighted by what it
            // lets through.
            let (mut light, mut transmittance) = (0.0f64, 0.0f64);
            for [dx, dy] in glassbake_rays::through::FOOTPRINT {
                let ray = camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy, w, h);
                let Some(end) = trace_through(&scene, &geometry, 0, ray.origin, ray.direction) else { continue };
                let t = f64::from(end.transmittance);
                transmittance += t;
                match pixel_of(end.position) {
                    Some((sx, sy)) if !hidden_from_camera(end.position) => {
                        seen += 1;
                        light += t * f64::from(sy * w + sx);
                    }
                    Some(_) => hidden += 1,
                    None => {}
                }
            }
            let expected = if transmittance > 0.0 { light / transmittance } else { 0.0 };
            assert!((f64::from(get(through::LD)) - expected).abs() <= 1e-5 * expected.max(1.0), "({x}, {y}): L_d {} vs {expected}", get(through::LD));
            // Where the hit is seen is the centre's.
            let Some((sx, sy)) = pixel_of(hit.position) else {
                assert_eq!(get(through::ON_SCREEN), 0.0);
                continue;
            };
            assert_eq!((get(through::SCREEN_OFFSET), get(through::SCREEN_OFFSET + 1)), (sx as f32 - x as f32, sy as f32 - y as f32));
            let blocked = hidden_from_camera(hit.position);
            assert_eq!(get(through::ON_SCREEN), if blocked { 0.0 } else { 1.0 }, "({x}, {y}) -> ({sx}, {sy})");
        }
    }
    assert!(seen > 80 && hidden > 80, "footprint rays seen {seen}, hidden {hidden}");
}

/// Through a frosted pane the albedo is the mean over its lobe: beside the edge between a black
/// and a white wall it is grey, where the smooth pane's is black or white; far from the edge
/// both are the wall's (the frosted one within GGX's long tail).
#[test]
fn a_rough_pane_blurs_the_albedo_behind_it() {
    use glassbake_core::camera::Camera;
    use glassbake_core::image::PlanarImage;
    use glassbake_core::layout::{self, through, transparent};
    use glassbake_rays::through::through_buffer;

    let frame = |roughness: f32| {
        let mut scene = Scene::empty("frosted");
        let wall = |x: f32| shapes::rect(Vec3::new(x, 0.0, WALL_Z as f32), Vec3::X * 20.0, Vec3::Y * 40.0, Vec2::ONE);
        add(&mut scene, "black", wall(-10.0), Material::diffuse("black", Vec3::ZERO), Vec3::ZERO, false);
        add(&mut scene, "white", wall(10.0), Material::diffuse("white", Vec3::ONE), Vec3::ZERO, false);
        let pane = shapes::rect(Vec3::ZERO, Vec3::X * 8.0, Vec3::Y * 8.0, Vec2::ONE);
        add(&mut scene, "pane", pane, Material::glass("pane", Vec3::ONE, roughness, IOR as f32, true), Vec3::ZERO, true);
        let geometry = ThroughScene::build(&scene);
        let camera = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::new(0.0, 0.0, 0.0), 40.0);
        let mut coverage = PlanarImage::new(32, 8, layout::transparent_channel_names(0));
        coverage.plane_mut(transparent::COVERAGE).fill(1.0);
        let gbuffer = PlanarImage::new(32, 8, layout::opaque_channel_names());
        through_buffer(&scene, &geometry, 0, &camera, &gbuffer, coverage.plane(transparent::COVERAGE))
    };
    let (smooth, frosted) = (frame(0.0), frame(0.3));
    let grey = |image: &PlanarImage, x: u32| image.get(through::ALBEDO, x, 4);
    for x in [0, 31] {
        assert_eq!(grey(&smooth, x), if x == 0 { 0.0 } else { 1.0 });
        assert!((grey(&frosted, x) - grey(&smooth, x)).abs() < 0.05, "far from the edge, column {x}: {}", grey(&frosted, x));
    }
    // The edge is between columns 15 and 16.
    for x in [15, 16] {
        assert!(grey(&smooth, x) == 0.0 || grey(&smooth, x) == 1.0);
        assert!(grey(&frosted, x) > 0.05 && grey(&frosted, x) < 0.95, "column {x}: {}", grey(&frosted, x));
    }
    assert!(frosted.get(through::TRANSMITTANCE, 16, 4) > 0.0 && frosted.get(through::TRANSMITTANCE, 16, 4) <= 1.0);
}

/// The through buffer of object 0 for a `w` x `h` frame it covers whole, the G-buffer's L_d 0.
fn covered_frame(scene: &Scene, camera: &glassbake_core::camera::Camera, w: u32, h: u32) -> glassbake_core::image::PlanarImage {
    use glassbake_core::image::PlanarImage;
    use glassbake_core::layout::{self, transparent};
    let geometry = ThroughScene::build(scene);
    let mut coverage = PlanarImage::new(w, h, layout::transparent_channel_names(0));
    coverage.plane_mut(transparent::COVERAGE).fill(1.0);
    let gbuffer = PlanarImage::new(w, h, layout::opaque_channel_names());
    glassbake_rays::through::through_buffer(scene, &geometry, 0, camera, &gbuffer, coverage.plane(transparent::COVERAGE))
}

/// The directions of pixel (x, y)'s footprint rays in a `w` x `h` frame of `camera`.
fn footprint_directions(camera: &glassbake_core::camera::Camera, x: u32, y: u32, w: u32, h: u32) -> Vec<DVec3> {
    glassbake_rays::through::FOOTPRINT.iter().map(|[dx, dy]| camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy, w, h).direction.as_dvec3()).collect()
}

/// The spread channel's definition, in f64: log2(1 + s), s the RMS distance of `hits` from
/// their mean over the footprint's RMS radius at `path_length` with nothing between.
fn expected_spread(hits: &[DVec3], path_length: f64, camera: &glassbake_core::camera::Camera, w: u32, h: u32) -> f64 {
    let mean = hits.iter().sum::<DVec3>() / hits.len() as f64;
    let rms = (hits.iter().map(|p| (*p - mean).length_squared()).sum::<f64>() / hits.len() as f64).sqrt();
    let pixel_size = 2.0 * f64::from(camera.tan_half_fov(w, h).1) / f64::from(h);
    let footprint_rms = glassbake_rays::through::FOOTPRINT.iter().map(|[x, y]| f64::from(x * x + y * y)).sum::<f64>() / 4.0;
    (1.0 + rms / (footprint_rms.sqrt() * path_length * pixel_size)).log2()
}

/// Through a flat pane the footprint lands on the wall as it would with nothing between: a
/// spread of log2(1 + 1) where the wall faces the camera, and exactly what the footprint's
/// rays' hits on the wall give at every pixel.
#[test]
fn a_flat_pane_leaves_the_footprint_as_the_open_view_spreads_it() {
    use glassbake_core::camera::Camera;
    use glassbake_core::layout::through;
    let pane = shapes::rect(Vec3::ZERO, Vec3::X * 8.0, Vec3::Y * 8.0, Vec2::ONE);
    let scene = scene_with(pane, true);
    let (w, h) = (5u32, 5u32);
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 30.0);
    let cast = covered_frame(&scene, &camera, w, h);
    let origin = camera.position.as_dvec3();
    for (x, y) in [(2, 2), (0, 0), (4, 1)] {
        let hits: Vec<DVec3> = footprint_directions(&camera, x, y, w, h).into_iter().map(|d| wall_hit(origin, d)).collect();
        let centre = wall_hit(origin, camera.pixel_center_ray(x, y, w, h).direction.as_dvec3());
        let expected = expected_spread(&hits, (centre - origin).length(), &camera, w, h);
        let spread = f64::from(cast.get(through::SPREAD, x, y));
        assert!((spread - expected).abs() < 1e-4, "({x}, {y}): {spread} vs {expected}");
        if (x, y) == (2, 2) {
            assert!((spread - 1.0).abs() < 1e-3, "the wall faces the camera: {spread}");
        }
    }
}

/// A glass ball in front of the wall gathers the footprint's rays, which cross behind it and
/// land on the wall closer together than they left (paraxially a quarter as far apart here):
/// the spread is what Snell's law in closed form gives for the footprint's four rays.
#[test]
fn a_ball_lens_shrinks_the_footprint_as_snell_says() {
    use glassbake_core::camera::Camera;
    use glassbake_core::layout::through;
    let radius = 1.0;
    let scene = scene_with(shapes::uv_sphere(radius as f32, 512, 256), false);
    let (w, h) = (3u32, 3u32);
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 20.0);
    let cast = covered_frame(&scene, &camera, w, h);
    let origin = camera.position.as_dvec3();
    // Entry, exit and wall hit of a ray from the camera through the ball.
    let path = |d: DVec3| {
        let BallPath { entry, exit, out, .. } = through_ball(origin, d, radius);
        let hit = wall_hit(exit, out);
        (hit, (entry - origin).length() + (exit - entry).length() + (hit - exit).length())
    };
    let hits: Vec<DVec3> = footprint_directions(&camera, 1, 1, w, h).into_iter().map(|d| path(d).0).collect();
    let (_, path_length) = path(camera.pixel_center_ray(1, 1, w, h).direction.as_dvec3());
    let expected = expected_spread(&hits, path_length, &camera, w, h);
    let spread = f64::from(cast.get(through::SPREAD, 1, 1));
    assert!((spread - expected).abs() < 0.01 * expected, "{spread} vs {expected}");
    // Paraxially: the ball's focal length n r / (2 (n - 1)) from its centre, the camera 5 in
    // front of it and the wall 3 behind: the wall sees |5 + 3 - 5 x 3 / 1.5| / 8 = 0.25 of the
    // spread. The footprint's rays pass 0.18 radii from the axis, where spherical aberration
    // focuses them a little shorter, so a little more.
    let stretch = expected.exp2() - 1.0;
    assert!((0.25..0.3).contains(&stretch), "{stretch}");
}

/// The footprint averages what the pixel's area sees: with the edge between a black and a white
/// wall through the middle of a column, that column's albedo is grey (two of the footprint's
/// four rays on each side) where its centre's ray alone sees white.
#[test]
fn the_footprint_averages_an_edge_inside_the_pixel() {
    use glassbake_core::camera::Camera;
    use glassbake_core::layout::through;
    let mut scene = Scene::empty("edge");
    let wall = |x: f32| shapes::rect(Vec3::new(x, 0.0, WALL_Z as f32), Vec3::X * 20.0, Vec3::Y * 40.0, Vec2::ONE);
    add(&mut scene, "black", wall(-10.0), Material::diffuse("black", Vec3::ZERO), Vec3::ZERO, false);
    add(&mut scene, "white", wall(10.0), Material::diffuse("white", Vec3::ONE), Vec3::ZERO, false);
    let pane = shapes::rect(Vec3::ZERO, Vec3::X * 8.0, Vec3::Y * 8.0, Vec2::ONE);
    add(&mut scene, "pane", pane, Material::glass("pane", Vec3::ONE, 0.0, IOR as f32, true), Vec3::ZERO, true);
    let (w, h) = (32u32, 8u32);
    // The camera 0.45 pixel (at the wall) to the left of the edge, so that the edge runs down
    // column 16, 0.05 pixel left of its centre.
    let shift = 0.45 * 2.0 * (20f32.to_radians()).tan() * (4.0 - WALL_Z as f32) / w as f32;
    let camera = Camera::look_at(Vec3::new(-shift, 0.0, 4.0), Vec3::new(-shift, 0.0, 0.0), 40.0);
    let cast = covered_frame(&scene, &camera, w, h);
    let geometry = ThroughScene::build(&scene);
    let ray = camera.pixel_center_ray(16, 4, w, h);
    let centre = trace_through(&scene, &geometry, 0, ray.origin, ray.direction).unwrap();
    assert_eq!(centre.albedo, Vec3::ONE, "the centre's ray sees the white wall");
    let albedo = |x: u32| cast.get(through::ALBEDO, x, 4);
    assert!((albedo(16) - 0.5).abs() < 1e-6, "column 16: {}", albedo(16));
    assert_eq!((albedo(15), albedo(17)), (0.0, 1.0));
}

/// A footprint whose four points land 1:1 on a texture `s` texels a pixel apart reads level
/// log2(s / 2): each point stands for a quarter of the pixel, half its side. A single hit on
/// the material, or a footprint finer than a texel a point, reads the full-size texture.
#[test]
fn the_footprint_reads_the_mip_level_of_its_share_of_the_pixel() {
    use glam::Vec2;
    use glassbake_rays::through::{footprint_lod, FOOTPRINT};
    let size = Vec2::new(512.0, 256.0);
    for s in [4.0f32, 16.0, 64.0] {
        let uvs: Vec<Vec2> = FOOTPRINT.iter().map(|&[x, y]| Vec2::new(0.5, 0.5) + Vec2::new(x, y) * s / size).collect();
        let lod = footprint_lod(&uvs, size, FOOTPRINT.len());
        assert!((lod - (s / 2.0).log2()).abs() < 1e-4, "{s} texels a pixel: level {lod}");
    }
    assert_eq!(footprint_lod(&[Vec2::new(0.1, 0.2)], size, 4), 0.0);
    let fine: Vec<Vec2> = FOOTPRINT.iter().map(|&[x, y]| Vec2::new(0.5, 0.5) + Vec2::new(x, y) / size).collect();
    assert_eq!(footprint_lod(&fine, size, 4), 0.0);
}

/// A footprint whose rays land on uvs moved by an affine map of their offsets gives that map's
/// gradients back, however it stretches and turns the pixel.
#[test]
fn the_footprint_gradients_are_the_map_from_its_offsets_to_its_uvs() {
    use glam::{Mat2, Vec2};
    use glassbake_rays::through::{footprint_gradients, FOOTPRINT};
    let size = Vec2::new(512.0, 256.0);
    let map = Mat2::from_cols(Vec2::new(7.0, -3.0), Vec2::new(2.5, 19.0));
    let uvs = FOOTPRINT.map(|[x, y]| Vec2::new(0.3, 0.6) + map * Vec2::new(x, y) / size);
    let gradients = footprint_gradients(&uvs, size);
    assert!(gradients.abs_diff_eq(map, 1e-3), "{gradients} for {map}");
}

/// Each footprint ray's quarter of the pixel, read as four lookups with half their cell's
/// gradients, is the box mean of the texels it covers where those line up with the texture's
/// grid: 8 texels a pixel, so 4x4 texels a quarter, on a texture of random texels. One lookup
/// at the quarter's level (what rough glass's lobe and mixed footprints read) is not.
#[test]
fn a_footprint_quarter_reads_the_mean_of_its_texels() {
    use glam::{Mat2, Vec2, Vec4};
    use glassbake_rays::through::{footprint_cell_sample, footprint_lod, FOOTPRINT};
    use glassbake_scene::model::Texture;
    use glassbake_scene::MipChain;
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let side = 64u32;
    let texels: Vec<Vec4> = (0..side * side).map(|_| Vec4::new(rng.random(), rng.random(), rng.random(), 1.0)).collect();
    let texture = Texture { name: "noise".into(), width: side, height: side, texels: texels.clone(), is_color: true };
    let chain = MipChain::new(&texture);
    let size = Vec2::splat(side as f32);
    let gradients = Mat2::from_diagonal(Vec2::splat(8.0));
    // The pixel's centre on the corner of texels (31, 31) and (32, 32).
    let centre = Vec2::splat(0.5);
    let uvs = FOOTPRINT.map(|[x, y]| centre + gradients * Vec2::new(x, y) / size);
    let lod = footprint_lod(&uvs, size, FOOTPRINT.len());
    let (mut cell_error, mut level_error) = (0.0f32, 0.0f32);
    for (point, &[x, y]) in FOOTPRINT.iter().enumerate() {
        // The quarter's texels: columns and rows 28..32 or 32..36.
        let (x0, y0) = (if x < 0.0 { 28 } else { 32 }, if y < 0.0 { 28 } else { 32 });
        let mean = (y0..y0 + 4).flat_map(|ty| (x0..x0 + 4).map(move |tx| (tx, ty))).map(|(tx, ty)| texels[(ty * side + tx) as usize]).sum::<Vec4>() / 16.0;
        let cells = footprint_cell_sample(&chain, uvs[point], point, gradients);
        cell_error = cell_error.max((cells - mean).abs().max_element());
        level_error = level_error.max((chain.sample(uvs[point], lod) - mean).abs().max_element());
    }
    assert!(cell_error < 1e-5, "the quarters' lookups are {cell_error} from their texels' mean");
    assert!(level_error > 0.05, "one lookup a quarter is as good: {level_error}");
}

/// Where the camera does not see what a footprint ray reaches, that ray's L_d is the lights'
/// direct diffuse light there: the light's radiance times the albedo times its form factor
/// (here by quadrature over the light), if the segment to its point for the ray
/// (`direct::light_point`) misses the posts that shadow the wall; where the camera sees it,
/// the G-buffer's.
#[test]
fn a_hit_the_camera_does_not_see_is_lit_by_the_lights_it_sees() {
    use glassbake_core::camera::Camera;
    use glassbake_core::image::PlanarImage;
    use glassbake_core::layout::{self, opaque, through, transparent};
    use glassbake_rays::direct::light_point;
    use glassbake_rays::through::{through_buffer, FOOTPRINT};
    use glassbake_scene::model::RectLight;

    let (mut scene, post, posts) = slab_before_posts();
    // Above the posts, facing down: they cast soft shadows on the wall.
    let light = RectLight {
        name: "strip".into(),
        corner: Vec3::new(-3.0, 2.5, -0.5),
        edge_u: Vec3::new(2.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, 0.6),
        radiance: Vec3::new(4.0, 3.0, 2.0),
        two_sided: false,
    };
    assert!(light.normal().y < -0.99);
    scene.rect_lights.push(light.clone());
    let geometry = ThroughScene::build(&scene);
    let camera = Camera::look_at(Vec3::new(3.0, 0.3, 4.0), Vec3::new(0.0, 0.0, -1.0), 60.0);
    let (w, h) = (64u32, 48u32);
    let mut coverage = PlanarImage::new(w, h, layout::transparent_channel_names(0));
    let mut gbuffer = PlanarImage::new(w, h, layout::opaque_channel_names());
    for y in 0..h {
        for x in 0..w {
            coverage.set(transparent::COVERAGE, x, y, f32::from(u8::from(x < w / 2)));
            for c in 0..3 {
                gbuffer.set(opaque::LD + c, x, y, 100.0 + (y * w + x) as f32);
            }
        }
    }
    let cast = through_buffer(&scene, &geometry, 0, &camera, &gbuffer, coverage.plane(transparent::COVERAGE));
    // Whether the segment from `a` to `b`, short of both ends, crosses a post.
    let blocked = |a: DVec3, b: DVec3| {
        let d = b - a;
        posts.iter().any(|&centre| {
            let (lo, hi) = ((centre - post).as_dvec3(), (centre + post).as_dvec3());
            let (mut t0, mut t1): (f64, f64) = (1e-3, 1.0 - 1e-3);
            for k in 0..3 {
                let (ta, tb) = ((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            t0 <= t1
        })
    };
    let on_wall = |p: Vec3| (f64::from(p.z) - WALL_Z).abs() < 1e-3;
    // The light's form factor at a point of the wall (facing +z), by the midpoint rule.
    let form_factor = |p: DVec3| {
        let n = 64;
        let (corner, u, v) = (light.corner.as_dvec3(), light.edge_u.as_dvec3(), light.edge_v.as_dvec3());
        let light_normal = u.cross(v).normalize();
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let q = corner + u * ((i as f64 + 0.5) / n as f64) + v * ((j as f64 + 0.5) / n as f64) - p;
                let r2 = q.length_squared();
                let wi = q / r2.sqrt();
                sum += wi.z.max(0.0) * (-wi.dot(light_normal)).max(0.0) / (std::f64::consts::PI * r2);
            }
        }
        sum * u.cross(v).length() / (n * n) as f64
    };
    let (mut checked, mut lit, mut shadowed) = (0, 0, 0);
    'pixels: for y in 0..h {
        for x in 0..w / 2 {
            let (mut light_sum, mut transmittance) = (DVec3::ZERO, 0.0f64);
            let mut unseen = 0;
            for (j, [dx, dy]) in FOOTPRINT.into_iter().enumerate() {
                let ray = camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy, w, h);
                let Some(end) = trace_through(&scene, &geometry, 0, ray.origin, ray.direction) else { continue 'pixels };
                let t = f64::from(end.transmittance);
                transmittance += t;
                let p = end.position.as_dvec3();
                let in_frame = camera.project(end.position, w, h).filter(|&(px, py)| px >= 0.0 && py >= 0.0 && px < w as f32 && py < h as f32);
                let l = match in_frame {
                    _ if end.is_light => end.emitted.as_dvec3(),
                    Some((px, py)) if !blocked(camera.position.as_dvec3(), p) => DVec3::splat(100.0 + f64::from(py as u32 * w + px as u32)),
                    // Only the wall's hits are worked out here.
                    _ if !on_wall(end.position) => continue 'pixels,
                    _ => {
                        unseen += 1;
                        let [u, v] = light_point(j);
                        let target = (light.corner + light.edge_u * u + light.edge_v * v).as_dvec3();
                        if blocked(p, target) {
                            shadowed += 1;
                            DVec3::ZERO
                        } else {
                            lit += 1;
                            0.5 * light.radiance.as_dvec3() * form_factor(p)
                        }
                    }
                };
                light_sum += t * l;
            }
            if unseen == 0 {
                continue;
            }
            checked += 1;
            let expected = light_sum / transmittance;
            for c in 0..3 {
                let got = f64::from(cast.get(through::LD + c, x, y));
                assert!((got - expected[c]).abs() <= 1e-3 * expected[c].max(1e-2), "({x}, {y}) channel {c}: L_d {got} vs {expected}");
            }
        }
    }
    assert!(checked > 40 && lit > 40 && shadowed > 10, "pixels checked {checked}; unseen rays lit {lit}, shadowed {shadowed}");
}
