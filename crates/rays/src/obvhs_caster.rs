//! Rays cast by obvhs' compressed wide BVH8 (Ylitie et al. 2017), pure Rust: the default ray
//! caster behind `geometry::SceneGeometry` (a build with the `embree` feature uses
//! `embree_caster.rs` instead).

use glam::Vec3;
use glam_bvh::Vec3A as BvhVec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ploc::PlocBuilder;
use obvhs::ray::{Ray as BvhRay, RayHit};
use obvhs::triangle::Triangle as BvhTriangle;
use obvhs::BvhBuildParams;

use crate::triangle::{moller_trumbore, Hit, TriangleAttributes};

fn to_bvh(v: Vec3) -> BvhVec3 {
    BvhVec3::new(v.x, v.y, v.z)
}

fn bvh_ray(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> BvhRay {
    BvhRay::new(to_bvh(origin), to_bvh(direction), t_min, t_max)
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
    #[inline(always)]
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        moller_trumbore(self.v0, self.edge1, self.edge2, origin, direction, t_min, t_max)
    }
}

/// obvhs' CWBVH over the triangles, and their intersection data in BVH order.
pub(crate) struct ObvhsCaster {
    bvh: CwBvh,
    hot: Vec<HotTriangle>,
    /// The binary BVH the CWBVH was collapsed from, kept for [`Self::refit`].
    binary: Bvh2,
}

/// The build: obvhs' `medium_build`, which "tries to be around the same build time as embree
/// but with faster traversal".
const BUILD: BvhBuildParams = BvhBuildParams::medium_build();

fn bvh_triangles(attributes: &[TriangleAttributes]) -> Vec<BvhTriangle> {
    attributes.iter().map(|a| BvhTriangle { v0: to_bvh(a.positions[0]), v1: to_bvh(a.positions[1]), v2: to_bvh(a.positions[2]) }).collect()
}

impl ObvhsCaster {
    /// The steps of obvhs' `build_cwbvh_from_tris` without spatial splits (which
    /// `medium_build` does not make), keeping the binary BVH between them.
    pub(crate) fn build(attributes: &[TriangleAttributes]) -> Self {
        let triangles = bvh_triangles(attributes);
        let indices = (0..triangles.len() as u32).collect();
        let mut binary = PlocBuilder::with_capacity(triangles.len()).build(
            BUILD.ploc_search_distance,
            &triangles,
            indices,
            BUILD.sort_precision,
            BUILD.search_depth_threshold,
        );
        ReinsertionOptimizer::default().run(&mut binary, BUILD.reinsertion_batch_ratio, None);
        Self::collapse(binary, attributes)
    }

    /// The same tree over `attributes`' triangles where they are now (as many as at the
    /// build): leaf boxes from the triangles, inner boxes from their children, then collapsed
    /// to a CWBVH again. Traversal stays exact whatever moved; the tree is as good as a
    /// rebuild's when each part moved as a whole.
    pub(crate) fn refit(self, attributes: &[TriangleAttributes]) -> Self {
        assert_eq!(attributes.len(), self.hot.len(), "a refit keeps the triangle count");
        let triangles = bvh_triangles(attributes);
        let mut binary = self.binary;
        for node in binary.nodes.iter_mut().filter(|n| n.is_leaf()) {
            let first = node.first_index as usize;
            let prims = &binary.primitive_indices[first..first + node.prim_count as usize];
            let aabb = prims.iter().fold(Aabb::empty(), |aabb, &p| aabb.union(&triangles[p as usize].aabb()));
            node.set_aabb(aabb);
        }
        binary.refit_all();
        Self::collapse(binary, attributes)
    }

    fn collapse(binary: Bvh2, attributes: &[TriangleAttributes]) -> Self {
        let bvh = bvh2_to_cwbvh(&binary, BUILD.max_prims_per_leaf.clamp(1, 3), true, false);
        let hot = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let p = attributes[i as usize].positions;
                HotTriangle { v0: p[0], edge1: p[1] - p[0], edge2: p[2] - p[0], index: i }
            })
            .collect();
        ObvhsCaster { bvh, hot, binary }
    }

    pub(crate) fn closest_hit(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best: Option<(f32, f32, f32, u32)> = None;
        let mut ray_hit = RayHit::none();
        let hot = &self.hot;
        self.bvh.ray_traverse(bvh_ray(origin, direction, t_min, t_max), &mut ray_hit, |ray, id| {
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

    pub(crate) fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        let hot = &self.hot;
        !self.bvh.ray_traverse_miss(bvh_ray(origin, direction, t_min, t_max), |_, id| {
            hot[id].intersect(origin, direction, t_min, t_max).map_or(f32::INFINITY, |(t, _, _)| t)
        })
    }

    /// Panes come in BVH traversal order, each once (`medium_build` does not split triangles, so
    /// each is in one leaf).
    pub(crate) fn shadow_query(&self, attributes: &[TriangleAttributes], origin: Vec3, direction: Vec3, t_min: f32, t_max: f32, panes: &mut Vec<Hit>) -> bool {
        let hot = &self.hot;
        !self.bvh.ray_traverse_miss(bvh_ray(origin, direction, t_min, t_max), |_, id| {
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
