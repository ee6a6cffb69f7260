//! The triangle-level types both ray casters and the tracers share: what a triangle belongs
//! to, its shading attributes, a closest hit, and the ray/triangle test. `geometry.rs` builds
//! them into a scene; the casters (`obvhs_caster.rs`, `embree_caster.rs`) answer queries in
//! them. Nothing here depends on another module of the tracer.

use glam::{Vec2, Vec3};

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

impl TriangleAttributes {
    /// The unit normal its winding gives.
    #[inline]
    pub fn face_normal(&self) -> Vec3 {
        let [p0, p1, p2] = self.positions;
        (p1 - p0).cross(p2 - p0).normalize()
    }

    /// The interpolated vertex normal at `hit`, or `face_normal` where the mesh has none.
    #[inline]
    pub fn shading_normal(&self, hit: &Hit, face_normal: Vec3) -> Vec3 {
        match self.normals {
            Some([n0, n1, n2]) => (n0 * (1.0 - hit.b1 - hit.b2) + n1 * hit.b1 + n2 * hit.b2).normalize_or(face_normal),
            None => face_normal,
        }
    }

    /// The texture coordinates at `hit`.
    #[inline]
    pub fn uv(&self, hit: &Hit) -> Vec2 {
        let [t0, t1, t2] = self.uvs;
        t0 * (1.0 - hit.b1 - hit.b2) + t1 * hit.b1 + t2 * hit.b2
    }
}

/// Möller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle Intersection". Returns
/// (t, b1, b2) with t in (t_min, t_max). The obvhs caster's triangle test, and the brute force
/// the tests check both casters against.
#[inline(always)]
#[cfg_attr(all(feature = "embree", not(test)), allow(dead_code))]
pub fn moller_trumbore(v0: Vec3, edge1: Vec3, edge2: Vec3, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
    let p = direction.cross(edge2);
    let det = edge1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = origin - v0;
    let b1 = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&b1) {
        return None;
    }
    let q = s.cross(edge1);
    let b2 = direction.dot(q) * inv_det;
    if b2 < 0.0 || b1 + b2 > 1.0 {
        return None;
    }
    let t = edge2.dot(q) * inv_det;
    (t > t_min && t < t_max).then_some((t, b1, b2))
}

/// A closest-hit result.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into `SceneGeometry::attributes`.
    pub triangle: u32,
    /// Barycentric weights of vertices 1 and 2.
    pub b1: f32,
    pub b2: f32,
}
