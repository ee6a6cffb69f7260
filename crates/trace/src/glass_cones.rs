//! Directions towards the scene's glass: the cones that bounding spheres of the glass
//! objects subtend from a point, sampled over their union (overlaps counted in the
//! density). The light tracer sends its light paths along them.
//!
//! (Tried and not kept, docs/benchmarks.md: mixing these cones into the path tracer's
//! direction sampling where the camera's view has bent, to find the caustics it sees in or
//! through glass; at 128 px, 256 spp it lowered efficiency on every scene.)

use std::f32::consts::TAU;

use glam::{Vec2, Vec3};

use crate::bsdf::MaterialModel;
use crate::prepared::PreparedScene;

/// Most cones a point chooses among (they live on the stack); a scene with more glass
/// objects gets one sphere around all of them.
pub(crate) const MAX_CONES: usize = 64;

/// A sphere around one glass object.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoundingSphere {
    pub center: Vec3,
    pub radius: f32,
}

/// A cone of directions from a point towards a bounding sphere.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cone {
    pub axis: Vec3,
    /// Cosine of the half angle; -1 for a point inside the sphere (every direction).
    pub cos_max: f32,
    pub solid_angle: f32,
}

impl Cone {
    pub fn towards(from: Vec3, sphere: &BoundingSphere) -> Cone {
        let to_center = sphere.center - from;
        let distance = to_center.length();
        // Slightly enlarged so that a point on the object's surface is always inside.
        let radius = sphere.radius * 1.001 + 1e-5;
        if distance <= radius {
            return Cone { axis: Vec3::Z, cos_max: -1.0, solid_angle: 2.0 * TAU };
        }
        let sin_max = radius / distance;
        let cos_max = (1.0 - sin_max * sin_max).max(0.0).sqrt();
        Cone { axis: to_center / distance, cos_max, solid_angle: TAU * (1.0 - cos_max) }
    }

    pub fn contains(&self, direction: Vec3) -> bool {
        self.cos_max <= -1.0 || direction.dot(self.axis) >= self.cos_max
    }

    /// A direction uniformly within the cone.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let cos = 1.0 - u.x * (1.0 - self.cos_max);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = TAU * u.y;
        let frame = crate::sampling::Frame::from_normal(self.axis);
        frame.to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos)).normalize()
    }
}

/// Bounding spheres of a scene's glass objects (materials with a transmissive dielectric
/// lobe, `Bsdf::is_glass`).
#[derive(Clone, Debug, Default)]
pub struct GlassBounds {
    pub(crate) spheres: Vec<BoundingSphere>,
}

impl GlassBounds {
    pub fn new(prepared: &PreparedScene, model: MaterialModel) -> Self {
        let scene = prepared.scene;
        let mut spheres: Vec<BoundingSphere> = (0..scene.objects.len())
            .filter(|&i| prepared.object_is_glass(i, model))
            .filter_map(|i| {
                let mesh = scene.world_mesh(i);
                if mesh.positions.is_empty() {
                    return None;
                }
                let (min, max) = mesh.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
                let center = 0.5 * (min + max);
                let radius = mesh.positions.iter().map(|&p| (p - center).length()).fold(0.0f32, f32::max);
                Some(BoundingSphere { center, radius })
            })
            .collect();
        if spheres.len() > MAX_CONES {
            // One sphere around them all: coarser, but every piece of glass stays reachable
            // (the light tracer relies on that: the path tracer leaves it those paths).
            let center = spheres.iter().map(|s| s.center).sum::<Vec3>() / spheres.len() as f32;
            let radius = spheres.iter().map(|s| (s.center - center).length() + s.radius).fold(0.0f32, f32::max);
            spheres = vec![BoundingSphere { center, radius }];
        }
        GlassBounds { spheres }
    }

    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty()
    }

    /// The cones the glass subtends from `from`.
    pub fn cones_from(&self, from: Vec3) -> GlassCones<'_> {
        let total_solid_angle = self.spheres.iter().map(|s| Cone::towards(from, s).solid_angle).sum();
        GlassCones { bounds: self, from, total_solid_angle }
    }
}

/// The cones towards the glass from one point: a distribution of directions, uniform over
/// their union where they do not overlap. The cones are recomputed from the spheres on each
/// use rather than stored: there are few, and up to [`MAX_CONES`] copies would cost more.
#[derive(Clone, Copy, Debug)]
pub struct GlassCones<'a> {
    bounds: &'a GlassBounds,
    from: Vec3,
    total_solid_angle: f32,
}

impl GlassCones<'_> {
    fn cones(&self) -> impl Iterator<Item = Cone> + '_ {
        self.bounds.spheres.iter().map(|s| Cone::towards(self.from, s))
    }

    pub fn is_empty(&self) -> bool {
        self.total_solid_angle <= 0.0
    }

    /// A direction and its solid-angle density: a cone picked in proportion to its solid
    /// angle, then uniformly within it.
    pub fn sample(&self, u_pick: f32, u: Vec2) -> Option<(Vec3, f32)> {
        if self.is_empty() {
            return None;
        }
        let mut target = u_pick * self.total_solid_angle;
        let mut picked = None;
        for cone in self.cones() {
            picked = Some(cone);
            if target < cone.solid_angle {
                break;
            }
            target -= cone.solid_angle;
        }
        let direction = picked?.sample(u);
        Some((direction, self.pdf(direction).max(1.0 / self.total_solid_angle)))
    }

    /// Solid-angle density of `direction` under [`GlassCones::sample`]: (cones containing it)
    /// / (sum of the cones' solid angles).
    pub fn pdf(&self, direction: Vec3) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let covering = self.cones().filter(|c| c.contains(direction)).count();
        covering as f32 / self.total_solid_angle
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    const SPHERE: f32 = 4.0 * std::f32::consts::PI;

    #[test]
    fn cone_sampling_stays_inside_and_counts_overlaps() {
        let bounds = GlassBounds {
            spheres: vec![BoundingSphere { center: Vec3::new(0.0, 0.0, -2.0), radius: 0.5 }, BoundingSphere { center: Vec3::new(0.2, 0.0, -2.5), radius: 0.6 }],
        };
        let cones = bounds.cones_from(Vec3::ZERO);
        let mut rng = Pcg32::new(3, 4);
        for cone in cones.cones() {
            for _ in 0..1000 {
                assert!(cone.contains(cone.sample(rng.next_vec2())));
            }
        }
        // Integrating the sampler's density over the sphere of directions must give 1, and
        // its samples must land where the density says: a histogram over the number of
        // covering cones against the density's mass there.
        let n = 400_000;
        let mut integral = 0.0f64;
        for _ in 0..n {
            integral += cones.pdf(crate::sampling::uniform_sphere(rng.next_vec2())) as f64;
        }
        integral *= SPHERE as f64 / n as f64;
        assert!((integral - 1.0).abs() < 0.03, "density integrates to {integral}");
        let (mut in_overlap, mut overlap_mass) = (0u32, 0.0f64);
        for _ in 0..n {
            let (d, pdf) = cones.sample(rng.next_f32(), rng.next_vec2()).unwrap();
            assert_eq!(pdf, cones.pdf(d));
            let covering = cones.cones().filter(|c| c.contains(d)).count();
            in_overlap += (covering == 2) as u32;
            let u = crate::sampling::uniform_sphere(rng.next_vec2());
            if cones.cones().filter(|c| c.contains(u)).count() == 2 {
                overlap_mass += (cones.pdf(u) * SPHERE) as f64;
            }
        }
        let (sampled, expected) = (in_overlap as f64 / n as f64, overlap_mass / n as f64);
        assert!(expected > 0.05, "the cones overlap ({expected})");
        assert!((sampled - expected).abs() < 0.01, "samples in the overlap {sampled}, density says {expected}");
        // Inside a sphere the cone is every direction.
        let inside = Cone::towards(Vec3::new(0.0, 0.0, -2.1), &bounds.spheres[0]);
        assert!(inside.contains(Vec3::Z) && inside.contains(Vec3::NEG_Z));
        assert!((inside.solid_angle - SPHERE).abs() < 1e-5);
    }
}
