//! The scene flattened into world-space triangles behind one BVH, with the per-triangle
//! attributes shading needs. The BVH is obvhs' compressed wide BVH8 (Ylitie et al. 2017),
//! pure Rust; a build with the `embree` feature casts rays with Intel Embree 3 instead
//! (`obvhs_caster.rs`, or `embree_caster.rs`: [`RAY_CASTER`]).

use glam::{Vec2, Vec3};
use glassbake_scene::Scene;

/// The ray caster this build traces with: `obvhs`, or `embree` (the `embree` feature). The
/// two find the same hits up to rounding (each has its own triangle test), so the same
/// inputs give slightly different images: datasets record which one traced them.
pub const RAY_CASTER: &str = if cfg!(feature = "embree") { "embree" } else { "obvhs" };

#[cfg(not(feature = "embree"))]
type Caster = crate::obvhs_caster::ObvhsCaster;
#[cfg(feature = "embree")]
type Caster = crate::embree_caster::EmbreeCaster;

pub use crate::triangle::{Hit, Owner, TriangleAttributes};

pub struct SceneGeometry {
    /// `None` when the scene has no triangles.
    caster: Option<Caster>,
    pub attributes: Vec<TriangleAttributes>,
}

impl SceneGeometry {
    /// Flatten the scene's objects and rectangle lights. `emitter_of` gives the emitter
    /// index of each object triangle (object, triangle index in its mesh) and of each rect
    /// light, as the light sampler numbered them.
    pub fn build(scene: &Scene, emitter_of: &dyn Fn(Owner, usize) -> Option<u32>) -> Self {
        Self::from_triangles(scene_triangles(scene, &|_| true, true, emitter_of))
    }

    /// A BVH over `attributes` (which [`scene_triangles`] makes from a scene).
    pub fn from_triangles(attributes: Vec<TriangleAttributes>) -> Self {
        let caster = (!attributes.is_empty()).then(|| Caster::build(&attributes));
        SceneGeometry { caster, attributes }
    }

    /// [`Self::from_triangles`] for triangles that may have moved since `self` was built:
    /// where none moved (a variable changed a colour), the BVH is kept; with as many
    /// triangles as before, it is refit to where they are now (obvhs; the `embree` build makes
    /// it anew), else built. Traversal is exact either way; a refit tree is as good as a new
    /// one when each object or light moved as a whole.
    pub fn refit_or_build(self, attributes: Vec<TriangleAttributes>) -> Self {
        let same_count = attributes.len() == self.attributes.len();
        let unmoved = same_count
            && attributes
                .iter()
                .zip(&self.attributes)
                .all(|(a, b)| a.positions.iter().zip(&b.positions).all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits)));
        match self.caster {
            Some(caster) if unmoved => SceneGeometry { caster: Some(caster), attributes },
            Some(caster) if same_count => SceneGeometry { caster: Some(caster.refit(&attributes)), attributes },
            _ => Self::from_triangles(attributes),
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.attributes.len()
    }

    /// The closest triangle hit with t in (t_min, t_max).
    pub fn closest_hit(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        self.caster.as_ref()?.closest_hit(origin, direction, t_min, t_max)
    }

    /// Whether any triangle lies on the segment (t_min, t_max): `closest_hit(..).is_some()`,
    /// with a traversal that stops at the first hit it finds instead of looking on for the
    /// nearest.
    pub fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.caster.as_ref().is_some_and(|caster| caster.occluded(origin, direction, t_min, t_max))
    }

    /// One traversal for a shadow segment (t_min, t_max): returns whether anything that
    /// cannot let light through lies on it, and (when nothing does) leaves in `panes` every
    /// hit with a triangle that may pass light through, each once, in an order fixed by the
    /// scene and the ray (not by the thread that asks).
    pub fn shadow_query(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32, panes: &mut Vec<Hit>) -> bool {
        panes.clear();
        match &self.caster {
            Some(caster) => caster.shadow_query(&self.attributes, origin, direction, t_min, t_max, panes),
            None => false,
        }
    }
}

/// The world-space triangles of the scene's objects for which `include_object(object index)`
/// holds, in object and mesh order, then (with `include_lights`) two per rectangle light.
/// Degenerate triangles and ones with out-of-range indices are left out.
pub fn scene_triangles(
    scene: &Scene,
    include_object: &dyn Fn(usize) -> bool,
    include_lights: bool,
    emitter_of: &dyn Fn(Owner, usize) -> Option<u32>,
) -> Vec<TriangleAttributes> {
    let mut attributes = Vec::new();
    for (object_index, object) in scene.objects.iter().enumerate().filter(|&(i, _)| include_object(i)) {
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
            attributes.push(TriangleAttributes { positions, normals, uvs, owner, emitter: emitter_of(owner, triangle_index), may_pass_through });
        }
    }
    for (light_index, light) in scene.rect_lights.iter().enumerate().filter(|_| include_lights) {
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
    attributes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangle::moller_trumbore;
    use glassbake_scene::builtin::builtin;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn uniform_sphere(rng: &mut ChaCha8Rng) -> Vec3 {
        let z = 1.0 - 2.0 * rng.random::<f32>();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * rng.random::<f32>();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Brute force over all triangles, for checking the BVH.
    fn brute_force(geometry: &SceneGeometry, origin: Vec3, direction: Vec3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for (index, triangle) in geometry.attributes.iter().enumerate() {
            let [v0, v1, v2] = triangle.positions;
            if let Some((t, _, _)) = moller_trumbore(v0, v1 - v0, v2 - v0, origin, direction, 0.0, f32::INFINITY) {
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, index as u32));
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
        check_against_brute_force(&geometry, 1);
    }

    #[test]
    fn a_bvh_refit_to_moved_objects_and_lights_agrees_with_brute_force() {
        let base = builtin("cornellbox8").unwrap();
        let (low, high): (Vec<f32>, Vec<f32>) = base.variables.iter().map(|v| (v.min, v.max)).unzip();
        let geometry = SceneGeometry::build(&base.instantiate(&low).unwrap(), &|_, _| None);
        // Every translation at the other end of its range: the glass, an opaque sphere and
        // the light all move, and the refit tree must still find every nearest hit.
        let moved = base.instantiate(&high).unwrap();
        let refit = geometry.refit_or_build(scene_triangles(&moved, &|_| true, true, &|_, _| None));
        assert_eq!(refit.attributes[0].positions, scene_triangles(&moved, &|_| true, true, &|_, _| None)[0].positions);
        check_against_brute_force(&SceneGeometry::build(&moved, &|_, _| None), 2);
        check_against_brute_force(&refit, 2);
        // Nothing moved the second time: the tree is kept as it is.
        let kept = refit.refit_or_build(scene_triangles(&moved, &|_| true, true, &|_, _| None));
        check_against_brute_force(&kept, 3);
    }

    /// Random rays from inside the Cornell box: the BVH's nearest hits and shadow queries
    /// against testing every triangle.
    fn check_against_brute_force(geometry: &SceneGeometry, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..2000 {
            let origin = Vec3::new(rng.random::<f32>() * 1.8 - 0.9, rng.random::<f32>() * 1.8 + 0.1, rng.random::<f32>() * 1.8 - 0.9);
            let direction = uniform_sphere(&mut rng);
            let fast = geometry.closest_hit(origin, direction, 0.0, f32::INFINITY).map(|h| (h.t, h.triangle));
            let slow = brute_force(geometry, origin, direction);
            match (fast, slow) {
                (Some(a), Some(b)) => assert!((a.0 - b.0).abs() < 1e-5, "{a:?} vs {b:?}"),
                (None, None) => {}
                other => panic!("BVH and brute force disagree: {other:?}"),
            }
            // The segment up to a random distance is blocked exactly when the nearest hit lies
            // on it (hits within rounding of its end may go either way).
            let t_max = rng.random::<f32>() * 3.0;
            if slow.is_none_or(|(t, _)| (t - t_max).abs() > 1e-4 * t_max.max(1.0)) {
                assert_eq!(geometry.occluded(origin, direction, 0.0, t_max), slow.is_some_and(|(t, _)| t < t_max), "{origin} {direction} {t_max}");
            }
            // Nothing lies before the closest hit; the closest hit blocks unless it is a pane,
            // and then the shadow query reports it.
            let mut panes = Vec::new();
            // A hit within rounding of the origin may fall either side of the segment's end.
            if slow.is_some_and(|(t, _)| t < 1e-3) {
                continue;
            }
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

    /// Every hit on the segment (0, t_max), by brute force: (t, triangle, b1, b2).
    fn all_hits(geometry: &SceneGeometry, origin: Vec3, direction: Vec3, t_max: f32) -> Vec<(f32, u32, f32, f32)> {
        let mut hits = Vec::new();
        for (index, triangle) in geometry.attributes.iter().enumerate() {
            let [v0, v1, v2] = triangle.positions;
            if let Some((t, b1, b2)) = moller_trumbore(v0, v1 - v0, v2 - v0, origin, direction, 0.0, t_max) {
                hits.push((t, index as u32, b1, b2));
            }
        }
        hits
    }

    #[test]
    fn shadow_queries_report_every_pane_on_the_segment_once() {
        // The bathroom's partition and the glass cube's thin panes are pass-through triangles.
        let mut queries_with_panes = 0;
        for name in ["bathroom", "cornellbox"] {
            let scene = builtin(name).unwrap();
            let geometry = SceneGeometry::build(&scene, &|_, _| None);
            assert!(geometry.attributes.iter().any(|a| a.may_pass_through), "{name} has no pane");
            let lower = geometry.attributes.iter().flat_map(|a| a.positions).fold(Vec3::MAX, Vec3::min);
            let upper = geometry.attributes.iter().flat_map(|a| a.positions).fold(Vec3::MIN, Vec3::max);
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut panes = Vec::new();
            for _ in 0..4000 {
                let origin = lower + (upper - lower) * Vec3::new(rng.random::<f32>(), rng.random::<f32>(), rng.random::<f32>());
                let direction = uniform_sphere(&mut rng);
                let t_max = rng.random::<f32>() * (upper - lower).length();
                let hits = all_hits(&geometry, origin, direction, t_max);
                // Hits within rounding of the segment's ends may go either way.
                if hits.iter().any(|h| h.0 < 1e-3 || h.0 > t_max * (1.0 - 1e-4)) {
                    continue;
                }
                let blocked = hits.iter().any(|h| !geometry.attributes[h.1 as usize].may_pass_through);
                assert_eq!(geometry.shadow_query(origin, direction, 0.0, t_max, &mut panes), blocked, "{name}: {origin} {direction} {t_max}");
                if blocked {
                    continue;
                }
                queries_with_panes += usize::from(!hits.is_empty());
                let mut reported: Vec<u32> = panes.iter().map(|h| h.triangle).collect();
                reported.sort_unstable();
                let mut expected: Vec<u32> = hits.iter().map(|h| h.1).collect();
                expected.sort_unstable();
                assert_eq!(reported, expected, "{name}: {origin} {direction} {t_max}");
                for pane in &panes {
                    let &(t, _, b1, b2) = hits.iter().find(|h| h.1 == pane.triangle).unwrap();
                    assert!((pane.t - t).abs() <= 1e-4 * t.max(1.0) && (pane.b1 - b1).abs() < 1e-4 && (pane.b2 - b2).abs() < 1e-4, "{pane:?} vs {t} {b1} {b2}");
                }
            }
        }
        assert!(queries_with_panes > 100, "only {queries_with_panes} unblocked segments crossed a pane");
    }
}
