//! BVHs as the flat arrays of vec4s that WGSL compute shaders traverse (`shaders/bvh.wgsl`),
//! shared by the GPU path tracer and the GPU through pass. Several BVHs may share one pair of
//! arrays, each traversed from its own root: the through pass keeps the opaque scene and every
//! transparent object apart that way. The other WGSL both kernels share lives here too:
//! `shaders/optics.wgsl` and `shaders/common.wgsl`.

use glam::Vec3;
use glam_bvh::Vec3A as BvhVec3;
use glassbake_core::{Error, Result};
use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::PlocBuilder;
use obvhs::triangle::Triangle as BvhTriangle;
use obvhs::BvhBuildParams;

/// obvhs' `build_bvh2_from_tris` with its `medium_build` parameters, step by step: the same
/// tree, without the build timer it keeps (a clock a browser's wasm has no std access to).
fn medium_build(triangles: &[BvhTriangle]) -> Bvh2 {
    let config = BvhBuildParams::medium_build();
    let indices = (0..triangles.len() as u32).collect();
    let mut bvh = PlocBuilder::with_capacity(triangles.len()).build(
        config.ploc_search_distance,
        triangles,
        indices,
        config.sort_precision,
        config.search_depth_threshold,
    );
    let mut reinsertion = ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh, config.reinsertion_batch_ratio, None);
    collapse(&mut bvh, config.max_prims_per_leaf.clamp(1, 255), config.collapse_traversal_cost);
    reinsertion.run(&mut bvh, config.reinsertion_batch_ratio * config.post_collapse_reinsertion_batch_ratio_multiplier, None);
    bvh
}

/// Deepest BVH the shader's traversal stack holds (its `BVH_STACK_SIZE`).
pub const MAX_BVH_DEPTH: usize = 64;
/// A node: (min, first child or first triangle), (max, triangle count; 0 = inner node).
pub const NODE_VEC4S: usize = 2;
/// A triangle in leaf order: (v0, its `attribute`), (edge1, its `flags`), (edge2, 0).
pub const TRIANGLE_VEC4S: usize = 3;
/// The root of a BVH without triangles: traversal finds nothing.
pub const EMPTY_ROOT: u32 = u32::MAX;

/// One triangle as a BVH holds it: its corners, the index of its attributes (which the shader
/// reads on a hit), and flags a traversal may filter on.
#[derive(Clone, Copy, Debug)]
pub struct GpuTriangle {
    pub positions: [Vec3; 3],
    pub attribute: u32,
    pub flags: u32,
}

/// The node and triangle arrays of one or more BVHs.
#[derive(Clone, Debug, Default)]
pub struct GpuBvhs {
    pub nodes: Vec<[f32; 4]>,
    pub triangles: Vec<[f32; 4]>,
    /// Deepest leaf of any BVH (a root has depth 0).
    pub depth: usize,
}

fn bits(x: u32) -> f32 {
    f32::from_bits(x)
}

impl GpuBvhs {
    /// Build a BVH over `triangles` after those already held and return its root node, or
    /// [`EMPTY_ROOT`] for no triangles. Fails, naming `name` (the scene or object), when the BVH is deeper than the
    /// shader's traversal stack.
    pub fn push(&mut self, triangles: &[GpuTriangle], name: &str) -> Result<u32> {
        if triangles.is_empty() {
            return Ok(EMPTY_ROOT);
        }
        let to_bvh = |v: Vec3| BvhVec3::new(v.x, v.y, v.z);
        let bvh_triangles: Vec<BvhTriangle> =
            triangles.iter().map(|t| BvhTriangle { v0: to_bvh(t.positions[0]), v1: to_bvh(t.positions[1]), v2: to_bvh(t.positions[2]) }).collect();
        let bvh = medium_build(&bvh_triangles);
        let depth = depth(&bvh.nodes);
        if depth >= MAX_BVH_DEPTH {
            return Err(Error::bad_input(name, "geometry", format!("its BVH is {depth} levels deep; the GPU traversal stack holds {MAX_BVH_DEPTH}")));
        }
        self.depth = self.depth.max(depth);
        let node_base = (self.nodes.len() / NODE_VEC4S) as u32;
        let triangle_base = (self.triangles.len() / TRIANGLE_VEC4S) as u32;
        self.nodes.reserve(bvh.nodes.len() * NODE_VEC4S);
        for node in &bvh.nodes {
            let (lo, hi) = (node.aabb.min, node.aabb.max);
            let first = node.first_index + if node.prim_count == 0 { node_base } else { triangle_base };
            self.nodes.push([lo.x, lo.y, lo.z, bits(first)]);
            self.nodes.push([hi.x, hi.y, hi.z, bits(node.prim_count)]);
        }
        self.triangles.reserve(bvh.primitive_indices.len() * TRIANGLE_VEC4S);
        for &index in &bvh.primitive_indices {
            let t = &triangles[index as usize];
            let [p0, p1, p2] = t.positions;
            self.triangles.push([p0.x, p0.y, p0.z, bits(t.attribute)]);
            let e1 = p1 - p0;
            self.triangles.push([e1.x, e1.y, e1.z, bits(t.flags)]);
            let e2 = p2 - p0;
            self.triangles.push([e2.x, e2.y, e2.z, 0.0]);
        }
        Ok(node_base)
    }

    /// Refit the BVHs below `roots` to triangles that moved: each triangle is given its new
    /// corners by `corners(its attribute)`, each leaf's box becomes its triangles' bounds and
    /// each inner node's the union of its children's. The tree is kept, so traversal stays
    /// exact whatever moved; it is as tight as a rebuild when a BVH's triangles moved
    /// together (a translated object), looser when its parts moved apart.
    pub fn refit(&mut self, roots: &[u32], corners: &dyn Fn(u32) -> [Vec3; 3]) {
        for &root in roots.iter().filter(|&&r| r != EMPTY_ROOT) {
            // Post-order: a node's box is written after both of its children's.
            let mut stack = vec![(root as usize, false)];
            while let Some((node, children_done)) = stack.pop() {
                let (first, count) = (self.nodes[NODE_VEC4S * node][3].to_bits() as usize, self.nodes[NODE_VEC4S * node + 1][3].to_bits() as usize);
                let (lo, hi) = if count > 0 {
                    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                    for slot in first..first + count {
                        let t = &mut self.triangles[TRIANGLE_VEC4S * slot..TRIANGLE_VEC4S * (slot + 1)];
                        let [p0, p1, p2] = corners(t[0][3].to_bits());
                        let (e1, e2) = (p1 - p0, p2 - p0);
                        t[0][..3].copy_from_slice(&p0.to_array());
                        t[1][..3].copy_from_slice(&e1.to_array());
                        t[2][..3].copy_from_slice(&e2.to_array());
                        lo = lo.min(p0.min(p1).min(p2));
                        hi = hi.max(p0.max(p1).max(p2));
                    }
                    (lo, hi)
                } else if !children_done {
                    stack.push((node, true));
                    stack.push((first, false));
                    stack.push((first + 1, false));
                    continue;
                } else {
                    let corner = |n: usize, side: usize| Vec3::from_slice(&self.nodes[NODE_VEC4S * n + side][..3]);
                    (corner(first, 0).min(corner(first + 1, 0)), corner(first, 1).max(corner(first + 1, 1)))
                };
                self.nodes[NODE_VEC4S * node][..3].copy_from_slice(&lo.to_array());
                self.nodes[NODE_VEC4S * node + 1][..3].copy_from_slice(&hi.to_array());
            }
        }
    }

    /// The WGSL constants `shaders/bvh.wgsl` reads, then its source. The including shader
    /// declares the storage arrays `nodes` and `triangles` it traverses. (The other WGSL the
    /// GPU kernels share: [`OPTICS_WGSL`], [`COMMON_WGSL`].)
    pub fn wgsl() -> String {
        let constants = [
            ("BVH_NODE_VEC4S", NODE_VEC4S as u64),
            ("BVH_TRIANGLE_VEC4S", TRIANGLE_VEC4S as u64),
            ("BVH_STACK_SIZE", MAX_BVH_DEPTH as u64),
            ("BVH_EMPTY_ROOT", EMPTY_ROOT as u64),
        ];
        let mut source: String = constants.iter().map(|(name, value)| format!("const {name}: u32 = {value}u;\n")).collect();
        source.push_str(include_str!("../shaders/bvh.wgsl"));
        source
    }
}

/// Light at a smooth dielectric interface (`optics.rs` in WGSL): Fresnel, thin slab, mirror
/// reflection, Snell's refraction.
pub const OPTICS_WGSL: &str = include_str!("../shaders/optics.wgsl");

/// pcg4d and texture sampling; the including shader declares `materials`, `texels` and
/// `params.texture_table`.
pub const COMMON_WGSL: &str = include_str!("../shaders/common.wgsl");

/// Depth of the deepest leaf below node 0.
fn depth(nodes: &[obvhs::bvh2::node::Bvh2Node]) -> usize {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 0usize)];
    while let Some((node, d)) = stack.pop() {
        deepest = deepest.max(d);
        let n = &nodes[node];
        if n.prim_count == 0 {
            stack.push((n.first_index as usize, d + 1));
            stack.push((n.first_index as usize + 1, d + 1));
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(count: usize, offset: Vec3) -> Vec<GpuTriangle> {
        (0..count)
            .map(|i| {
                let p = offset + Vec3::new(i as f32, (i % 3) as f32, 0.0);
                GpuTriangle { positions: [p, p + Vec3::X * 0.5, p + Vec3::Y * 0.5], attribute: i as u32, flags: (i % 2) as u32 }
            })
            .collect()
    }

    /// Walk every BVH from its root: each leaf's triangles lie inside every box on the way
    /// down, and each triangle of each BVH is in exactly one of its leaves.
    #[test]
    fn every_triangle_is_in_exactly_one_leaf_of_its_own_bvh_and_inside_its_boxes() {
        let mut bvhs = GpuBvhs::default();
        let sets = [grid(40, Vec3::ZERO), grid(7, Vec3::Z * 10.0), Vec::new(), grid(1, -Vec3::Z)];
        let roots: Vec<u32> = sets.iter().map(|s| bvhs.push(s, "test").unwrap()).collect();
        assert_eq!(roots[2], EMPTY_ROOT);
        assert_eq!(roots[0], 0);
        check_leaves_and_boxes(&bvhs, &sets, &roots);
        assert!(bvhs.depth > 0 && bvhs.depth < MAX_BVH_DEPTH);
    }

    /// Every triangle of `sets[i]` (attributes numbered within its set) lies in exactly one
    /// leaf below `roots[i]`, with the corners `sets[i]` gives it, inside every box on the way.
    fn check_leaves_and_boxes(bvhs: &GpuBvhs, sets: &[Vec<GpuTriangle>], roots: &[u32]) {
        for (set, &root) in sets.iter().zip(roots).filter(|(_, &r)| r != EMPTY_ROOT) {
            let mut seen = vec![0u32; set.len()];
            let mut stack = vec![(root as usize, Vec::<([f32; 4], [f32; 4])>::new())];
            while let Some((node, mut boxes)) = stack.pop() {
                let (lo, hi) = (bvhs.nodes[NODE_VEC4S * node], bvhs.nodes[NODE_VEC4S * node + 1]);
                boxes.push((lo, hi));
                let (first, count) = (lo[3].to_bits() as usize, hi[3].to_bits() as usize);
                if count == 0 {
                    stack.push((first, boxes.clone()));
                    stack.push((first + 1, boxes));
                    continue;
                }
                for k in first..first + count {
                    let t = &bvhs.triangles[TRIANGLE_VEC4S * k..TRIANGLE_VEC4S * (k + 1)];
                    let v0 = Vec3::new(t[0][0], t[0][1], t[0][2]);
                    let corners = [v0, v0 + Vec3::new(t[1][0], t[1][1], t[1][2]), v0 + Vec3::new(t[2][0], t[2][1], t[2][2])];
                    for (lo, hi) in &boxes {
                        for c in corners {
                            for axis in 0..3 {
                                assert!(c[axis] >= lo[axis] - 1e-5 && c[axis] <= hi[axis] + 1e-5, "triangle {k} outside a box");
                            }
                        }
                    }
                    let attribute = t[0][3].to_bits() as usize;
                    assert_eq!(t[1][3].to_bits(), set[attribute].flags, "the flags travel with the triangle");
                    assert_eq!(corners[0], set[attribute].positions[0]);
                    seen[attribute] += 1;
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "a triangle is missing from its BVH's leaves or in two of them");
        }
    }

    #[test]
    fn refitting_unmoved_triangles_changes_no_bit_of_the_build() {
        let sets = [grid(40, Vec3::ZERO), grid(9, Vec3::Z * 10.0)];
        let mut bvhs = GpuBvhs::default();
        let roots: Vec<u32> = sets.iter().map(|s| bvhs.push(s, "test").unwrap()).collect();
        let built = bvhs.clone();
        // Attributes are numbered within each set here; the two sets' ranges overlap, so the
        // lookup goes by the root the triangle was found under.
        for (set, &root) in sets.iter().zip(&roots) {
            bvhs.refit(&[root], &|attribute| set[attribute as usize].positions);
        }
        assert_eq!(bvhs.nodes.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>(), built.nodes.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>());
        assert_eq!(
            bvhs.triangles.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>(),
            built.triangles.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_refit_bounds_moved_triangles_as_tightly_as_a_rebuild() {
        let before = [grid(40, Vec3::ZERO), grid(9, Vec3::Z * 10.0)];
        let mut bvhs = GpuBvhs::default();
        let roots: Vec<u32> = before.iter().map(|s| bvhs.push(s, "test").unwrap()).collect();
        // The first set moves as a whole; the second is pulled apart, one triangle far off.
        let mut after = [grid(40, Vec3::new(3.0, -2.0, 0.5)), grid(9, Vec3::Z * 10.0)];
        after[1][4].positions = after[1][4].positions.map(|p| p + Vec3::new(0.0, 50.0, -7.0));
        for (set, &root) in after.iter().zip(&roots) {
            bvhs.refit(&[root], &|attribute| set[attribute as usize].positions);
        }
        check_leaves_and_boxes(&bvhs, &after, &roots);
        // Each root's box is the bounds of its set's corners, exactly.
        for (set, &root) in after.iter().zip(&roots) {
            let lo = set.iter().flat_map(|t| t.positions).fold(Vec3::INFINITY, Vec3::min);
            let hi = set.iter().flat_map(|t| t.positions).fold(Vec3::NEG_INFINITY, Vec3::max);
            let node = NODE_VEC4S * root as usize;
            assert_eq!(Vec3::from_slice(&bvhs.nodes[node][..3]), lo);
            assert_eq!(Vec3::from_slice(&bvhs.nodes[node + 1][..3]), hi);
        }
        // A translated set keeps its tree, so its refit equals its rebuild's boxes moved.
        let mut moved = GpuBvhs::default();
        moved.push(&after[0], "test").unwrap();
        let first_bvh_nodes = moved.nodes.len();
        for (refit, rebuilt) in bvhs.nodes[..first_bvh_nodes].iter().zip(&moved.nodes) {
            for axis in 0..3 {
                assert!((refit[axis] - rebuilt[axis]).abs() < 1e-5, "{refit:?} against {rebuilt:?}");
            }
        }
    }

    #[test]
    fn the_medium_build_is_obvhs_own_tree() {
        let to_bvh = |v: Vec3| BvhVec3::new(v.x, v.y, v.z);
        let triangles: Vec<BvhTriangle> = grid(40, Vec3::ZERO)
            .iter()
            .chain(&grid(9, Vec3::new(0.3, 2.0, 10.0)))
            .map(|t| BvhTriangle { v0: to_bvh(t.positions[0]), v1: to_bvh(t.positions[1]), v2: to_bvh(t.positions[2]) })
            .collect();
        let ours = medium_build(&triangles);
        let theirs = obvhs::bvh2::builder::build_bvh2_from_tris(&triangles, BvhBuildParams::medium_build(), &mut std::time::Duration::default());
        assert_eq!(ours.primitive_indices, theirs.primitive_indices);
        assert_eq!(ours.nodes.len(), theirs.nodes.len());
        for (a, b) in ours.nodes.iter().zip(&theirs.nodes) {
            assert_eq!((a.aabb.min, a.aabb.max, a.first_index, a.prim_count), (b.aabb.min, b.aabb.max, b.first_index, b.prim_count));
        }
    }
}
