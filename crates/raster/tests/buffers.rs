//! Every channel of the opaque, naive and transparency buffers on a scene of known geometry,
//! checked against a CPU ray cast through each pixel centre (runs on lavapipe in CI).

mod common;

use common::*;
use glam::Vec3;
use glassbake_core::layout::{self, opaque, transparent};
use glassbake_core::{Camera, Error, PlanarImage};
use glassbake_scene::Scene;

const W: u32 = 50; // 800-byte rows: exercises the 256-byte readback padding
const H: u32 = 40;

/// A 4 x 4 opaque wall at z = -1, an opaque occluder in front of everything, a glass pane
/// facing the camera (partly hidden by the occluder) and a second pane facing away from the
/// camera that hangs over the wall's edge (no opaque surface behind part of it).
fn known_scene() -> (Scene, Vec<Quad>, Camera) {
    let quads = vec![
        Quad { centre: Vec3::new(0.0, 0.0, -1.0), u: Vec3::X * 4.0, v: Vec3::Y * 4.0, albedo: Vec3::new(0.5, 0.4, 0.3), roughness: 0.7, transparent: false },
        Quad { centre: Vec3::new(-0.2, 0.0, 2.0), u: Vec3::X * 0.2, v: Vec3::Y * 0.2, albedo: Vec3::new(0.2, 0.6, 0.1), roughness: 0.9, transparent: false },
        Quad { centre: Vec3::new(-0.3, 0.0, 1.0), u: Vec3::X * 1.0, v: Vec3::Y * 1.0, albedo: Vec3::new(0.9, 0.95, 1.0), roughness: 0.05, transparent: true },
        // Faces -z, away from the camera: u x v = x x (-y) = -z.
        Quad { centre: Vec3::new(1.0, 0.0, 0.5), u: Vec3::X * 0.8, v: Vec3::NEG_Y * 0.6, albedo: Vec3::new(0.7, 0.9, 0.8), roughness: 0.2, transparent: true },
    ];
    assert!(quads[3].normal().z < 0.0, "the second pane faces away from the camera");
    let mut scene = empty_scene("known");
    add_quads(&mut scene, &quads);
    // Behind the camera, facing the wall: lights the scene, invisible in the image.
    scene.rect_lights.push(light(Vec3::new(-0.5, 1.0, 3.5), Vec3::X, Vec3::Y * -0.5, Vec3::splat(5.0)));
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 60.0);
    (scene, quads, cam)
}

/// Nearest hit among the quads selected by `keep`: (quad index, t).
fn nearest(quads: &[Quad], origin: Vec3, dir: Vec3, keep: impl Fn(usize) -> bool) -> Option<(usize, f32)> {
    quads.iter().enumerate().filter(|(i, _)| keep(*i)).filter_map(|(i, q)| q.hit(origin, dir).map(|t| (i, t))).min_by(|a, b| a.1.total_cmp(&b.1))
}

/// What each buffer sees along a ray: (opaque hit, naive hit, hit of transparent quad k if
/// in front of the opaque hit).
type Seen = (Option<usize>, Option<usize>, Vec<Option<usize>>);

fn seen(quads: &[Quad], origin: Vec3, dir: Vec3, transparent: &[usize]) -> Seen {
    let o = nearest(quads, origin, dir, |i| !quads[i].transparent);
    let n = nearest(quads, origin, dir, |_| true);
    let t = transparent
        .iter()
        .map(|&k| {
            let hit = quads[k].hit(origin, dir)?;
            match o {
                Some((_, to)) if to <= hit => None,
                _ => Some(k),
            }
        })
        .collect();
    (o.map(|h| h.0), n.map(|h| h.0), t)
}

/// Pixels whose centre and corners all see the same surfaces in every buffer (away from
/// edges, where which triangle covers a pixel is a rasterization-rule detail).
fn unambiguous(cam: &Camera, quads: &[Quad], transparent: &[usize], x: u32, y: u32) -> bool {
    let centre = seen(quads, cam.position, cam.pixel_center_ray(x, y, W, H).direction, transparent);
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].iter().all(|(dx, dy)| {
        let r = cam.ray(x as f32 + dx, y as f32 + dy, W, H);
        seen(quads, cam.position, r.direction, transparent) == centre
    })
}

fn check(what: &str, got: f32, want: f32, tol: f32, x: u32, y: u32, max_err: &mut f32) {
    let err = (got - want).abs();
    *max_err = max_err.max(err);
    assert!(err <= tol, "{what} at ({x}, {y}): got {got}, want {want} (tolerance {tol})");
}

fn vec3_at(im: &PlanarImage, first: usize, x: u32, y: u32) -> Vec3 {
    Vec3::new(im.get(first, x, y), im.get(first + 1, x, y), im.get(first + 2, x, y))
}

const POS_TOL: f32 = 1e-5;
const DIR_TOL: f32 = 1e-6;
const EXACT: f32 = 1e-6;

#[test]
fn every_channel_of_every_buffer_matches_a_ray_cast() {
    let (scene, quads, cam) = known_scene();
    let transparent_quads: Vec<usize> = scene.transparent_objects();
    assert_eq!(transparent_quads, vec![2, 3]);
    let mut r = rasterizer();
    let b = r.render(&scene, &cam, W, H).unwrap();
    assert_eq!(b.opaque.channels(), layout::opaque_channel_names().as_slice());
    assert_eq!(b.naive.channels(), layout::naive_channel_names().as_slice());
    assert_eq!(b.transparent.len(), 2);
    assert_eq!(b.transparent[1].channels(), layout::transparent_channel_names(1).as_slice());

    let mut checked = 0;
    let (mut max_pos, mut max_dir) = (0.0f32, 0.0f32);
    let (mut wall, mut lit, mut glass_lit) = (0, 0, 0);
    let mut counts = [0usize; 4]; // glass 0 drawn, glass 1 drawn, glass 1 without opaque behind, occluded glass
    for y in 0..H {
        for x in 0..W {
            if !unambiguous(&cam, &quads, &transparent_quads, x, y) {
                continue;
            }
            checked += 1;
            let ray = cam.pixel_center_ray(x, y, W, H);
            let (o, _, t) = seen(&quads, ray.origin, ray.direction, &transparent_quads);
            let opaque_hit = nearest(&quads, ray.origin, ray.direction, |i| !quads[i].transparent);

            // Opaque and naive G-buffers.
            for (im, hit) in [(&b.opaque, opaque_hit), (&b.naive, nearest(&quads, ray.origin, ray.direction, |_| true))] {
                match hit {
                    None => {
                        for c in 0..layout::OPAQUE_CHANNELS {
                            assert_eq!(im.get(c, x, y), 0.0, "background channel {c} at ({x}, {y})");
                        }
                    }
                    Some((i, t_hit)) => {
                        let q = quads[i];
                        let p = ray.at(t_hit);
                        let n = if q.normal().dot(-ray.direction) > 0.0 { q.normal() } else { -q.normal() };
                        for c in 0..3 {
                            check("normal", im.get(opaque::NORMAL + c, x, y), n[c], DIR_TOL, x, y, &mut max_dir);
                            check("position", im.get(opaque::POSITION + c, x, y), p[c], POS_TOL, x, y, &mut max_pos);
                            check("albedo", im.get(opaque::ALBEDO + c, x, y), q.albedo[c], EXACT, x, y, &mut 0.0);
                            check("wo", im.get(opaque::WO + c, x, y), -ray.direction[c], DIR_TOL, x, y, &mut max_dir);
                            let ld = im.get(opaque::LD + c, x, y);
                            assert!(ld.is_finite() && ld >= 0.0, "L_d {ld} at ({x}, {y})");
                        }
                        check("roughness", im.get(opaque::ROUGHNESS, x, y), q.roughness, EXACT, x, y, &mut 0.0);
                        check("depth", im.get(opaque::DEPTH, x, y), t_hit, POS_TOL, x, y, &mut max_pos);
                    }
                }
            }
            // The wall is lit by the light behind the camera (except in the occluder's shadow).
            if o == Some(0) {
                wall += 1;
                lit += (b.opaque.get(opaque::LD, x, y) > 0.0) as usize;
            }

            // Transparency buffers.
            for (k, &qi) in transparent_quads.iter().enumerate() {
                let im = &b.transparent[k];
                match t[k] {
                    None => {
                        for c in 0..layout::TRANSPARENT_CHANNELS {
                            assert_eq!(im.get(c, x, y), 0.0, "transparent.{k} channel {c} at ({x}, {y})");
                        }
                        if quads[qi].hit(ray.origin, ray.direction).is_some() {
                            counts[3] += 1;
                        }
                    }
                    Some(_) => {
                        counts[k] += 1;
                        let q = quads[qi];
                        let t_hit = q.hit(ray.origin, ray.direction).unwrap();
                        let p = ray.at(t_hit);
                        let n = if q.normal().dot(-ray.direction) > 0.0 { q.normal() } else { -q.normal() };
                        for c in 0..3 {
                            check("normal", im.get(transparent::NORMAL + c, x, y), n[c], DIR_TOL, x, y, &mut max_dir);
                            check("position", im.get(transparent::POSITION + c, x, y), p[c], POS_TOL, x, y, &mut max_pos);
                            check("albedo", im.get(transparent::ALBEDO + c, x, y), q.albedo[c], EXACT, x, y, &mut 0.0);
                            check("wo", im.get(transparent::WO + c, x, y), -ray.direction[c], DIR_TOL, x, y, &mut max_dir);
                        }
                        check("roughness", im.get(transparent::ROUGHNESS, x, y), q.roughness, EXACT, x, y, &mut 0.0);
                        check("depth", im.get(transparent::DEPTH, x, y), t_hit, POS_TOL, x, y, &mut max_pos);
                        let relative = match opaque_hit {
                            Some((_, to)) => to - t_hit,
                            None => {
                                counts[2] += 1;
                                0.0
                            }
                        };
                        check("relative depth", im.get(transparent::RELATIVE_DEPTH, x, y), relative, POS_TOL, x, y, &mut max_pos);
                        assert_eq!(im.get(transparent::COVERAGE, x, y), 1.0, "coverage at ({x}, {y})");
                        // L_d: the light the glass surface reflects, the same as the naive
                        // G-buffer's where that surface is the front-most one.
                        if nearest(&quads, ray.origin, ray.direction, |_| true).map(|(i, _)| i) == Some(qi) {
                            for c in 0..3 {
                                let (got, want) = (im.get(transparent::LD + c, x, y), b.naive.get(opaque::LD + c, x, y));
                                check("L_d", got, want, 1e-5 * want.max(1.0), x, y, &mut 0.0);
                            }
                            glass_lit += (im.get(transparent::LD, x, y) > 0.0) as usize;
                        }
                        // A single pane is its own farthest surface.
                        for c in 0..3 {
                            check("L_d far", im.get(transparent::LD_FAR + c, x, y), im.get(transparent::LD + c, x, y), 0.0, x, y, &mut 0.0);
                        }
                    }
                }
            }
        }
    }
    eprintln!("checked {checked} of {} pixels; max position/depth error {max_pos:e}, max direction error {max_dir:e}; glass pixels {counts:?}", W * H);
    // The scene exercises every case.
    assert!(checked > (W * H * 8 / 10) as usize);
    assert!(counts.iter().all(|&n| n > 0), "{counts:?}");
    assert!(lit * 10 > wall * 9, "{lit} of {wall} wall pixels lit");
    assert!(glass_lit > 0, "no glass pixel reflects the light: the L_d check compared only zeros");
}

#[test]
fn naive_differs_from_opaque_exactly_where_glass_covers() {
    let (scene, _, cam) = known_scene();
    let mut r = rasterizer();
    let b = r.render(&scene, &cam, W, H).unwrap();
    let mut covered = 0;
    for y in 0..H {
        for x in 0..W {
            let glass = b.transparent.iter().any(|t| t.get(transparent::COVERAGE, x, y) > 0.0);
            let differs = (0..layout::OPAQUE_CHANNELS).any(|c| b.naive.get(c, x, y) != b.opaque.get(c, x, y));
            assert_eq!(differs, glass, "pixel ({x}, {y}): naive differs {differs}, glass covers {glass}");
            covered += glass as usize;
        }
    }
    assert!(covered > 50, "{covered}");
}

#[test]
fn streaming_equals_all_at_once_and_reuses_one_buffer() {
    let (scene, _, cam) = known_scene();
    let mut r = rasterizer();
    let all = r.render(&scene, &cam, W, H).unwrap();
    let mut frame = r.begin_frame(&scene, &cam, W, H).unwrap();
    assert_eq!(frame.opaque().unwrap(), all.opaque);
    let mut planes = vec![f32::NAN; layout::TRANSPARENT_CHANNELS * (W * H) as usize];
    for k in (0..frame.transparent_count()).rev() {
        frame.transparent_into(k, &mut planes).unwrap();
        assert!(planes == all.transparent[k].data(), "transparency buffer {k}");
    }
    // Wrong buffer size is an error, not a panic.
    assert!(frame.transparent_into(0, &mut [0.0; 3]).is_err());
    assert!(frame.transparent(2).is_err());
}

#[test]
fn g_buffer_position_lies_on_the_pixel_centre_ray() {
    let scene = glassbake_scene::builtin::builtin("cornellbox").unwrap();
    let mut r = rasterizer();
    for i in 0..3 {
        let sample = scene.sample(7, i);
        let instance = scene.instantiate(&sample.values).unwrap();
        let (w, h) = (48, 36);
        let b = r.render(&instance, &sample.camera, w, h).unwrap();
        let mut hits = 0;
        for y in 0..h {
            for x in 0..w {
                for (im, depth_c, pos_c) in [(&b.opaque, opaque::DEPTH, opaque::POSITION), (&b.transparent[0], transparent::DEPTH, transparent::POSITION)] {
                    let depth = im.get(depth_c, x, y);
                    if depth == 0.0 {
                        continue;
                    }
                    hits += 1;
                    let p = vec3_at(im, pos_c, x, y);
                    let ray = sample.camera.pixel_center_ray(x, y, w, h);
                    let along = (p - ray.origin).dot(ray.direction);
                    let off_ray = (p - ray.at(along)).length();
                    assert!(off_ray <= 2e-5 * along, "({x}, {y}): {off_ray} off the ray at distance {along}");
                    assert!((depth - along).abs() <= 2e-5 * along, "({x}, {y}): depth {depth} vs {along}");
                }
            }
        }
        assert!(hits > (w * h) as usize);
    }
}

#[test]
fn bad_resolutions_are_refused_as_bad_input() {
    let (scene, _, cam) = known_scene();
    let mut r = rasterizer();
    for (w, h) in [(0, 16), (16, 0), (8193, 16)] {
        match r.render(&scene, &cam, w, h) {
            Err(Error::BadInput { .. }) => {}
            other => panic!("{w}x{h}: {:?}", other.map(|_| ())),
        }
    }
}

#[test]
fn a_scene_without_lights_has_zero_direct_light_except_emission() {
    let (mut scene, quads, cam) = known_scene();
    scene.rect_lights.clear();
    // The occluder glows.
    scene.materials[1].emission = Vec3::new(2.0, 1.0, 0.5);
    let mut r = rasterizer();
    let b = r.render(&scene, &cam, W, H).unwrap();
    let mut glowing = 0;
    for y in 0..H {
        for x in 0..W {
            let ray = cam.pixel_center_ray(x, y, W, H);
            let hit = nearest(&quads, ray.origin, ray.direction, |i| !quads[i].transparent);
            let ld = vec3_at(&b.opaque, opaque::LD, x, y);
            match hit {
                Some((1, _)) if unambiguous(&cam, &quads, &[2, 3], x, y) => {
                    assert_eq!(ld, Vec3::new(2.0, 1.0, 0.5));
                    glowing += 1;
                }
                Some((0, _)) if unambiguous(&cam, &quads, &[2, 3], x, y) => assert_eq!(ld, Vec3::ZERO),
                _ => {}
            }
        }
    }
    assert!(glowing > 0);
}

#[test]
fn textures_are_sampled_with_mipmaps() {
    // A 1-texel black/white checkerboard tiled 64 times over a wall seen from afar: with
    // mipmaps every pixel averages many texels (~0.5); without them it would alias to 0 or 1.
    use std::sync::Arc;
    let (mut scene, _, _) = known_scene();
    let checker = glassbake_scene::Texture::from_fn("checker", 64, 64, true, |u, v| {
        let c = ((u * 64.0) as u32 + (v * 64.0) as u32) % 2;
        glam::Vec4::new(c as f32, c as f32, c as f32, 1.0)
    });
    scene.textures.push(Arc::new(checker));
    scene.meshes[0] = Arc::new(glassbake_scene::shapes::rect(Vec3::new(0.0, 0.0, -1.0), Vec3::X * 4.0, Vec3::Y * 4.0, glam::Vec2::splat(64.0)));
    scene.materials[0].base_color = Vec3::ONE;
    scene.materials[0].base_color_texture = Some(0);
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.0, 0.0, -1.0), 60.0);
    let mut r = rasterizer();
    let b = r.render(&scene, &cam, 32, 32).unwrap();
    let mut n = 0;
    for y in 12..20 {
        for x in 12..20 {
            if b.opaque.get(opaque::DEPTH, x, y) > 3.9 {
                let a = b.opaque.get(opaque::ALBEDO, x, y);
                assert!((a - 0.5).abs() < 0.1, "albedo {a} at ({x}, {y})");
                n += 1;
            }
        }
    }
    assert!(n > 10, "{n}");
}

#[test]
fn a_device_with_default_limits_is_refused_and_a_shared_one_renders() {
    let r = rasterizer();
    let (instance, adapter) = (r.instance().clone(), r.adapter().clone());
    let open = |limits: glassbake_raster::wgpu::Limits| {
        pollster::block_on(adapter.request_device(&glassbake_raster::wgpu::DeviceDescriptor { required_limits: limits, ..Default::default() })).unwrap()
    };
    let (device, queue) = open(glassbake_raster::wgpu::Limits::default());
    let err = glassbake_raster::Rasterizer::from_device(instance.clone(), adapter.clone(), device, queue, Default::default());
    assert!(err.is_err());
    let (device, queue) = open(adapter.limits());
    let mut shared = glassbake_raster::Rasterizer::from_device(instance, adapter.clone(), device, queue, Default::default()).unwrap();
    let (scene, _, cam) = known_scene();
    let mut own = rasterizer();
    assert_eq!(shared.render(&scene, &cam, W, H).unwrap().opaque, own.render(&scene, &cam, W, H).unwrap().opaque);
}

/// Shadows are tested from the light's centre (docs/raster.md): wall points whose segments to
/// the light's centre region are blocked by the occluder get no direct light; points whose
/// segments are all clear get light.
#[test]
fn the_occluder_shadows_the_wall_as_seen_from_the_lights_centre() {
    let (scene, quads, cam) = known_scene();
    let light = &scene.rect_lights[0];
    let mut r = rasterizer();
    let frame = r.render(&scene, &cam, W, H).unwrap();
    // The centre and four points around it on the light (a margin against the shadow map's
    // resolution and filtering at the shadow's edge).
    let (du, dv) = (light.edge_u * 0.08, light.edge_v * 0.08);
    let c = light.center();
    let probes = [c, c + du, c - du, c + dv, c - dv];
    let blocked = |p: Vec3, q: Vec3| quads[1].hit(p, (q - p).normalize()).is_some_and(|t| t < (q - p).length());
    let (mut shadowed, mut lit) = (Vec::new(), Vec::new());
    for y in 0..H {
        for x in 0..W {
            let ray = cam.pixel_center_ray(x, y, W, H);
            if !unambiguous(&cam, &quads, &[2, 3], x, y) || nearest(&quads, ray.origin, ray.direction, |i| !quads[i].transparent).map(|h| h.0) != Some(0) {
                continue;
            }
            let p = vec3_at(&frame.opaque, opaque::POSITION, x, y);
            let ld = vec3_at(&frame.opaque, opaque::LD, x, y).x;
            match probes.iter().filter(|&&q| blocked(p, q)).count() {
                5 => shadowed.push(ld),
                0 => lit.push(ld),
                _ => {}
            }
        }
    }
    assert!(shadowed.len() >= 5 && lit.len() >= 100, "{} shadowed, {} lit pixels", shadowed.len(), lit.len());
    let lit_min = lit.iter().copied().fold(f32::INFINITY, f32::min);
    assert!(lit_min > 0.0, "every clear wall point receives light");
    let shadow_max = shadowed.iter().copied().fold(0.0, f32::max);
    assert!(shadow_max <= 0.02 * lit_min, "shadowed L_d up to {shadow_max}, lit at least {lit_min}");
}

#[test]
fn the_far_pass_holds_the_light_reflected_by_the_far_wall() {
    // One transparent object of two walls, as a thin glass box's front and back: its L_d is
    // the near wall's and its L_d_far the far wall's, each equal to the L_d of a transparency
    // buffer of that wall alone. A light above, between camera and walls, shows in both, unalike.
    let wall_scene = |walls: &[(Vec3, f32)]| {
        let mut scene = empty_scene("walls");
        add_quads(
            &mut scene,
            &[Quad { centre: Vec3::new(0.0, 0.0, -1.0), u: Vec3::X * 4.0, v: Vec3::Y * 4.0, albedo: Vec3::splat(0.5), roughness: 0.8, transparent: false }],
        );
        let mut mesh = glassbake_scene::Mesh::default();
        for &(centre, tilt) in walls {
            let v = Vec3::new(0.0, tilt.cos(), tilt.sin());
            mesh.append(&glassbake_scene::shapes::rect(centre - Vec3::X * 0.6 - v * 0.6, Vec3::X * 1.2, v * 1.2, glam::Vec2::ONE));
        }
        scene.meshes.push(std::sync::Arc::new(mesh));
        scene.materials.push(glassbake_scene::Material::glass("glass", Vec3::ONE, 0.4, 1.5, true));
        scene.objects.push(glassbake_scene::Object {
            name: "walls".into(),
            mesh: scene.meshes.len() - 1,
            material: scene.materials.len() - 1,
            transform: glam::Affine3A::IDENTITY,
            transparent: true,
        });
        scene.rect_lights.push(light(Vec3::new(-0.5, 1.2, 1.4), Vec3::X, Vec3::Z * 0.8, Vec3::splat(8.0)));
        scene
    };
    let near = (Vec3::new(0.0, 0.0, 1.0), -0.2);
    let far = (Vec3::new(0.0, 0.0, 0.2), -0.7);
    let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 50.0);
    let mut r = rasterizer();
    let mut ld = |walls: &[(Vec3, f32)]| r.render(&wall_scene(walls), &cam, W, H).unwrap().transparent.remove(0);
    let (both, near_only, far_only) = (ld(&[near, far]), ld(&[near]), ld(&[far]));
    let (mut compared, mut differ) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let covered = |im: &PlanarImage| im.get(transparent::COVERAGE, x, y) == 1.0;
            // Pixels inside both walls, away from their edges (where which one covers a
            // pixel is a rasterization detail).
            let inside = (-1..=1).all(|dy: i32| {
                (-1..=1).all(|dx: i32| {
                    let (px, py) = ((x as i32 + dx).clamp(0, W as i32 - 1) as u32, (y as i32 + dy).clamp(0, H as i32 - 1) as u32);
                    near_only.get(transparent::COVERAGE, px, py) == 1.0 && far_only.get(transparent::COVERAGE, px, py) == 1.0
                })
            });
            if !inside {
                continue;
            }
            assert!(covered(&both));
            compared += 1;
            for c in 0..3 {
                let (got_near, want_near) = (both.get(transparent::LD + c, x, y), near_only.get(transparent::LD + c, x, y));
                let (got_far, want_far) = (both.get(transparent::LD_FAR + c, x, y), far_only.get(transparent::LD + c, x, y));
                check("L_d of the near wall", got_near, want_near, 1e-6 * want_near.max(1.0), x, y, &mut 0.0);
                check("L_d_far of the far wall", got_far, want_far, 1e-6 * want_far.max(1.0), x, y, &mut 0.0);
                // A single wall is its own far surface.
                check("L_d_far of one wall", far_only.get(transparent::LD_FAR + c, x, y), want_far, 1e-6 * want_far.max(1.0), x, y, &mut 0.0);
            }
            let (l_near, l_far) = (both.get(transparent::LD, x, y), both.get(transparent::LD_FAR, x, y));
            differ += (l_near > 0.0 && l_far > 0.0 && (l_near - l_far).abs() > 0.05 * l_near.max(l_far)) as usize;
        }
    }
    eprintln!("{compared} pixels inside both walls, {differ} with both lit, unalike");
    assert!(compared > 100, "{compared}");
    assert!(differ * 2 > compared, "near and far walls are unlit or lit alike in {} of {compared} pixels: the check cannot tell them apart", compared - differ);
}
