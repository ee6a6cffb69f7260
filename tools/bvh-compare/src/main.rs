//! Closest-hit throughput of two BVH crates on the built-in scenes: obvhs's compressed wide
//! BVH8 (what glassbake-trace uses) against the `bvh` crate's SAH binary BVH, traversed front to
//! back with t-max culling. Same triangles, same rays, same Moller-Trumbore test.
//! With `--features embree` also Embree 3 (`rtcIntersect1`, one ray at a time as glassbake
//! traces, its own watertight triangle test; needs `apt-get install libembree-dev`), the BVH
//! behind Mitsuba 3's CPU variants.
//!
//! CARGO_TARGET_DIR=../../target cargo run --release [--features embree]   (from tools/bvh-compare)
use std::time::{Duration, Instant};
use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::BHShape;
use bvh::bvh::{Bvh, BvhNode};
use glam::Vec3;
use nalgebra::{Point3, Vector3};

#[derive(Clone, Copy)]
struct Tri { v0: Vec3, e1: Vec3, e2: Vec3, node: usize }
impl Tri {
    #[inline(always)]
    fn hit(&self, o: Vec3, d: Vec3, tmax: f32) -> f32 {
        let p = d.cross(self.e2); let det = self.e1.dot(p); if det == 0.0 { return f32::INFINITY; }
        let inv = 1.0 / det; let s = o - self.v0; let b1 = s.dot(p) * inv; if !(0.0..=1.0).contains(&b1) { return f32::INFINITY; }
        let q = s.cross(self.e1); let b2 = d.dot(q) * inv; if b2 < 0.0 || b1 + b2 > 1.0 { return f32::INFINITY; }
        let t = self.e2.dot(q) * inv; if t > 0.0 && t < tmax { t } else { f32::INFINITY }
    }
}
impl Bounded<f32, 3> for Tri {
    fn aabb(&self) -> Aabb<f32, 3> {
        let (a, b, c) = (self.v0, self.v0 + self.e1, self.v0 + self.e2);
        let lo = a.min(b).min(c); let hi = a.max(b).max(c);
        Aabb::with_bounds(Point3::new(lo.x, lo.y, lo.z), Point3::new(hi.x, hi.y, hi.z))
    }
}
impl BHShape<f32, 3> for Tri {
    fn set_bh_node_index(&mut self, i: usize) { self.node = i; }
    fn bh_node_index(&self) -> usize { self.node }
}

fn bvh_closest(bvh: &Bvh<f32, 3>, tris: &[Tri], o: Vec3, d: Vec3) -> f32 {
    let ray = bvh::ray::Ray::new(Point3::new(o.x, o.y, o.z), Vector3::new(d.x, d.y, d.z));
    let mut best = f32::INFINITY;
    let mut stack: [usize; 64] = [0; 64]; let mut sp = 1; stack[0] = 0;
    while sp > 0 {
        sp -= 1; let n = stack[sp];
        match bvh.nodes[n] {
            BvhNode::Leaf { shape_index, .. } => { best = best.min(tris[shape_index].hit(o, d, best)); }
            BvhNode::Node { child_l_index, child_l_aabb, child_r_index, child_r_aabb, .. } => {
                let l = ray.intersection_slice_for_aabb(&child_l_aabb).filter(|s| s.0 < best);
                let r = ray.intersection_slice_for_aabb(&child_r_aabb).filter(|s| s.0 < best);
                match (l, r) {
                    (Some(a), Some(b)) => { if a.0 < b.0 { stack[sp] = child_r_index; stack[sp + 1] = child_l_index; } else { stack[sp] = child_l_index; stack[sp + 1] = child_r_index; } sp += 2; }
                    (Some(_), None) => { stack[sp] = child_l_index; sp += 1; }
                    (None, Some(_)) => { stack[sp] = child_r_index; sp += 1; }
                    _ => {}
                }
            }
        }
    }
    best
}

fn main() {
    let embree_columns = if cfg!(feature = "embree") { (" Embree build | Embree Mrays/s | same t as obvhs |", "---|---|---|") } else { ("", "") };
    println!("| scene | triangles | rays | obvhs build | obvhs Mrays/s | bvh build | bvh Mrays/s | same hits |{}", embree_columns.0);
    println!("|---|---|---|---|---|---|---|---|{}", embree_columns.1);
    for name in ["cornell-glass", "cornellbox", "cornellbox8", "desk", "bathroom"] {
        let scene = glassbake_scene::builtin::builtin(name).unwrap();
        let sample = scene.sample(0, 0);
        let inst = scene.instantiate(&sample.values).unwrap();
        let mut tris = Vec::new();
        for i in 0..inst.objects.len() {
            let m = inst.world_mesh(i);
            for t in &m.indices { let [a, b, c] = t.map(|i| m.positions[i as usize]); if (b - a).cross(c - a).length_squared() > 0.0 { tris.push(Tri { v0: a, e1: b - a, e2: c - a, node: 0 }); } }
        }
        // Rays: primary rays through a 256^2 grid, then from each primary hit a secondary ray in a
        // hashed direction (the incoherent rays that dominate path tracing).
        let cam = sample.camera; let res = 256u32;
        let mut rays = Vec::new();
        let mut rng = glassbake_trace::rng::Pcg32::new(1, 1);
        for y in 0..res { for x in 0..res { let r = cam.pixel_center_ray(x, y, res, res); rays.push((r.origin, r.direction)); } }
        let primary = rays.len();
        // obvhs
        let t0 = Instant::now();
        let otris: Vec<obvhs::triangle::Triangle> = tris.iter().map(|t| { let c = |v: Vec3| glam_bvh::Vec3A::new(v.x, v.y, v.z); obvhs::triangle::Triangle { v0: c(t.v0), v1: c(t.v0 + t.e1), v2: c(t.v0 + t.e2) } }).collect();
        let cw = obvhs::cwbvh::builder::build_cwbvh_from_tris(&otris, obvhs::BvhBuildParams::medium_build(), &mut Duration::default());
        let ordered: Vec<Tri> = cw.primitive_indices.iter().map(|&i| tris[i as usize]).collect();
        let obuild = t0.elapsed();
        let ocast = |o: Vec3, d: Vec3| { let mut h = obvhs::ray::RayHit::none(); let ray = obvhs::ray::Ray::new_inf(glam_bvh::Vec3A::new(o.x, o.y, o.z), glam_bvh::Vec3A::new(d.x, d.y, d.z)); cw.ray_traverse(ray, &mut h, |r, id| ordered[id].hit(o, d, r.tmax)); h.t };
        for i in 0..primary { let (o, d) = rays[i]; let t = ocast(o, d); if t.is_finite() { let p = o + d * t * 0.9999; let u = rng.next_vec2(); let z = 1.0 - 2.0 * u.x; let rr = (1.0 - z * z).max(0.0).sqrt(); let phi = 6.2831855 * u.y; rays.push((p, Vec3::new(rr * phi.cos(), rr * phi.sin(), z))); } }
        // bvh crate
        let t1 = Instant::now();
        let mut btris = tris.clone();
        let b = Bvh::build(&mut btris);
        let bbuild = t1.elapsed();
        let reps = 3;
        let t2 = Instant::now(); let mut osum = Vec::with_capacity(rays.len());
        for _ in 0..reps { osum.clear(); for &(o, d) in &rays { osum.push(ocast(o, d)); } }
        let otime = t2.elapsed();
        let t3 = Instant::now(); let mut bsum = Vec::with_capacity(rays.len());
        for _ in 0..reps { bsum.clear(); for &(o, d) in &rays { bsum.push(bvh_closest(&b, &btris, o, d)); } }
        let btime = t3.elapsed();
        let same = osum.iter().zip(&bsum).filter(|(a, b)| a == b || (a.is_infinite() && b.is_infinite())).count();
        let n = (rays.len() * reps) as f64;
        print!("| {name} | {} | {} | {:.1} ms | {:.2} | {:.1} ms | {:.2} | {:.4} |", tris.len(), rays.len(), obuild.as_secs_f64() * 1e3, n / otime.as_secs_f64() / 1e6, bbuild.as_secs_f64() * 1e3, n / btime.as_secs_f64() / 1e6, same as f64 / rays.len() as f64);
        #[cfg(feature = "embree")]
        {
            let (build, seconds, hits) = embree_closest(&tris, &rays, reps);
            // Embree's watertight test and Moller-Trumbore round differently: compare t to 1e-4
            // relative.
            let close = osum.iter().zip(&hits).filter(|(a, b)| (a.is_infinite() && b.is_infinite()) || (*a - *b).abs() <= 1e-4 * a.abs().max(1e-3)).count();
            print!(" {:.1} ms | {:.2} | {:.4} |", build.as_secs_f64() * 1e3, n / seconds.as_secs_f64() / 1e6, close as f64 / rays.len() as f64);
        }
        println!();
    }
}

/// Build an Embree scene over `tris` (high build quality, with Embree's own build threads) and
/// time `reps` passes of single-ray closest-hit queries. Returns the build time,
/// the query time and the hit distances of the last pass (infinite for a miss).
#[cfg(feature = "embree")]
fn embree_closest(tris: &[Tri], rays: &[(Vec3, Vec3)], reps: usize) -> (Duration, Duration, Vec<f32>) {
    use cgmath::{Vector3 as V3, Vector4 as V4};
    use embree::{Device, Geometry, IntersectContext, Ray, RayHit, Scene, TriangleMesh};
    let device = Device::new();
    let t0 = Instant::now();
    let mut mesh = TriangleMesh::unanimated(&device, tris.len(), 3 * tris.len());
    {
        let mut vertices = mesh.vertex_buffer.map();
        let mut indices = mesh.index_buffer.map();
        for (i, t) in tris.iter().enumerate() {
            for (k, v) in [t.v0, t.v0 + t.e1, t.v0 + t.e2].into_iter().enumerate() {
                vertices[3 * i + k] = V4::new(v.x, v.y, v.z, 0.0);
            }
            let first = 3 * i as u32;
            indices[i] = V3::new(first, first + 1, first + 2);
        }
    }
    let mut geometry = Geometry::Triangle(mesh);
    geometry.commit();
    let mut scene = Scene::new(&device);
    // SAFETY: the handle is the live scene's, before its commit.
    unsafe { embree::sys::rtcSetSceneBuildQuality(scene.handle(), embree::BuildQuality::HIGH) };
    scene.attach_geometry(geometry);
    let committed = scene.commit();
    let build = t0.elapsed();
    let mut context = IntersectContext::incoherent();
    let mut hits = Vec::with_capacity(rays.len());
    let t1 = Instant::now();
    for _ in 0..reps {
        hits.clear();
        for &(o, d) in rays {
            let mut ray_hit = RayHit::new(Ray::new(V3::new(o.x, o.y, o.z), V3::new(d.x, d.y, d.z)));
            committed.intersect(&mut context, &mut ray_hit);
            hits.push(if ray_hit.hit.hit() { ray_hit.ray.tfar } else { f32::INFINITY });
        }
    }
    (build, t1.elapsed(), hits)
}
