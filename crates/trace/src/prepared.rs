//! A scene prepared for tracing, and what every tracer here asks of it: closest hits with
//! their shading attributes, materials with textures applied, shadow segments through smooth
//! thin panes, and the offset that starts a ray off a surface. The camera's path integrator
//! (`integrator.rs`), the light tracer (`light_tracing.rs`) and the glass bounds
//! (`glass_cones.rs`) all build on it; it depends on none of them.

use std::cell::Cell;

use glam::{Vec2, Vec3};
use glassbake_core::Ray;
use glassbake_scene::Scene;

use crate::bsdf::{Bsdf, MaterialModel, SurfaceMaterial};
use crate::estimator::Transport;
use crate::geometry::SceneGeometry;
use crate::lights::LightSampler;
use crate::path_class::PathFilter;
use crate::triangle::{Hit, Owner};

thread_local! {
    /// Rays this thread has cast (closest-hit and shadow queries): the cost with which the
    /// light tracer's budget is weighed against the camera's (`light_tracing::balanced_light_paths`).
    /// Counted rather than timed so that the budget, and so the image, is deterministic.
    static RAYS_CAST: Cell<u64> = const { Cell::new(0) };
}

#[inline]
fn count_ray() {
    RAYS_CAST.with(|count| count.set(count.get() + 1));
}

/// Rays cast by the calling thread so far; differences of two readings on one thread count
/// the rays of the work in between.
pub(crate) fn rays_cast() -> u64 {
    RAYS_CAST.with(Cell::get)
}

/// How a path is traced.
#[derive(Clone, Copy, Debug)]
pub struct PathSettings {
    /// Longest path, counted in segments as Mitsuba does: 1 = emitters seen directly,
    /// 2 = direct lighting, ... Every surface interaction starts a new segment, straight
    /// crossings of smooth thin panes included (Mitsuba's `thindielectric` is a BSDF like
    /// any other); Russian roulette counts them the same way.
    pub max_depth: u32,
    /// Russian roulette applies to paths longer than this many segments.
    pub rr_depth: u32,
    pub material_model: MaterialModel,
    /// Which paths' light is counted: an analysis tool, [`PathFilter::All`] for images.
    pub path_filter: PathFilter,
}

/// A scene ready to trace: geometry, BVH, lights.
pub struct PreparedScene<'a> {
    pub scene: &'a Scene,
    pub geometry: SceneGeometry,
    pub lights: LightSampler,
}

/// What a ray hit, ready for shading.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub position: Vec3,
    pub distance: f32,
    /// Geometric normal, oriented to agree with the shading normal (the mesh's outside).
    pub geometric_normal: Vec3,
    pub shading_normal: Vec3,
    pub uv: Vec2,
    pub owner: Owner,
    pub emitter: Option<u32>,
}

/// Hard cap on path vertices, pane crossings included: a guard against pathological scenes
/// (two mirrors facing each other with Russian roulette off), never reached in practice.
pub const MAX_VERTICES: u32 = 4096;

impl<'a> PreparedScene<'a> {
    /// Ready for the plain transport's light sampling; enough for geometry queries.
    pub fn new(scene: &'a Scene) -> Self {
        Self::for_transport(scene, Transport::Plain)
    }

    /// Ready for `transport`'s light sampling: the caustic transport samples rectangles by
    /// solid angle near them and picks emitters by their contribution (`lights.rs`).
    pub fn for_transport(scene: &'a Scene, transport: Transport) -> Self {
        let caustic = matches!(transport, Transport::Caustic { .. });
        let lights = LightSampler::new(scene, caustic, caustic);
        let geometry = SceneGeometry::build(scene, &|owner, index| lights.emitter_of(owner, index));
        PreparedScene { scene, geometry, lights }
    }

    /// The closest surface along `ray` (no minimum distance).
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        self.intersect_from(ray.origin, ray.direction, 0.0, f32::INFINITY)
    }

    #[inline]
    pub(crate) fn intersect_from(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<SurfaceHit> {
        count_ray();
        let hit = self.geometry.closest_hit(origin, direction, t_min, t_max)?;
        Some(self.surface_hit(&hit))
    }

    #[inline]
    fn surface_hit(&self, hit: &Hit) -> SurfaceHit {
        let a = &self.geometry.attributes[hit.triangle as usize];
        let b0 = 1.0 - hit.b1 - hit.b2;
        let [p0, p1, p2] = a.positions;
        let position = p0 * b0 + p1 * hit.b1 + p2 * hit.b2;
        let mut geometric_normal = a.face_normal();
        let shading_normal = a.shading_normal(hit, geometric_normal);
        if geometric_normal.dot(shading_normal) < 0.0 {
            geometric_normal = -geometric_normal;
        }
        SurfaceHit { position, distance: hit.t, geometric_normal, shading_normal, uv: a.uv(hit), owner: a.owner, emitter: a.emitter }
    }

    /// Whether object `object` is glass ([`Bsdf::is_glass`]) under `model`: its material
    /// has a transmissive dielectric lobe (textures never change that).
    pub fn object_is_glass(&self, object: usize, model: MaterialModel) -> bool {
        self.untextured_bsdf(&self.scene.objects[object], model).is_glass()
    }

    /// The BSDF of an object's material without its textures.
    fn untextured_bsdf(&self, object: &glassbake_scene::Object, model: MaterialModel) -> Bsdf {
        let material = &self.scene.materials[object.material];
        let surface = SurfaceMaterial::new(material.base_color, material.roughness, material.metallic, material.transmission);
        Bsdf::new(&surface, Vec3::Z, model)
    }

    /// Material parameters at a hit, textures applied.
    #[inline]
    pub fn surface_material(&self, material: u32, uv: Vec2) -> SurfaceMaterial {
        let m = &self.scene.materials[material as usize];
        let mut base_color = m.base_color;
        if let Some(t) = m.base_color_texture.and_then(|t| self.scene.textures.get(t)) {
            base_color *= t.sample(uv).truncate();
        }
        let mut roughness = m.roughness;
        if let Some(t) = m.roughness_texture.and_then(|t| self.scene.textures.get(t)) {
            roughness *= t.sample(uv).y;
        }
        let mut specular = m.specular;
        if let Some(t) = m.specular_texture.and_then(|t| self.scene.textures.get(t)) {
            specular *= t.sample(uv).w;
        }
        let mut specular_color = m.specular_color;
        if let Some(t) = m.specular_color_texture.and_then(|t| self.scene.textures.get(t)) {
            specular_color *= t.sample(uv).truncate();
        }
        SurfaceMaterial { base_color, roughness, metallic: m.metallic, specular, specular_color, transmission: m.transmission }
    }

    /// Light transport along a shadow segment: `None` if something opaque blocks it or it
    /// crosses more than `max_crossings` panes, otherwise the product of the smooth thin
    /// panes' transmittances and the product of the probabilities with which BSDF sampling
    /// would have crossed them.
    pub(crate) fn transmittance(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_max: f32,
        max_crossings: u32,
        settings: &PathSettings,
        scratch: &mut Vec<Hit>,
    ) -> Option<(Vec3, f32)> {
        count_ray();
        if t_max <= 0.0 || self.geometry.shadow_query(origin, direction, 0.0, t_max, scratch) {
            return None;
        }
        if scratch.is_empty() {
            return Some((Vec3::ONE, 1.0));
        }
        // Multiply in distance order so the result does not depend on traversal order.
        scratch.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.triangle.cmp(&b.triangle)));
        let mut transmittance = Vec3::ONE;
        let mut probability = 1.0;
        let mut previous_t = f32::NEG_INFINITY;
        let mut crossings = 0u32;
        for hit in scratch.iter() {
            // A ray through a shared edge reports both triangles; the pane is crossed once.
            if hit.t - previous_t < 1e-6 * hit.t.max(1.0) {
                continue;
            }
            previous_t = hit.t;
            crossings += 1;
            if crossings > max_crossings {
                return None;
            }
            let surface = self.surface_hit(hit);
            let Owner::Object { material, .. } = surface.owner else { return None };
            let bsdf = Bsdf::new(&self.surface_material(material, surface.uv), surface.shading_normal, settings.material_model);
            let (t, p) = bsdf.pass_through(-direction)?;
            transmittance *= t;
            probability *= p;
        }
        Some((transmittance, probability))
    }
}

/// Distance by which new rays start off a surface, relative to the scene's magnitude at
/// that point (f32 positions carry about 7 significant digits).
#[inline]
pub(crate) fn ray_epsilon(p: Vec3) -> f32 {
    1e-4 * p.abs().max_element().max(1.0)
}

/// A ray origin just off the surface at `p`, on the side `direction` leaves to.
#[inline]
pub fn offset_origin(p: Vec3, geometric_normal: Vec3, direction: Vec3) -> Vec3 {
    let side = if direction.dot(geometric_normal) >= 0.0 { 1.0 } else { -1.0 };
    p + geometric_normal * (side * ray_epsilon(p))
}
