//! On a built-in scene with curved glass (CORNELLBOX8, sampled camera and variables): which
//! pixels each transparency buffer covers, and the opaque depth, against a CPU ray cast
//! through the pixel centres against every triangle.

mod common;

use glam::Vec3;
use glassbake_core::layout::{opaque, transparent};
use glassbake_scene::Scene;

/// Nearest hit of a ray with a triangle list (Moller-Trumbore), double-sided.
fn nearest_hit(triangles: &[[Vec3; 3]], origin: Vec3, dir: Vec3) -> Option<f32> {
    let mut best: Option<f32> = None;
    for [a, b, c] in triangles {
        let e1 = *b - *a;
        let e2 = *c - *a;
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let inv = 1.0 / det;
        let s = origin - *a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let q = s.cross(e1);
        let v = dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t = e2.dot(q) * inv;
        if t > 1e-6 && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    }
    best
}

fn triangles(scene: &Scene, objects: impl Iterator<Item = usize>) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for i in objects {
        let mesh = scene.world_mesh(i);
        out.extend(mesh.indices.iter().map(|t| t.map(|k| mesh.positions[k as usize])));
    }
    out
}

#[test]
fn coverage_and_depth_match_a_ray_cast_on_cornellbox8() {
    let base = glassbake_scene::builtin::builtin("cornellbox8").unwrap();
    let sample = base.sample(11, 3);
    let scene = base.instantiate(&sample.values).unwrap();
    let cam = sample.camera;
    let (w, h) = (40, 40);
    let mut r = common::rasterizer();
    let b = r.render(&scene, &cam, w, h).unwrap();

    let opaque_objects: Vec<usize> = (0..scene.objects.len()).filter(|&i| !scene.objects[i].transparent).collect();
    let mut occluders = triangles(&scene, opaque_objects.into_iter());
    for l in &scene.rect_lights {
        let c = l.corners();
        occluders.push([c[0], c[1], c[2]]);
        occluders.push([c[0], c[2], c[3]]);
    }
    let glass: Vec<Vec<[Vec3; 3]>> = scene.transparent_objects().into_iter().map(|i| triangles(&scene, std::iter::once(i))).collect();

    // Coverage as the ray cast sees it through image point (px, py), per transparency buffer.
    let seen = |px: f32, py: f32| -> (Option<f32>, Vec<bool>) {
        let ray = cam.ray(px, py, w, h);
        let o = nearest_hit(&occluders, ray.origin, ray.direction);
        let cover = glass.iter().map(|tris| nearest_hit(tris, ray.origin, ray.direction).is_some_and(|t| o.is_none_or(|o| t < o))).collect();
        (o, cover)
    };
    let (mut compared, mut covered) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let (o, cover) = seen(x as f32 + 0.5, y as f32 + 0.5);
            // Skip pixels on a silhouette (the corners disagree on what they see).
            let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].map(|(dx, dy)| seen(x as f32 + dx, y as f32 + dy));
            if corners.iter().any(|c| c.1 != cover || c.0.is_some() != o.is_some()) {
                continue;
            }
            compared += 1;
            let depth = b.opaque.get(opaque::DEPTH, x, y);
            match o {
                // Curved surfaces are tessellated identically; only rounding differs.
                Some(t) => assert!((depth - t).abs() <= 1e-4 * t, "opaque depth at ({x}, {y}): {depth} vs {t}"),
                None => assert_eq!(depth, 0.0, "({x}, {y})"),
            }
            for (k, &c) in cover.iter().enumerate() {
                let got = b.transparent[k].get(transparent::COVERAGE, x, y);
                assert_eq!(got, if c { 1.0 } else { 0.0 }, "coverage of transparency buffer {k} at ({x}, {y})");
                covered += c as usize;
            }
        }
    }
    assert!(compared > (w * h * 7 / 10) as usize, "{compared}");
    assert!(covered > 50, "{covered}");
}

/// The through buffers against the rasterized frame (CORNELLBOX, sampled camera and
/// variables): through a thin pane, which does not bend light, the ray lands where the opaque
/// G-buffer's pixel is and takes its L_d; through solid glass it lands elsewhere; where an
/// object covers nothing its through buffer is empty. Silhouette pixels are left out.
#[test]
fn through_buffers_agree_with_the_rasterized_frame_on_cornellbox() {
    use glassbake_core::layout::{through, THROUGH_CHANNELS};
    let base = glassbake_scene::builtin::builtin("cornellbox").unwrap();
    let sample = base.sample(5, 2);
    let scene = base.instantiate(&sample.values).unwrap();
    let (w, h) = (48, 48);
    let b = common::rasterizer().render(&scene, &sample.camera, w, h).unwrap();
    assert_eq!(b.through.len(), b.transparent.len());
    let (mut thin_pixels, mut solid_pixels, mut bent) = (0, 0, 0);
    for (k, &object) in scene.transparent_objects().iter().enumerate() {
        let thin = scene.materials[scene.objects[object].material].transmission.is_some_and(|t| t.thin);
        let (buffer, cast) = (&b.transparent[k], &b.through[k]);
        for y in 0..h {
            for x in 0..w {
                let at = |image: &glassbake_core::PlanarImage, c: usize| Vec3::new(image.get(c, x, y), image.get(c + 1, x, y), image.get(c + 2, x, y));
                if buffer.get(transparent::COVERAGE, x, y) == 0.0 {
                    assert!((0..THROUGH_CHANNELS).all(|c| cast.get(c, x, y) == 0.0), "buffer {k} casts at uncovered ({x}, {y})");
                    continue;
                }
                // On a silhouette the pixel centre's ray may miss what the rasterizer covered.
                let neighbours = [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)];
                if neighbours.iter().any(|&(u, v)| u >= w || v >= h || buffer.get(transparent::COVERAGE, u, v) == 0.0) {
                    continue;
                }
                let (hit, seen) = (at(cast, through::POSITION), at(&b.opaque, opaque::POSITION));
                let transmittance = cast.get(through::TRANSMITTANCE, x, y);
                assert!(transmittance > 0.0 && transmittance <= 1.0, "buffer {k} at ({x}, {y}): transmittance {transmittance}");
                let same_point = (hit - seen).length() <= 1e-3 * b.opaque.get(opaque::DEPTH, x, y);
                if thin {
                    thin_pixels += 1;
                    assert!(same_point, "through pane {k} at ({x}, {y}): {hit} vs the G-buffer's {seen}");
                    // Every ray of the footprint reads the G-buffer at this pixel: their mean,
                    // weighted by each one's transmittance, is its L_d to rounding.
                    let (light, gbuffer_light) = (at(cast, through::LD), at(&b.opaque, opaque::LD));
                    assert!(
                        (light - gbuffer_light).abs().max_element() <= 1e-5 * gbuffer_light.max_element().max(1e-3),
                        "pane {k} at ({x}, {y}): {light} vs {gbuffer_light}"
                    );
                    assert_eq!(cast.get(through::LENGTH, x, y), 0.0);
                    // The hit is what the G-buffer shows at this very pixel.
                    assert_eq!((cast.get(through::SCREEN_OFFSET, x, y), cast.get(through::SCREEN_OFFSET + 1, x, y)), (0.0, 0.0), "pane {k} at ({x}, {y})");
                    assert_eq!(cast.get(through::ON_SCREEN, x, y), 1.0, "pane {k} at ({x}, {y})");
                } else {
                    solid_pixels += 1;
                    bent += usize::from(!same_point);
                    assert!(cast.get(through::LENGTH, x, y) > 0.0, "solid {k} at ({x}, {y}) has no length inside");
                }
            }
        }
    }
    assert!(thin_pixels > 20 && solid_pixels > 20, "panes {thin_pixels}, solids {solid_pixels}");
    assert!(bent * 2 > solid_pixels, "solid glass bent only {bent} of {solid_pixels} rays");
}
