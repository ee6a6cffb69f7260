//! Light tracing of caustic paths: the half of the `caustic` estimator that starts at the
//! lights (the other half is the path tracer with these paths left out).
//!
//! A path tracer finds light that reached a diffuse surface through glass (a caustic) only
//! when a direction sampled at that surface happens to pass through the glass and hit a
//! light: rare, and each hit is a firefly. Traced from the light, the same light is easy to
//! find: send light towards the glass, follow it through, and where it lands on an opaque
//! surface connect that point to the camera (Veach 1997, ch. 10, the s = k, t = 1 strategy
//! of bidirectional path tracing).
//!
//! The two halves split the paths between them, so each path is counted exactly once and
//! the sum is unbiased. Reading a path from the camera (E) to the light (L), with P a
//! straight crossing of a smooth thin pane, O an opaque surface and G any vertex on glass
//! (a material with a transmissive dielectric lobe), the light tracer takes exactly the paths
//!
//! ```text
//!     E P* O ... O G+ L     with at least one G that is not a straight pane crossing
//! ```
//!
//! (the camera sees an opaque surface, possibly through smooth panes, which a connection can
//! reach; the light's last bounce before the final opaque vertex was through glass that bends
//! or reflects light, which next-event estimation cannot follow). [`crate::path_class::PathClass`] is the path
//! tracer's side of that rule; [`LightTracer::trace`] produces exactly those paths and no
//! others: its first segment must end on glass, its first opaque vertex must follow a bending
//! glass event, and it connects to the camera only from opaque vertices, through panes only.
//!
//! Light paths leave the lights only towards the glass: a direction is drawn uniformly from
//! the cones that the bounding spheres of the glass objects subtend (several cones may
//! overlap; the density counts them). A path whose first segment misses the glass is not one
//! of the light tracer's, so nothing is lost.
//!
//! The measurement contribution uses the path tracer's BSDF argument order (`wo` towards the
//! camera) and its shading-normal convention, so both halves estimate the same integral:
//! sampling from the light side multiplies by the adjoint correction |n_s.w_light||n_g.w_next|
//! / (|n_s.w_next||n_g.w_light|) (Veach 1997, sec. 5.3), and refraction carries no 1/eta^2
//! (light tracing transports flux, not radiance).

use glam::Vec3;
use glassbake_core::Camera;

use crate::bsdf::Bsdf;
use crate::glass_cones::GlassBounds;
use crate::photon_merging::Photon;
use crate::prepared::{offset_origin, PathSettings, PreparedScene, SurfaceHit, MAX_VERTICES};
use crate::rng::Pcg32;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, Frame};
use crate::triangle::{Hit, Owner};

/// Light paths traced per camera sample, before the image's own budget is known: the
/// progress bar's first estimate. (A fixed one per four was the rule until the budget was
/// balanced per image: at 128 px, 256 spp it was too many for the desk, whose light tracing
/// adds little, and too few for cornell-glass and bathroom; docs/benchmarks.md.)
pub const LIGHT_PATHS_PER_CAMERA_PATH: f64 = 0.25;

/// The bounds of the balanced budget, in light paths per camera sample.
pub const MIN_LIGHT_PATHS_PER_CAMERA_SAMPLE: f64 = 1.0 / 64.0;
pub const MAX_LIGHT_PATHS_PER_CAMERA_SAMPLE: f64 = 1.0;

/// Light paths traced, and set aside, to measure what one light path costs and how much
/// variance it adds: 1/64 of the camera samples, at least 1,024 and at most 65,536.
pub fn pilot_light_paths(camera_samples: u64) -> u64 {
    (camera_samples / 64).clamp(1024, 65_536)
}

/// The number of light paths that makes the image cheapest for its noise. The image is the
/// sum of two independent estimates, the camera samples' (variance `camera_variance`, summed
/// over the pixels, at a cost of `camera_rays`) and the light paths' (`light_variance_per_path`
/// / N, at `rays_per_light_path` x N), so the product of variance and cost,
/// (A + B / N)(C + c N), is least at N = sqrt(B C / (A c)): the number of light paths at which
/// one more light path lowers the variance by as much per ray as more camera samples would.
/// Clamped to [`MIN_LIGHT_PATHS_PER_CAMERA_SAMPLE`, `MAX_LIGHT_PATHS_PER_CAMERA_SAMPLE`] per
/// camera sample: the estimates come from pilots, and a light tracer that never runs cannot
/// show it has become worth running.
pub fn balanced_light_paths(camera_variance: f64, light_variance_per_path: f64, camera_rays: f64, rays_per_light_path: f64, camera_samples: u64) -> u64 {
    let least = (camera_samples as f64 * MIN_LIGHT_PATHS_PER_CAMERA_SAMPLE).ceil().max(1.0);
    let most = (camera_samples as f64 * MAX_LIGHT_PATHS_PER_CAMERA_SAMPLE).max(least);
    let best = if camera_variance <= 0.0 || rays_per_light_path <= 0.0 {
        most
    } else {
        (light_variance_per_path * camera_rays / (camera_variance * rays_per_light_path)).sqrt()
    };
    if best.is_nan() {
        return least as u64;
    }
    best.clamp(least, most).round() as u64
}

/// What a pilot of light paths measured, per pixel: the sum of each path's contributions
/// and of their squares (a path's splats on one pixel summed first), and the rays cast.
pub struct LightPilot {
    pub paths: u64,
    pub sum: Vec<[f64; 3]>,
    pub sum_squares: Vec<[f64; 3]>,
    pub rays: u64,
}

/// Light paths traced per unit of work: one random stream each, and the grain at which
/// splats are gathered (in path order, so the image does not depend on the thread count).
pub const PATHS_PER_CHUNK: u64 = 4096;

/// Which light paths a walk from the lights traces, and where it stops to connect or leave a
/// photon.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightWalk {
    /// The light tracer's: leave the light towards the glass, keep the opaque vertices after
    /// the first glass event that bends light (the caustic paths).
    Caustic,
    /// All light: leave the light in a cosine-distributed direction, keep every opaque vertex
    /// after the first scattering event (light that came straight from the light is next-event
    /// estimation's).
    Global,
}

/// Where a light path leaves its emitter, and the flux it carries.
struct Emission {
    origin: Vec3,
    direction: Vec3,
    beta: Vec3,
}

/// An opaque vertex of a light path, as the light tracer reaches it.
#[derive(Clone, Copy)]
struct LightVertex<'a> {
    hit: &'a SurfaceHit,
    bsdf: &'a Bsdf,
    /// Towards the light, along the path.
    w_light: Vec3,
    /// Flux carried to the vertex.
    beta: Vec3,
    /// Segments from the light to the vertex.
    segments: u32,
    /// The path's first opaque vertex came after glass that bent its light: seen from a
    /// camera path whose view did not bend, the light tracer's path.
    caustic_start: bool,
}

/// A light path's contribution to one pixel, before dividing by the number of light paths.
#[derive(Clone, Copy, Debug)]
pub struct Splat {
    pub pixel: u32,
    pub value: Vec3,
}

/// What the pinhole camera needs to take a connection: the pixel a point projects to and
/// the importance of that direction.
struct CameraProjection {
    position: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_x: f32,
    tan_half_y: f32,
    width: u32,
    height: u32,
    /// Area of one pixel on the image plane at distance 1.
    pixel_area: f32,
}

impl CameraProjection {
    fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let frame = camera.frame();
        let (tan_half_x, tan_half_y) = camera.tan_half_fov(width, height);
        let pixel_area = (2.0 * tan_half_x / width as f32) * (2.0 * tan_half_y / height as f32);
        CameraProjection {
            position: camera.position,
            forward: frame.forward,
            right: frame.right,
            up: frame.up,
            tan_half_x,
            tan_half_y,
            width,
            height,
            pixel_area,
        }
    }

    /// The pixel (row-major index) whose box contains the projection of `point`, and the
    /// camera's importance along the ray to it: a pixel's value is (1 / A) times the
    /// integral of radiance over its area A on the image plane at distance 1, and that
    /// plane's area element is d(omega) / cos^3 of the angle to the view axis.
    fn pixel_and_importance(&self, point: Vec3) -> Option<(u32, f32)> {
        let v = point - self.position;
        let depth = v.dot(self.forward);
        if depth <= 0.0 {
            return None;
        }
        let ndc_x = v.dot(self.right) / depth / self.tan_half_x;
        let ndc_y = v.dot(self.up) / depth / self.tan_half_y;
        let px = (ndc_x + 1.0) * 0.5 * self.width as f32;
        let py = (1.0 - ndc_y) * 0.5 * self.height as f32;
        if !(px >= 0.0 && py >= 0.0 && px < self.width as f32 && py < self.height as f32) {
            return None;
        }
        let (x, y) = ((px as u32).min(self.width - 1), (py as u32).min(self.height - 1));
        let cos = depth / v.length();
        Some((y * self.width + x, 1.0 / (self.pixel_area * cos * cos * cos)))
    }
}

/// Traces light paths into splats on the image of one camera.
pub struct LightTracer<'a> {
    prepared: &'a PreparedScene<'a>,
    camera: CameraProjection,
    glass: GlassBounds,
    settings: PathSettings,
}

impl<'a> LightTracer<'a> {
    pub fn new(prepared: &'a PreparedScene<'a>, camera: &Camera, width: u32, height: u32, settings: PathSettings) -> Self {
        let glass = GlassBounds::new(prepared, settings.material_model);
        LightTracer { prepared, camera: CameraProjection::new(camera, width, height), glass, settings }
    }

    /// Pixels of the image the splats land on.
    pub fn pixel_count(&self) -> usize {
        self.camera.width as usize * self.camera.height as usize
    }

    /// Width of one pixel at the camera's mean distance to the glass objects' bounding
    /// spheres (their nearest points; at least a tenth of the distance to their centres, so a
    /// camera inside a sphere still gets a footprint), or `None` without glass.
    pub fn pixel_footprint_at_glass(&self) -> Option<f32> {
        let spheres = &self.glass.spheres;
        if spheres.is_empty() {
            return None;
        }
        let to_sphere = |s: &crate::glass_cones::BoundingSphere| {
            let centre = (s.center - self.camera.position).length();
            (centre - s.radius).max(0.1 * centre).max(1e-3 * s.radius)
        };
        let distance = spheres.iter().map(to_sphere).sum::<f32>() / spheres.len() as f32;
        Some(distance * 2.0 * self.camera.tan_half_x / self.camera.width as f32)
    }

    /// Whether any light path can be the light tracer's: the scene has glass and a light.
    pub fn has_work(&self) -> bool {
        !self.glass.is_empty() && !self.prepared.lights.is_empty()
    }

    /// One light path from the stream `rng`, its camera connections appended to `splats`.
    /// Returns how many of them were not finite (left out).
    pub fn trace(&self, rng: &mut Pcg32, splats: &mut Vec<Splat>, hits: &mut Vec<Hit>) -> u64 {
        self.walk(rng, hits, LightWalk::Caustic, &mut |vertex, hits| self.connect_to_camera(vertex, splats, hits))
    }

    /// One light path from the stream `rng`, traced as `walk` says, its vertices left as
    /// photons in `photons` for [`crate::photon_merging`] instead of being connected to the
    /// camera.
    pub fn trace_photons(&self, rng: &mut Pcg32, walk: LightWalk, photons: &mut Vec<Photon>, hits: &mut Vec<Hit>) {
        self.walk(rng, hits, walk, &mut |vertex, _| {
            let LightVertex { hit, w_light, beta, segments, caustic_start, .. } = *vertex;
            let correction = w_light.dot(hit.shading_normal).abs() / w_light.dot(hit.geometric_normal).abs();
            let flux = beta * correction;
            if flux.is_finite() && flux != Vec3::ZERO {
                photons.push(Photon { position: hit.position, normal: hit.geometric_normal, w_light, flux, segments, caustic_start });
            }
            0
        });
    }

    /// A light path's start: an emitter picked by power, a point uniform by area on it, and a
    /// direction towards the glass (`Caustic`) or cosine-distributed (`Global`); `None` when
    /// the draw carries no light.
    fn emit(&self, rng: &mut Pcg32, walk: LightWalk) -> Option<Emission> {
        let lights = &self.prepared.lights;
        let (index, pmf) = lights.pick(rng.next_f32())?;
        let emitter = &lights.emitters[index];
        let point = emitter.point_at(rng.next_vec2());
        let (direction, density) = match walk {
            LightWalk::Caustic => {
                let u_pick = rng.next_f32();
                let u_direction = rng.next_vec2();
                self.glass.cones_from(point).sample(u_pick, u_direction)?
            }
            LightWalk::Global => {
                let u_side = rng.next_f32();
                let local = cosine_hemisphere(rng.next_vec2());
                let (normal, side_probability) = match emitter.two_sided {
                    true if u_side < 0.5 => (-emitter.normal, 0.5),
                    true => (emitter.normal, 0.5),
                    false => (emitter.normal, 1.0),
                };
                (Frame::from_normal(normal).to_world(local), side_probability * cosine_hemisphere_pdf(local.z))
            }
        };
        let radiance = emitter.emitted(direction);
        let cos_light = emitter.normal.dot(direction).abs();
        if radiance == Vec3::ZERO || cos_light <= 0.0 || emitter.area <= 0.0 || pmf <= 0.0 {
            return None;
        }
        // Flux carried: L cos / (p(emitter) p(point) p(direction)).
        let beta = radiance * (cos_light * emitter.area / (pmf * density));
        Some(Emission { origin: offset_origin(point, emitter.normal, direction), direction, beta })
    }

    /// One light path from the stream `rng`, `visit` called at each of its opaque vertices
    /// that `walk` keeps (for the light tracer: those after the first glass event that bends
    /// light). Returns the sum of what `visit` returned.
    fn walk(&self, rng: &mut Pcg32, hits: &mut Vec<Hit>, walk: LightWalk, visit: &mut dyn FnMut(&LightVertex, &mut Vec<Hit>) -> u64) -> u64 {
        let Some(Emission { mut origin, mut direction, mut beta }) = self.emit(rng, walk) else { return 0 };
        let start = beta.max_element();
        // Segments from the light to the vertex about to be found.
        let mut segments = 1u32;
        // Whether a glass event that bends light has happened (before the first opaque vertex).
        let mut bent = false;
        // Whether the first opaque vertex (after bending glass) has been met.
        let mut caustic = false;
        // Whether the path has scattered (anything but a straight pane crossing) since the light.
        let mut scattered = false;
        // Whether the path's first opaque vertex came after bending glass (once it is met).
        let mut caustic_start: Option<bool> = None;

        let mut discarded = 0;

        for _ in 0..MAX_VERTICES {
            let Some(hit) = self.prepared.intersect_from(origin, direction, 0.0, f32::INFINITY) else { break };
            // A rectangle light's surface is black and ends paths.
            let Owner::Object { material, .. } = hit.owner else { break };
            let surface = self.prepared.surface_material(material, hit.uv);
            let bsdf = Bsdf::new(&surface, hit.shading_normal, self.settings.material_model);
            let glass = bsdf.is_glass();
            let w_light = -direction;
            let ng = hit.geometric_normal;
            let ns = hit.shading_normal;
            if !glass && caustic_start.is_none() {
                caustic_start = Some(bent);
            }
            let caustic_start = caustic_start == Some(true);
            if !glass && walk == LightWalk::Global {
                // Light that came straight from the light (through panes at most) is the
                // camera path's next-event estimation's.
                if scattered {
                    discarded += visit(&LightVertex { hit: &hit, bsdf: &bsdf, w_light, beta, segments, caustic_start }, hits);
                }
            } else if !glass {
                if !caustic {
                    // The path must reach its first opaque vertex through glass that bent it
                    // (so its first segment ended on glass).
                    if !bent {
                        break;
                    }
                    caustic = true;
                }
                discarded += visit(&LightVertex { hit: &hit, bsdf: &bsdf, w_light, beta, segments, caustic_start }, hits);
            }
            // One more segment must leave room for the connection to the camera.
            if segments + 2 > self.settings.max_depth {
                break;
            }
            let (u_lobe, u_event, u) = (rng.next_f32(), rng.next_f32(), rng.next_vec2());
            let Some(sample) = bsdf.sample(w_light, u_lobe, u_event, u) else { break };
            let w_next = sample.wi;
            if sample.delta {
                // The sampled weight is in radiance form; flux does not pick up 1/eta^2.
                let flux_scale = if sample.transmitted { sample.etap * sample.etap } else { 1.0 };
                beta *= sample.weight * flux_scale;
            } else {
                let reflection = w_next.dot(ng) * w_light.dot(ng) > 0.0;
                if reflection == sample.transmitted {
                    break;
                }
                // f in the path tracer's order (wo towards the camera) and the adjoint
                // shading-normal correction.
                let f = bsdf.eval(w_next, w_light);
                let correction = w_light.dot(ns).abs() * w_next.dot(ng).abs() / w_light.dot(ng).abs();
                beta *= f * (correction / sample.pdf);
            }
            if glass && !sample.pass_through {
                bent = true;
            }
            scattered |= !sample.pass_through;
            if !beta.is_finite() || beta == Vec3::ZERO {
                break;
            }
            origin = offset_origin(hit.position, ng, w_next);
            direction = w_next;
            segments += 1;
            // Russian roulette on the flux lost since the light, from the first bounce: a light
            // path's value is spread over every surface it lights, so long dim walks are not
            // worth their connections. Capped at 0.95 beyond the path tracer's rr_depth.
            let cap = if segments > self.settings.rr_depth { 0.95 } else { 1.0 };
            let survival = (beta.max_element() / start).min(cap);
            if survival < 1.0 {
                if rng.next_f32() >= survival {
                    break;
                }
                beta /= survival;
            }
        }
        discarded
    }

    /// Connect an opaque vertex of a light path to the camera, through smooth thin panes
    /// only. Returns 1 if the splat was not finite (and so left out).
    fn connect_to_camera(&self, vertex: &LightVertex, splats: &mut Vec<Splat>, hits: &mut Vec<Hit>) -> u64 {
        let LightVertex { hit, bsdf, w_light, beta, segments, .. } = *vertex;
        let Some((pixel, importance)) = self.camera.pixel_and_importance(hit.position) else { return 0 };
        let ng = hit.geometric_normal;
        let ns = hit.shading_normal;
        let to_camera = self.camera.position - hit.position;
        let distance2 = to_camera.length_squared();
        if distance2 <= 0.0 {
            return 0;
        }
        let w_camera = to_camera / distance2.sqrt();
        // The path tracer refuses the same configurations when it samples here.
        let reflection = w_camera.dot(ng) * w_light.dot(ng) > 0.0;
        let shading_reflection = w_camera.dot(ns) * w_light.dot(ns) > 0.0;
        if reflection != shading_reflection {
            return 0;
        }
        let f = bsdf.eval(w_camera, w_light);
        if f == Vec3::ZERO {
            return 0;
        }
        let origin = offset_origin(hit.position, ng, w_camera);
        let to_camera = self.camera.position - origin;
        let distance = to_camera.length();
        let crossings_allowed = self.settings.max_depth - segments - 1;
        let Some((transmittance, _)) = self.prepared.transmittance(origin, to_camera / distance, distance, crossings_allowed, &self.settings, hits) else {
            return 0;
        };
        let correction = w_light.dot(ns).abs() / w_light.dot(ng).abs();
        let geometry = w_camera.dot(ng).abs() / distance2;
        let value = beta * f * transmittance * (correction * geometry * importance);
        if !value.is_finite() {
            return 1;
        }
        if value != Vec3::ZERO {
            splats.push(Splat { pixel, value });
        }
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The balanced budget minimizes (variance x cost) of the image: it is the closed form's
    /// optimum, and no other count does better.
    #[test]
    fn balanced_light_paths_minimize_variance_times_cost() {
        let product = |a: f64, b: f64, c: f64, per_path: f64, n: f64| (a + b / n) * (c + per_path * n);
        // A = 2e-3 summed variance, B = 50 per light path, 4e6 camera rays, 6 rays a light path.
        let (a, b, c, per_path, samples) = (2e-3, 50.0, 4.0e6, 6.0, 1_000_000u64);
        let n = balanced_light_paths(a, b, c, per_path, samples) as f64;
        let exact = (b * c / (a * per_path)).sqrt();
        assert!((n - exact).abs() <= 1.0, "{n} vs {exact}");
        assert!(n > samples as f64 * MIN_LIGHT_PATHS_PER_CAMERA_SAMPLE && n < samples as f64 * MAX_LIGHT_PATHS_PER_CAMERA_SAMPLE);
        for other in [0.5 * n, 0.9 * n, 1.1 * n, 2.0 * n] {
            assert!(product(a, b, c, per_path, n) < product(a, b, c, per_path, other), "{n} must beat {other}");
        }
        // At the optimum both halves' variance-cost shares balance: B C / N = A c N.
        assert!(((b * c / n) / (a * per_path * n) - 1.0).abs() < 1e-3);
        // Bounds: light paths that add no variance are still traced at the floor (a pilot
        // cannot prove them useless forever); a silent camera leaves all to the light tracer.
        assert_eq!(balanced_light_paths(a, 0.0, c, per_path, samples), 15_625, "1/64 of the camera samples");
        assert_eq!(balanced_light_paths(0.0, b, c, per_path, samples), samples);
        assert_eq!(balanced_light_paths(a, 1e12, c, per_path, samples), samples);
        assert_eq!(balanced_light_paths(a, 0.0, c, per_path, 10), 1, "at least one light path");
    }

    #[test]
    fn the_camera_projection_inverts_the_pixel_ray() {
        let camera = Camera::look_at(Vec3::new(0.3, 1.1, 3.0), Vec3::new(-0.1, 0.9, 0.0), 45.0);
        let (w, h) = (40, 30);
        let projection = CameraProjection::new(&camera, w, h);
        for (px, py) in [(0.5f32, 0.5f32), (20.2, 14.9), (39.7, 29.2), (3.3, 27.5)] {
            let ray = camera.ray(px, py, w, h);
            let point = ray.origin + ray.direction * 2.7;
            let (pixel, _) = projection.pixel_and_importance(point).unwrap();
            let (x, y) = (px as u32, py as u32);
            assert_eq!(pixel, y * w + x);
            // The importance integrates to 1 over the pixel's solid angle, taken exactly as a
            // spherical rectangle: the pixel's corners on the image plane at distance 1.
            let f = camera.frame();
            let (tx, ty) = camera.tan_half_fov(w, h);
            let corner = camera.position + f.forward + f.right * ((2.0 * x as f32 / w as f32 - 1.0) * tx) + f.up * ((1.0 - 2.0 * y as f32 / h as f32) * ty);
            let edge_u = f.right * (2.0 * tx / w as f32);
            let edge_v = -f.up * (2.0 * ty / h as f32);
            let rect = crate::spherical_rect::SphericalRect::new(corner, edge_u, edge_v, camera.position).unwrap();
            let centre = camera.ray(x as f32 + 0.5, y as f32 + 0.5, w, h);
            let (_, centre_importance) = projection.pixel_and_importance(centre.origin + centre.direction).unwrap();
            let integral = centre_importance as f64 * rect.solid_angle;
            assert!((integral - 1.0).abs() < 2e-3, "importance x pixel solid angle = {integral}");
        }
        assert!(projection.pixel_and_importance(camera.position - camera.frame().forward).is_none());
    }

    /// More glass objects than cones: one sphere around all of them, so no glass is ever
    /// out of the light paths' reach (which would bias the estimator: the path tracer leaves
    /// those paths to the light tracer).
    #[test]
    fn many_glass_objects_share_one_sphere_that_holds_them_all() {
        use glassbake_scene::{Material, Object, Scene};
        let mut scene = Scene::empty("many panes");
        scene.materials.push(Material::glass("pane", Vec3::ONE, 0.0, 1.5, true));
        for i in 0..(crate::glass_cones::MAX_CONES + 6) {
            let centre = Vec3::new(i as f32 * 0.3 - 10.0, 1.0 + (i % 5) as f32, -((i % 7) as f32));
            scene.meshes.push(std::sync::Arc::new(glassbake_scene::shapes::rect(centre, Vec3::X * 0.2, Vec3::Y * 0.2, glam::Vec2::ONE)));
            scene.objects.push(Object { name: format!("pane {i}"), mesh: i, material: 0, transform: glam::Affine3A::IDENTITY, transparent: true });
        }
        let prepared = PreparedScene::new(&scene);
        let camera = Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, 50.0);
        let settings = PathSettings { max_depth: 8, rr_depth: 5, material_model: crate::MaterialModel::Gltf, path_filter: crate::PathFilter::All };
        let tracer = LightTracer::new(&prepared, &camera, 8, 8, settings);
        assert_eq!(tracer.glass.spheres.len(), 1);
        let sphere = tracer.glass.spheres[0];
        for i in 0..scene.objects.len() {
            for p in scene.world_mesh(i).positions {
                assert!((p - sphere.center).length() <= sphere.radius * 1.0001, "pane {i} sticks out of the sphere");
            }
        }
    }
}
