//! Emitters and their sampling for next-event estimation: rectangle lights and the
//! triangles of emissive-mesh objects, picked in proportion to their power. Rectangles are
//! sampled uniformly in the solid angle they subtend ([`crate::spherical_rect`]) unless the
//! plain estimator asks for area sampling; triangles and non-rectangular parallelograms are
//! sampled uniformly by area.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};
use glassbake_scene::Scene;

use crate::sampling::{luminance, uniform_triangle};
use crate::spherical_rect::SphericalRect;
use crate::triangle::Owner;

/// Rectangles are sampled by solid angle from points closer to their centre than this
/// many times the sum of their edge lengths: there the area density's distance^2 / cos term
/// varies most over the light. Farther away the four `acos` per shadow ray cost more than
/// they save: with the `caustic` estimator at 128 px, 256 spp, 1.5 and 0.75 lowered the
/// desk's variance alike (-18%) but 1.5 cost it +20% time and 0.75 nothing measurable
/// (docs/history/benchmarks-2026-11.md, 2026-11-24).
/// The GPU tracer's kernel takes this value too (`glassbake_trace_gpu`'s `trace_source`).
pub const SOLID_ANGLE_RANGE: f32 = 0.75;

/// Where an emitter's points lie.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// corner + u * edge_u + v * edge_v, u, v in [0, 1].
    Parallelogram {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
    },
    Triangle {
        v0: Vec3,
        edge1: Vec3,
        edge2: Vec3,
    },
}

#[derive(Clone, Copy, Debug)]
pub struct Emitter {
    pub shape: Shape,
    /// Unit normal of the emitting side.
    pub normal: Vec3,
    pub area: f32,
    pub radiance: Vec3,
    pub two_sided: bool,
}

impl Emitter {
    /// Radiance leaving the emitter towards `w` (unit, pointing away from it).
    pub fn emitted(&self, w: Vec3) -> Vec3 {
        if self.two_sided || self.normal.dot(w) > 0.0 {
            self.radiance
        } else {
            Vec3::ZERO
        }
    }

    /// The point at `u` in [0, 1)^2, uniformly distributed by area.
    pub fn point_at(&self, u: Vec2) -> Vec3 {
        match self.shape {
            Shape::Parallelogram { corner, edge_u, edge_v } => corner + u.x * edge_u + u.y * edge_v,
            Shape::Triangle { v0, edge1, edge2 } => {
                let b = uniform_triangle(u);
                v0 + b.x * edge1 + b.y * edge2
            }
        }
    }

    /// Whether the line from `origin` along `direction` may cross the emitter ahead of
    /// `origin`: false only where it certainly does not (the shape tested with a margin of
    /// 0.1% of its edges, and a line nearly in its plane always may), so a caller that
    /// casts a ray only when this holds misses no emitter the ray would hit.
    pub fn may_be_crossed_by(&self, origin: Vec3, direction: Vec3) -> bool {
        match self.crossing(origin, direction) {
            Crossing::InPlane => true,
            Crossing::Behind => false,
            Crossing::Ahead { u, v, .. } => self.holds(u, v, 1e-3),
        }
    }

    /// The point where the line from `origin` along `direction` crosses the emitter ahead of
    /// `origin`, if it does (no margin; a line in its plane never does).
    pub fn crossed_at(&self, origin: Vec3, direction: Vec3) -> Option<Vec3> {
        match self.crossing(origin, direction) {
            Crossing::Ahead { t, u, v } if self.holds(u, v, 0.0) => Some(origin + t * direction),
            _ => None,
        }
    }

    /// Where the line from `origin` along `direction` meets the emitter's plane, in the
    /// coordinates of its two edges (their Gram system).
    fn crossing(&self, origin: Vec3, direction: Vec3) -> Crossing {
        let (corner, a, b) = match self.shape {
            Shape::Parallelogram { corner, edge_u, edge_v } => (corner, edge_u, edge_v),
            Shape::Triangle { v0, edge1, edge2 } => (v0, edge1, edge2),
        };
        let normal = a.cross(b);
        let facing = direction.dot(normal);
        if facing.abs() <= 1e-6 * normal.length() {
            return Crossing::InPlane;
        }
        let t = (corner - origin).dot(normal) / facing;
        if t < 0.0 {
            return Crossing::Behind;
        }
        let q = origin + t * direction - corner;
        let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
        let (qa, qb) = (q.dot(a), q.dot(b));
        let determinant = aa * bb - ab * ab;
        Crossing::Ahead { t, u: (qa * bb - qb * ab) / determinant, v: (qb * aa - qa * ab) / determinant }
    }

    /// Whether edge coordinates (u, v) lie on the shape, grown by `margin` of its edges.
    fn holds(&self, u: f32, v: f32, margin: f32) -> bool {
        let inside = match self.shape {
            Shape::Triangle { .. } => u + v <= 1.0 + margin,
            Shape::Parallelogram { .. } => u <= 1.0 + margin && v <= 1.0 + margin,
        };
        u >= -margin && v >= -margin && inside
    }

    fn power(&self) -> f64 {
        let sides = if self.two_sided { 2.0 } else { 1.0 };
        let p = luminance(self.radiance).max(0.0) as f64 * self.area as f64 * PI as f64 * sides;
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }
}

/// Where a line meets an emitter's plane.
enum Crossing {
    InPlane,
    Behind,
    /// At origin + t x direction, edge coordinates (u, v).
    Ahead {
        t: f32,
        u: f32,
        v: f32,
    },
}

/// A point on an emitter, chosen for a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    pub point: Vec3,
    /// Unit direction from the shading point to `point`.
    pub wi: Vec3,
    pub distance: f32,
    /// Radiance arriving along -wi.
    pub radiance: Vec3,
    /// Solid-angle density at the shading point, selection probability included.
    pub pdf: f32,
}

pub struct LightSampler {
    pub emitters: Vec<Emitter>,
    /// Selection probability of each emitter and the running sum for picking.
    pmf: Vec<f32>,
    cdf: Vec<f64>,
    /// Emitter index of each rect light, and of the first triangle of each object (the
    /// object's triangles follow in mesh order), for [`crate::geometry::SceneGeometry`].
    rect_light_emitter: Vec<Option<u32>>,
    object_first_emitter: Vec<Option<u32>>,
    /// Sample rectangles by solid angle (false: by area, the plain estimator).
    solid_angle_rectangles: bool,
    /// Next-event estimation picks among the emitters (few of them) by their unshadowed
    /// contribution at the shading point rather than by power.
    by_contribution: bool,
}

/// Up to this many emitters, next-event estimation picks one by its contribution at the
/// shading point (see `LightSampler::contributions`); with more, by power alone (a scene's
/// emissive meshes have an emitter per triangle, too many to weigh at every vertex).
const MAX_EMITTERS_BY_CONTRIBUTION: usize = 8;

/// Up to this many emitters, [`LightSampler::ray_may_hit_emitter`] tests each one.
const MAX_EMITTERS_TESTED_FOR_RAYS: usize = 16;

impl LightSampler {
    /// `solid_angle_rectangles`: sample rectangles by solid angle near them;
    /// `pick_by_contribution`: with 2 to [`MAX_EMITTERS_BY_CONTRIBUTION`] emitters, pick the
    /// one to sample by its contribution at the shading point (otherwise by power).
    pub fn new(scene: &Scene, solid_angle_rectangles: bool, pick_by_contribution: bool) -> Self {
        let mut emitters = Vec::new();
        let mut rect_light_emitter = Vec::new();
        for light in &scene.rect_lights {
            let area = light.area();
            if area > 0.0 && light.radiance.max_element() > 0.0 {
                rect_light_emitter.push(Some(emitters.len() as u32));
                emitters.push(Emitter {
                    shape: Shape::Parallelogram { corner: light.corner, edge_u: light.edge_u, edge_v: light.edge_v },
                    normal: light.normal(),
                    area,
                    radiance: light.radiance,
                    two_sided: light.two_sided,
                });
            } else {
                rect_light_emitter.push(None);
            }
        }
        let mut object_first_emitter = vec![None; scene.objects.len()];
        for object_index in scene.emissive_objects() {
            let material = &scene.materials[scene.objects[object_index].material];
            let mesh = scene.world_mesh(object_index);
            object_first_emitter[object_index] = Some(emitters.len() as u32);
            // One emitter per mesh triangle (degenerate ones get zero power), so that
            // triangle k of the object is emitter first + k.
            for indices in &mesh.indices {
                let positions = indices.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
                let edge1 = positions[1] - positions[0];
                let edge2 = positions[2] - positions[0];
                let cross = edge1.cross(edge2);
                let area = 0.5 * cross.length();
                let mut normal = cross.normalize_or_zero();
                // Emit on the side the vertex normals point to (the mesh's outside).
                if mesh.normals.len() == mesh.positions.len() {
                    let vertex_normals: Vec3 = indices.iter().map(|&i| mesh.normals[i as usize]).sum();
                    if vertex_normals.dot(normal) < 0.0 {
                        normal = -normal;
                    }
                }
                emitters.push(Emitter {
                    shape: Shape::Triangle { v0: positions[0], edge1, edge2 },
                    normal,
                    area: if normal == Vec3::ZERO { 0.0 } else { area },
                    radiance: material.emission,
                    two_sided: false,
                });
            }
        }
        let powers: Vec<f64> = emitters.iter().map(Emitter::power).collect();
        let total: f64 = powers.iter().sum();
        let mut cdf = Vec::with_capacity(powers.len());
        let mut running = 0.0;
        for p in &powers {
            running += p;
            cdf.push(running / total);
        }
        let pmf = powers.iter().map(|p| if total > 0.0 { (p / total) as f32 } else { 0.0 }).collect();
        if total <= 0.0 {
            cdf.clear();
        }
        let by_contribution = pick_by_contribution && (2..=MAX_EMITTERS_BY_CONTRIBUTION).contains(&emitters.len());
        LightSampler { emitters, pmf, cdf, rect_light_emitter, object_first_emitter, solid_angle_rectangles, by_contribution }
    }

    /// Whether a ray from `origin` along `direction` may hit an emitter first
    /// ([`Emitter::may_be_crossed_by`]); with more than [`MAX_EMITTERS_TESTED_FOR_RAYS`]
    /// emitters, always (testing them would cost more than the ray).
    pub fn ray_may_hit_emitter(&self, origin: Vec3, direction: Vec3) -> bool {
        self.emitters.len() > MAX_EMITTERS_TESTED_FOR_RAYS || self.emitters.iter().any(|e| e.may_be_crossed_by(origin, direction))
    }

    /// The solid-angle density with which [`Self::sample`] from `from` picks the direction
    /// `w`, whatever lies between: the sum over the emitters that the line crosses ahead of
    /// `from` and that send light back along it. What next-event estimation through smooth
    /// glass (whose sampled direction is refracted, so the light it reaches need not be the
    /// one sampled) weighs its paths by. `None` with more than
    /// [`MAX_EMITTERS_TESTED_FOR_RAYS`] emitters (too many to test).
    pub fn direction_pdf(&self, from: Vec3, w: Vec3) -> Option<f32> {
        if self.emitters.len() > MAX_EMITTERS_TESTED_FOR_RAYS {
            return None;
        }
        let mut pdf = 0.0;
        for (index, e) in self.emitters.iter().enumerate() {
            if e.emitted(-w) == Vec3::ZERO {
                continue;
            }
            if let Some(point) = e.crossed_at(from, w) {
                pdf += self.pdf(index as u32, from, point);
            }
        }
        Some(pdf)
    }

    /// Whether next-event estimation has anything to sample.
    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty()
    }

    /// The emitter index of a triangle owner (see [`crate::geometry::SceneGeometry::build`]).
    pub fn emitter_of(&self, owner: Owner, triangle_index: usize) -> Option<u32> {
        match owner {
            Owner::RectLight { light } => self.rect_light_emitter[light as usize],
            Owner::Object { object, .. } => self.object_first_emitter[object as usize].map(|first| first + triangle_index as u32),
        }
    }

    /// An emitter picked in proportion to its power, and its probability.
    pub fn pick(&self, u_select: f32) -> Option<(usize, f32)> {
        if self.cdf.is_empty() {
            return None;
        }
        let index = self.cdf.partition_point(|&c| c <= u_select as f64).min(self.cdf.len() - 1);
        Some((index, self.pmf[index]))
    }

    /// A point on an emitter for next-event estimation from `from`, and its solid-angle
    /// density (the emitter's selection included).
    pub fn sample(&self, from: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let (index, selection) = if self.by_contribution {
            let weights = self.contributions(from);
            let total: f32 = weights.iter().sum();
            if total <= 0.0 {
                return None;
            }
            // The first emitter whose cumulative weight passes u x total; rounding past the
            // end falls to the last emitter with any weight.
            let target = u_select * total;
            let mut running = 0.0;
            let mut index = None;
            for (i, &w) in weights.iter().enumerate().filter(|(_, &w)| w > 0.0) {
                running += w;
                index = Some(i);
                if target < running {
                    break;
                }
            }
            let index = index?;
            (index, weights[index] / total)
        } else {
            self.pick(u_select)?
        };
        self.sample_emitter(index, selection, from, u)
    }

    /// Each emitter's unshadowed contribution to a point at `from`, roughly: its luminance
    /// times the solid angle it subtends (area x cosine at its centre / distance^2, at most
    /// 2 pi; the cosine at least 0.05 so that no emitter in front gets 0), 0 behind a
    /// one-sided emitter (which sends nothing there). Any positive weights keep the estimate
    /// unbiased; these put the samples where the light is.
    fn contributions(&self, from: Vec3) -> [f32; MAX_EMITTERS_BY_CONTRIBUTION] {
        let mut weights = [0.0f32; MAX_EMITTERS_BY_CONTRIBUTION];
        for (weight, e) in weights.iter_mut().zip(&self.emitters) {
            let centre = match e.shape {
                Shape::Parallelogram { corner, edge_u, edge_v } => corner + 0.5 * (edge_u + edge_v),
                Shape::Triangle { v0, edge1, edge2 } => v0 + (edge1 + edge2) / 3.0,
            };
            let to_point = from - centre;
            let distance2 = to_point.length_squared().max(1e-12);
            let facing = e.normal.dot(to_point);
            if !e.two_sided && facing <= 0.0 {
                continue;
            }
            let cos = (facing.abs() / distance2.sqrt()).max(0.05);
            let solid_angle = (e.area * cos / distance2).min(2.0 * PI);
            *weight = luminance(e.radiance).max(0.0) * solid_angle;
        }
        weights
    }

    /// Probability with which next-event estimation from `from` takes emitter `index`.
    fn selection_probability(&self, index: usize, from: Vec3) -> f32 {
        if self.by_contribution {
            let weights = self.contributions(from);
            let total: f32 = weights.iter().sum();
            if total > 0.0 {
                weights[index] / total
            } else {
                0.0
            }
        } else {
            self.pmf[index]
        }
    }

    fn sample_emitter(&self, index: usize, selection: f32, from: Vec3, u: Vec2) -> Option<LightSample> {
        let emitter = &self.emitters[index];
        if let Some(rect) = self.spherical_rect(emitter, from) {
            let point = rect.sample(u);
            let to_light = point - from;
            let distance = to_light.length();
            if distance <= 0.0 {
                return None;
            }
            let wi = to_light / distance;
            let radiance = emitter.emitted(-wi);
            let pdf = (selection as f64 / rect.solid_angle) as f32;
            if radiance == Vec3::ZERO {
                return None;
            }
            return (pdf.is_finite() && pdf > 0.0).then_some(LightSample { point, wi, distance, radiance, pdf });
        }
        let point = emitter.point_at(u);
        let to_light = point - from;
        let distance2 = to_light.length_squared();
        if distance2 <= 0.0 {
            return None;
        }
        let distance = distance2.sqrt();
        let wi = to_light / distance;
        let radiance = emitter.emitted(-wi);
        let cos_light = emitter.normal.dot(-wi).abs();
        if radiance == Vec3::ZERO || cos_light <= 0.0 {
            return None;
        }
        let pdf = selection * distance2 / (cos_light * emitter.area);
        (pdf.is_finite() && pdf > 0.0).then_some(LightSample { point, wi, distance, radiance, pdf })
    }

    /// The emitter as a spherical rectangle seen from `from`, when it is a rectangle lit
    /// towards `from` and solid-angle sampling is on.
    fn spherical_rect(&self, emitter: &Emitter, from: Vec3) -> Option<SphericalRect> {
        let Shape::Parallelogram { corner, edge_u, edge_v } = emitter.shape else { return None };
        if !self.uses_solid_angle(emitter, from) {
            return None;
        }
        // Seen from its dark side a one-sided light sends nothing: no sample, density 0.
        let facing = emitter.normal.dot(from - corner);
        if !emitter.two_sided && facing <= 0.0 {
            return None;
        }
        SphericalRect::new(corner, edge_u, edge_v, from)
    }

    /// Whether `sample` picks points on `e` by solid angle as seen from `from`: for
    /// rectangles within [`SOLID_ANGLE_RANGE`] of it. Farther away area sampling is already
    /// nearly uniform in solid angle, and four fewer `acos` per shadow ray.
    fn uses_solid_angle(&self, e: &Emitter, from: Vec3) -> bool {
        let Shape::Parallelogram { corner, edge_u, edge_v } = e.shape else { return false };
        if !self.solid_angle_rectangles || !self.is_rectangle(e) {
            return false;
        }
        let reach = SOLID_ANGLE_RANGE * (edge_u.length() + edge_v.length());
        (from - (corner + 0.5 * (edge_u + edge_v))).length_squared() < reach * reach
    }

    /// The solid-angle density with which `sample` from `from` picks `point` on `emitter`.
    pub fn pdf(&self, emitter: u32, from: Vec3, point: Vec3) -> f32 {
        let e = &self.emitters[emitter as usize];
        if self.uses_solid_angle(e, from) {
            return match self.spherical_rect(e, from) {
                Some(rect) => (self.selection_probability(emitter as usize, from) as f64 / rect.solid_angle) as f32,
                None => 0.0,
            };
        }
        let to_light = point - from;
        let distance2 = to_light.length_squared();
        let cos_light = e.normal.dot(to_light).abs() / distance2.sqrt();
        if cos_light <= 0.0 || e.area <= 0.0 {
            return 0.0;
        }
        self.selection_probability(emitter as usize, from) * distance2 / (cos_light * e.area)
    }

    /// Probability that [`Self::sample`] picks emitter `index`, and the cumulative
    /// probability up to and including it (what the GPU tracer's selection searches).
    pub fn selection(&self, index: usize) -> (f32, f64) {
        (self.pmf[index], self.cdf.get(index).copied().unwrap_or(1.0))
    }

    /// Whether a parallelogram emitter is a rectangle (solid-angle sampling needs one).
    pub fn is_rectangle(&self, e: &Emitter) -> bool {
        match e.shape {
            Shape::Parallelogram { edge_u, edge_v, .. } => edge_u.dot(edge_v).abs() <= 1e-4 * edge_u.length() * edge_v.length(),
            Shape::Triangle { .. } => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glassbake_scene::RectLight;

    /// A large dim light high up and a small bright one low down, both facing down (edge_u x
    /// edge_v = X x Z = -Y).
    fn two_lights() -> Scene {
        let mut scene = Scene::empty("two lights");
        let light = |name: &str, corner: Vec3, side: f32, radiance: f32| RectLight {
            name: name.into(),
            corner,
            edge_u: Vec3::X * side,
            edge_v: Vec3::Z * side,
            radiance: Vec3::splat(radiance),
            two_sided: false,
        };
        scene.rect_lights.push(light("high", Vec3::new(-0.5, 2.0, -0.5), 1.0, 2.0));
        scene.rect_lights.push(light("low", Vec3::new(1.0, 0.4, 0.0), 0.2, 20.0));
        scene
    }

    /// `direction_pdf` is a density over directions: it integrates to one when every light
    /// sample succeeds, also where a small near light hides a far one exactly (both picked,
    /// both counted), and is 0 beside the lights and behind them.
    #[test]
    fn the_direction_density_integrates_to_one() {
        let mut scene = Scene::empty("stacked lights");
        let light = |name: &str, height: f32, half: f32| RectLight {
            name: name.into(),
            corner: Vec3::new(-half, height, -half),
            edge_u: Vec3::X * 2.0 * half,
            edge_v: Vec3::Z * 2.0 * half,
            radiance: Vec3::ONE,
            two_sided: false,
        };
        // Seen from the origin both span slopes of -0.25 to 0.25.
        scene.rect_lights.push(light("far", 2.0, 0.5));
        scene.rect_lights.push(light("near", 0.4, 0.1));
        for (solid_angle, by_contribution) in [(false, false), (true, true)] {
            let sampler = LightSampler::new(&scene, solid_angle, by_contribution);
            // Directions through the plane y = 1: d omega = dx dz / (x^2 + 1 + z^2)^(3/2).
            let (grid, half) = (1000, 0.4f32);
            let cell = 2.0 * half / grid as f32;
            let mut integral = 0.0f64;
            for i in 0..grid {
                for j in 0..grid {
                    let (x, z) = (-half + (i as f32 + 0.5) * cell, -half + (j as f32 + 0.5) * cell);
                    let r2 = x * x + 1.0 + z * z;
                    let pdf = sampler.direction_pdf(Vec3::ZERO, Vec3::new(x, 1.0, z) / r2.sqrt()).unwrap();
                    integral += (pdf * cell * cell / (r2 * r2.sqrt())) as f64;
                }
            }
            assert!((integral - 1.0).abs() < 0.01, "solid angle {solid_angle}, by contribution {by_contribution}: integral {integral}");
            assert_eq!(sampler.direction_pdf(Vec3::ZERO, Vec3::new(0.3, 1.0, 0.0).normalize()), Some(0.0), "beside the lights");
            assert_eq!(sampler.direction_pdf(Vec3::ZERO, Vec3::NEG_Y), Some(0.0), "below");
            assert_eq!(sampler.direction_pdf(Vec3::Y * 3.0, Vec3::NEG_Y), Some(0.0), "behind the lights, one-sided");
        }
    }

    /// Which of `two_lights`' emitters a sampled point lies on (their heights differ).
    fn emitter_at(point: Vec3) -> u32 {
        if (point.y - 2.0).abs() < 1e-4 {
            0
        } else {
            assert!((point.y - 0.4).abs() < 1e-4, "{point}");
            1
        }
    }

    /// Picking by contribution: the selection probabilities sum to one, the pick follows them
    /// over u_select, every sample's density is what `pdf` says for its point (MIS needs
    /// both to agree), and near the small light it is picked far more often than its share
    /// of the power.
    #[test]
    fn emitters_picked_by_contribution_agree_with_their_density() {
        let scene = two_lights();
        let sampler = LightSampler::new(&scene, true, true);
        assert!(sampler.by_contribution);
        let by_power = LightSampler::new(&scene, true, false);
        assert!(!by_power.by_contribution);
        let mut state = 0x9e37_79b9u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        for _ in 0..200 {
            let from = Vec3::new(next() * 4.0 - 2.0, next() * 0.3, next() * 4.0 - 2.0);
            let probabilities = [0, 1].map(|i| sampler.selection_probability(i, from));
            assert!((probabilities.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{probabilities:?}");
            let n = 4000;
            let low_picked =
                (0..n).filter(|k| sampler.sample(from, (*k as f32 + 0.5) / n as f32, Vec2::splat(0.5)).is_some_and(|s| emitter_at(s.point) == 1)).count();
            assert!((low_picked as f32 / n as f32 - probabilities[1]).abs() < 1e-3, "{low_picked} of {n} vs {}", probabilities[1]);
            for s in [&sampler, &by_power] {
                let sample = s.sample(from, next(), Vec2::new(next(), next())).expect("both lights face the point");
                let pdf = s.pdf(emitter_at(sample.point), from, sample.point);
                assert!((pdf / sample.pdf - 1.0).abs() < 1e-4, "{pdf} vs {}", sample.pdf);
            }
        }
        let under_the_low_light = Vec3::new(1.1, 0.0, 0.1);
        let power_share = by_power.selection_probability(1, under_the_low_light);
        let picked = sampler.selection_probability(1, under_the_low_light);
        assert!(picked > 2.0 * power_share, "{picked} vs {power_share}");
        // Above both lights' planes (one-sided, facing down) nothing is picked or sampled.
        let above = Vec3::new(0.0, 3.0, 0.0);
        assert_eq!(sampler.selection_probability(0, above) + sampler.selection_probability(1, above), 0.0);
        assert!(sampler.sample(above, 0.3, Vec2::splat(0.5)).is_none());
    }

    /// Möller-Trumbore against one triangle: the distance along the ray, if it hits.
    fn triangle_hit(origin: Vec3, direction: Vec3, v0: Vec3, e1: Vec3, e2: Vec3) -> Option<f32> {
        let p = direction.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let s = origin - v0;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = direction.dot(q) / det;
        let t = e2.dot(q) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some(t)
    }

    /// The pre-test before a ray towards emitters never says no where the ray hits one (an
    /// independent ray/triangle test), and says no to most rays that pass clearly beside.
    #[test]
    fn emitters_are_never_missed_by_the_ray_pre_test() {
        let parallelogram = Emitter {
            shape: Shape::Parallelogram { corner: Vec3::new(-0.4, 2.0, -0.3), edge_u: Vec3::new(0.8, 0.1, 0.0), edge_v: Vec3::new(0.2, 0.0, 0.6) },
            normal: Vec3::NEG_Y,
            area: 0.5,
            radiance: Vec3::ONE,
            two_sided: false,
        };
        let triangle = Emitter {
            shape: Shape::Triangle { v0: Vec3::new(0.5, 1.0, 0.2), edge1: Vec3::new(-0.3, 0.4, 0.1), edge2: Vec3::new(0.2, 0.1, -0.5) },
            normal: Vec3::Y,
            area: 0.1,
            radiance: Vec3::ONE,
            two_sided: false,
        };
        let mut rng = crate::rng::Pcg32::for_pixel(3, 7);
        for emitter in [parallelogram, triangle] {
            let (corner, a, b) = match emitter.shape {
                Shape::Parallelogram { corner, edge_u, edge_v } => (corner, edge_u, edge_v),
                Shape::Triangle { v0, edge1, edge2 } => (v0, edge1, edge2),
            };
            let hits = |origin: Vec3, direction: Vec3| match emitter.shape {
                Shape::Parallelogram { .. } => {
                    triangle_hit(origin, direction, corner, a, b).or_else(|| triangle_hit(origin, direction, corner + a + b, -a, -b))
                }
                Shape::Triangle { .. } => triangle_hit(origin, direction, corner, a, b),
            };
            let (mut hit, mut clear_misses, mut refused) = (0, 0, 0);
            for _ in 0..20_000 {
                let origin = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 6.0;
                // Aim at a point of the shape's plane spread well past its edges: the ray
                // crosses the plane there, at edge coordinates (s, t).
                let (s, t) = (rng.next_f32() * 1.6 - 0.3, rng.next_f32() * 1.6 - 0.3);
                let target = corner + a * s + b * t;
                let direction = (target - origin).normalize();
                let may = emitter.may_be_crossed_by(origin, direction);
                if hits(origin, direction).is_some() {
                    hit += 1;
                    assert!(may, "a ray from {origin} along {direction} hits the emitter but the pre-test said no");
                }
                let outside = match emitter.shape {
                    Shape::Parallelogram { .. } => s.min(t) < -0.01 || s.max(t) > 1.01,
                    Shape::Triangle { .. } => s.min(t) < -0.01 || s + t > 1.01,
                };
                if outside {
                    clear_misses += 1;
                    refused += usize::from(!may);
                }
                // A ray pointing away from the shape cannot reach it.
                assert!(!emitter.may_be_crossed_by(target + (target - origin), target - origin) || (target - origin).length() < 1e-3);
            }
            assert!(hit > 2_000 && clear_misses > 2_000, "{hit} hits, {clear_misses} clear misses");
            assert_eq!(refused, clear_misses, "every ray that passes clearly beside is refused");
        }
    }
}
