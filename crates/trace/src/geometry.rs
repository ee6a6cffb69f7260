//! The scene flattened into world-space triangles behind one BVH (obvhs' compressed wide
//! BVH8, Ylitie et al. 2017), with the per-triangle attributes shading needs.

use std::time::Duration;

use glam::{Vec2, Vec3};
use glam_bvh::Vec3A as BvhVec3;
use glassbake_scene::Scene;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as BvhRay, RayHit};
use obvhs::triangle::Triangle as BvhTriangle;
use obvhs::BvhBuildParams;

/// What a triangle belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Owner {
    /// A triangle of scene object `object` with material `material`.
    Object { object: u32, material: u32 },
    /// One of the two triangles of rectangle light `light`. Lights only emit: a ray that
    /// hits one ends there (on its back too), as a black emitter shape would.
    RectLight { light: u32 },
}

/// Everything shading needs about one triangle, in world space.
#[derive(Clone, Debug)]
pub struct TriangleAttributes {
    pub positions: [Vec3; 3],
    /// Per-vertex shading normals; `None` when the mesh has none (flat shading).
    pub normals: Option<[Vec3; 3]>,
    pub uvs: [Vec2; 3],
    pub owner: Owner,
    /// Index into the light sampler's emitter list, if the triangle emits.
    pub emitter: Option<u32>,
    /// The triangle may let shadow rays through (a thin, transmissive pane): occlusion
    /// queries have to look at its material.
    pub may_pass_through: bool,
}

/// The intersection data of one triangle, in BVH order for locality.
#[derive(Clone, Copy, Debug)]
struct HotTriangle {
    v0: Vec3,
    edge1: Vec3,
    edge2: Vec3,
    /// Index into `attributes`.
    index: u32,
}

impl HotTriangle {
    /// Möller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle Intersection". Returns
    /// (t, b1, b2) with t in (t_min, t_max).
    #[inline(always)]
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        let p = direction.cross(self.edge2);
        let det = self.edge1.dot(p);
        if det == 0.0 {
            return None;
        }
        let inv_det = 1.0 / det;
        let s = origin - self.v0;
        let b1 = s.dot(p) * inv_det;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let q = s.cross(self.edge1);
        let b2 = direction.dot(q) * inv_det;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = self.edge2.dot(q) * inv_det;
        (t > t_min && t < t_max).then_some((t, b1, b2))
    }
}

/// A closest-hit result.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into [`SceneGeometry::attributes`].
    pub triangle: u32,
    /// Barycentric weights of vertices 1 and 2.
    pub b1: f32,
    pub b2: f32,
}

pub struct SceneGeometry {
    bvh: Option<CwBvh>,
    hot: Vec<HotTriangle>,
    pub attributes: Vec<TriangleAttributes>,
}

fn to_bvh(v: Vec3) -> BvhVec3 {
    BvhVec3::new(v.x, v.y, v.z)
}

fn bvh_ray(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> BvhRay {
    BvhRay::new(to_bvh(origin), to_bvh(direction), t_min, t_max)
}

impl SceneGeometry {
    /// Flatten the scene's objects and rectangle lights. `emitter_of` gives the emitter
    /// index of each object triangle (object, triangle index in its mesh) and of each rect
    /// light, as the light sampler numbered them.
    pub fn build(scene: &Scene, emitter_of: &dyn Fn(Owner, usize) -> Option<u32>) -> Self {
        let mut attributes = Vec::new();
        for (object_index, object) in scene.objects.iter().enumerate() {
            let mesh = scene.world_mesh(object_index);
            let material = &scene.materials[object.material];
            let may_pass_through = material.transmission.is_some_and(|t| t.thin && t.weight > 0.0);
            let owner = Owner::Object { object: object_index as u32, material: object.material as u32 };
            let has_normals = mesh.normals.len() == mesh.positions.len();
            let has_uvs = mesh.uvs.len() == mesh.positions.len();
            for (triangle_index, indices) in mesh.indices.iter().enumerate() {
                let [a, b, c] = indices.map(|i| i as usize);
                if a.max(b).max(c) >= mesh.positions.len() {
                    continue;
                }
                let positions = [mesh.positions[a], mesh.positions[b], mesh.positions[c]];
                if (positions[1] - positions[0]).cross(positions[2] - positions[0]).length_squared() == 0.0 {
                    continue;
                }
                let normals = has_normals.then(|| [mesh.normals[a], mesh.normals[b], mesh.normals[c]]);
                let uvs = if has_uvs { [mesh.uvs[a], mesh.uvs[b], mesh.uvs[c]] } else { [Vec2::ZERO; 3] };
                attributes.push(TriangleAttributes {
                    positions,
                    normals,
                    uvs,
                    owner,
                    emitter: emitter_of(owner, triangle_index),
                    may_pass_through,
                });
            }
        }
        for (light_index, light) in scene.rect_lights.iter().enumerate() {
            let owner = Owner::RectLight { light: light_index as u32 };
            let mesh = light.to_mesh();
            for indices in &mesh.indices {
                let [a, b, c] = indices.map(|i| i as usize);
                attributes.push(TriangleAttributes {
                    positions: [mesh.positions[a], mesh.positions[b], mesh.positions[c]],
                    normals: None,
                    uvs: [mesh.uvs[a], mesh.uvs[b], mesh.uvs[c]],
                    owner,
                    emitter: emitter_of(owner, 0),
                    may_pass_through: false,
                });
            }
        }

        if attributes.is_empty() {
            return SceneGeometry { bvh: None, hot: Vec::new(), attributes };
        }
        let bvh_triangles: Vec<BvhTriangle> = attributes
            .iter()
            .map(|a| BvhTriangle { v0: to_bvh(a.positions[0]), v1: to_bvh(a.positions[1]), v2: to_bvh(a.positions[2]) })
            .collect();
        let bvh = build_cwbvh_from_tris(&bvh_triangles, BvhBuildParams::medium_build(), &mut Duration::default());
        let hot = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let p = attributes[i as usize].positions;
                HotTriangle { v0: p[0], edge1: p[1] - p[0], edge2: p[2] - p[0], index: i }
            })
            .collect();
        SceneGeometry { bvh: Some(bvh), hot, attributes }
    }

    pub fn triangle_count(&self) -> usize {
        self.attributes.len()
    }

    /// The closest triangle hit with t in (t_min, t_max).
    pub fn closest_hit(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let mut best: Option<(f32, f32, f32, u32)> = None;
        let mut ray_hit = RayHit::none();
        let hot = &self.hot;
        bvh.ray_traverse(bvh_ray(origin, direction, t_min, t_max), &mut ray_hit, |ray, id| {
            let tri = &hot[id];
            match tri.intersect(origin, direction, t_min, ray.tmax) {
                Some((t, b1, b2)) => {
                    // obvhs keeps the smallest t; remember the barycentrics that go with it.
                    if best.is_none_or(|b| t < b.0) {
                        best = Some((t, b1, b2, tri.index));
                    }
                    t
                }
                None => f32::INFINITY,
            }
        });
        best.map(|(t, b1, b2, triangle)| Hit { t, triangle, b1, b2 })
    }

    /// One traversal for a shadow segment (t_min, t_max): returns whether anything that
    /// cannot let light through lies on it, and (when nothing does) leaves in `panes` every
    /// hit with a triangle that may pass light through, in BVH traversal order
    /// (deterministic for a given scene).
    pub fn shadow_query(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32, panes: &mut Vec<Hit>) -> bool {
        panes.clear();
        let Some(bvh) = self.bvh.as_ref() else { return false };
        let hot = &self.hot;
        let attributes = &self.attributes;
        !bvh.ray_traverse_miss(bvh_ray(origin, direction, t_min, t_max), |_, id| {
            let tri = &hot[id];
            let Some((t, b1, b2)) = tri.intersect(origin, direction, t_min, t_max) else { return f32::INFINITY };
            if attributes[tri.index as usize].may_pass_through {
                panes.push(Hit { t, triangle: tri.index, b1, b2 });
                return f32::INFINITY;
            }
            t
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glassbake_scene::builtin::builtin;

    /// Brute force over all triangles, for checking the BVH.
    fn brute_force(geometry: &SceneGeometry, origin: Vec3, direction: Vec3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for tri in &geometry.hot {
            if let Some((t, _, _)) = tri.intersect(origin, direction, 0.0, f32::INFINITY) {
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, tri.index));
                }
            }
        }
        best
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let scene = builtin("cornellbox").unwrap();
        let geometry = SceneGeometry::build(&scene, &|_, _| None);
        assert_eq!(geometry.triangle_count(), scene.triangle_count() + 2 * scene.rect_lights.len());
        let mut rng = crate::rng::Pcg32::new(1, 2);
        for _ in 0..2000 {
            let origin = Vec3::new(rng.next_f32() * 1.8 - 0.9, rng.next_f32() * 1.8 + 0.1, rng.next_f32() * 1.8 - 0.9);
            let direction = crate::sampling::uniform_sphere(rng.next_vec2());
            let fast = geometry.closest_hit(origin, direction, 0.0, f32::INFINITY).map(|h| (h.t, h.triangle));
            let slow = brute_force(&geometry, origin, direction);
            match (fast, slow) {
                (Some(a), Some(b)) => assert!((a.0 - b.0).abs() < 1e-5, "{a:?} vs {b:?}"),
                (None, None) => {}
                other => panic!("BVH and brute force disagree: {other:?}"),
            }
            // Nothing lies before the closest hit; the closest hit blocks unless it is a pane,
            // and then the shadow query reports it.
            let mut panes = Vec::new();
            if let Some((t, triangle)) = slow {
                assert!(!geometry.shadow_query(origin, direction, 0.0, t * 0.999, &mut panes));
                assert!(panes.is_empty());
                let pane = geometry.attributes[triangle as usize].may_pass_through;
                let blocked = geometry.shadow_query(origin, direction, 0.0, t * 1.0001, &mut panes);
                if pane {
                    assert!(blocked || panes.iter().any(|h| h.triangle == triangle));
                } else {
                    assert!(blocked);
                }
            } else {
                assert!(!geometry.shadow_query(origin, direction, 0.0, 1e3, &mut panes) && panes.is_empty());
            }
        }
    }
}
