//! The camera's path integrator: unidirectional path tracing with next-event estimation and
//! multiple importance sampling (Veach 1997, power heuristic), Russian roulette and a maximum
//! path length; shadow rays pass straight through smooth thin panes (exact for a pane, which
//! does not bend light), with MIS that counts the pane crossings on both strategies, and
//! where the estimator asks, follow smooth glass that turns them.
//!
//! [`PreparedScene::trace_path`] reads top-down, one loop iteration per surface vertex:
//! find the next surface, add what an emitter there sends, let the estimator's hooks act,
//! estimate the direct light, sample the BSDF for the next direction, play Russian roulette.
//! An estimator changes the path tracer only through [`PathHooks`]: [`PlainPaths`] keeps
//! every default; the caustic estimator's hooks (`caustic_paths.rs`, with photon merging's in
//! `photon_merging.rs`) leave out the paths its light tracer or its photons carry, and take
//! the emitters that smooth glass seen by the camera reflects at every sample instead of at
//! the few samples that pick the reflection, and from surfaces the camera sees through
//! bending glass send shadow rays on through smooth glass.

use glam::Vec3;
use glassbake_core::Ray;

use crate::bsdf::{Bsdf, BsdfSample, DeltaContinuation};
use crate::path_class::{PathClass, PathFilter};
use crate::prepared::{offset_origin, ray_epsilon, PathSettings, PreparedScene, SurfaceHit, MAX_VERTICES};
use crate::qmc::{self, StratifiedSample};
use crate::rng::Pcg32;
use crate::sampling::power_heuristic;
use crate::triangle::{Hit, Owner};

/// What one camera path brought back: all of it, and the part its settings' [`PathFilter`]
/// counts (the same unless a filter is set).
#[derive(Clone, Copy, Debug)]
pub struct PathRadiance {
    pub all: Vec3,
    pub counted: Vec3,
}

/// Reusable per-thread storage for [`PreparedScene::trace_path`].
#[derive(Default)]
pub struct PathScratch {
    pub(crate) hits: Vec<Hit>,
    pub(crate) photons_found: Vec<u32>,
}

/// A surface vertex of a camera path, as the hooks see it.
pub(crate) struct Vertex<'v> {
    pub hit: &'v SurfaceHit,
    /// Towards the camera, along the path.
    pub wo: Vec3,
    pub bsdf: &'v Bsdf,
    /// Whether the material has a transmissive dielectric lobe ([`Bsdf::is_glass`]).
    pub glass: bool,
    /// The path's throughput as it arrives.
    pub throughput: Vec3,
    /// Segments so far, counting the one that arrived here.
    pub depth: u32,
    /// The path's class as it arrived, and once this vertex is entered.
    pub class_on_arrival: PathClass,
    pub class: PathClass,
}

/// What an estimator changes in the plain path tracer, at named points of a path. A value is
/// copied at the start of every path, so a hook may keep per-path state in it.
pub(crate) trait PathHooks: Copy {
    /// Whether the light of an emitter that the path hits (`class`: as it arrives) counts.
    fn counts_emitter_hit(&self, _class: &PathClass) -> bool {
        true
    }

    /// At a surface, before its direct light: light estimated there by other means (added to
    /// the path's), or `None` to end the path here.
    fn at_surface(&mut self, _vertex: &Vertex, _settings: &PathSettings, _rng: &mut Pcg32, _scratch: &mut PathScratch) -> Option<Vec3> {
        Some(Vec3::ZERO)
    }

    /// Whether the vertex's next-event estimation traces its shadow ray.
    fn traces_shadow_ray(&self, _vertex: &Vertex) -> bool {
        true
    }

    /// After the vertex sampled the path's next direction: whether the path goes on.
    fn continues(&mut self, _vertex: &Vertex, _sample: &BsdfSample) -> bool {
        true
    }

    /// Whether next-event estimation at the vertex follows its shadow ray through smooth
    /// glass, refracted, when it does not reach the light straight
    /// (`PreparedScene::light_through_glass`).
    fn shadow_rays_follow_glass(&self, _vertex: &Vertex) -> bool {
        false
    }

    /// Whether the vertices of the path's delta prefix (the camera's view in and through
    /// smooth glass) take the light of emitters reflected in smooth glass at every sample
    /// (`PreparedScene::reflected_emission`).
    fn takes_reflected_emission(&self) -> bool {
        false
    }
}

/// The plain path tracer: every hook at its default.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PlainPaths;

impl PathHooks for PlainPaths {}

/// The light a path gathers: all of it, and the part its filter counts.
struct Gathered {
    all: Vec3,
    counted: Vec3,
    filter: PathFilter,
}

impl Gathered {
    fn add(&mut self, light: Vec3, view_bent: bool) {
        self.all += light;
        if self.filter.counts(view_bent) {
            self.counted += light;
        }
    }
}

/// Where a path stands between two vertices.
struct PathState {
    throughput: Vec3,
    origin: Vec3,
    direction: Vec3,
    t_min: f32,
    /// Segments so far, counting the one being traced.
    depth: u32,
    /// Product of the IOR ratios crossed, squared, undoing the radiance scaling of refraction
    /// for Russian roulette.
    eta_scale: f32,
    /// MIS state: whether the path since its last non-delta vertex is something only BSDF
    /// sampling can produce, that vertex, and the density of reaching here from it.
    specular: bool,
    mis_origin: Vec3,
    mis_pdf: f32,
    class: PathClass,
    /// Every vertex so far was a delta event.
    delta_prefix: bool,
    /// The segment being traced is a delta reflection whose emitter's light the previous
    /// vertex already took (`PreparedScene::reflected_emission`): not counted again.
    emission_taken: bool,
    /// Since the last non-delta vertex, whose shadow ray followed smooth glass, the path has
    /// only passed smooth glass (transmitted, or totally reflected inside it): a path that
    /// shadow ray could have made too.
    glass_chain: Option<GlassChain>,
}

/// A path's run of smooth-glass events since a non-delta vertex (each the one way light
/// passes the glass there: [`Bsdf::delta_continuation`]), as next-event estimation through
/// glass (`PreparedScene::light_through_glass`) weighs it.
#[derive(Clone, Copy, Debug)]
struct GlassChain {
    /// The non-delta vertex and the direction the path left it in.
    origin: Vec3,
    direction: Vec3,
    /// The density of BSDF-sampling that direction there times the probabilities of the
    /// events picked since.
    probability: f32,
    interfaces: u32,
    /// One of them turned the path (solid glass): not a path the straight shadow ray makes.
    bends: bool,
}

impl GlassChain {
    /// Extended by the delta `sample` taken towards `wo` at a surface with `bsdf`, if it is
    /// the way light passes smooth glass there (what the shadow ray follows).
    fn through(mut self, bsdf: &Bsdf, wo: Vec3, sample: &BsdfSample) -> Option<Self> {
        let continuation = bsdf.delta_continuation(wo)?;
        if sample.transmitted == continuation.reflected {
            return None;
        }
        self.probability *= sample.pdf;
        self.interfaces += 1;
        self.bends |= continuation.bends;
        Some(self)
    }
}

/// Interfaces a shadow ray follows through smooth glass at most: a solid object's two, a
/// few objects deep.
const MAX_GLASS_INTERFACES: u32 = 8;

impl PathState {
    fn new(ray: &Ray) -> Self {
        PathState {
            throughput: Vec3::ONE,
            origin: ray.origin,
            direction: ray.direction,
            t_min: 0.0,
            depth: 1,
            eta_scale: 1.0,
            specular: true,
            mis_origin: ray.origin,
            mis_pdf: 0.0,
            class: PathClass::default(),
            delta_prefix: true,
            emission_taken: false,
            glass_chain: None,
        }
    }

    /// Follow `sample` from `hit`.
    fn scatter(&mut self, hit: &SurfaceHit, sample: &BsdfSample) {
        self.throughput *= sample.weight;
        if sample.transmitted && sample.etap != 1.0 {
            self.eta_scale *= sample.etap * sample.etap;
        }
        self.depth += 1;
        if sample.pass_through {
            self.mis_pdf *= sample.pdf;
        } else {
            self.specular = sample.delta;
            self.mis_pdf = sample.pdf;
            self.mis_origin = hit.position;
        }
        self.origin = offset_origin(hit.position, hit.geometric_normal, sample.wi);
        self.direction = sample.wi;
        self.t_min = 0.0;
    }

    /// Russian roulette past `rr_depth` segments: whether the path survives (its throughput
    /// then divided by the survival probability).
    fn survives_roulette(&mut self, rr_depth: u32, rng: &mut Pcg32) -> bool {
        if self.throughput == Vec3::ZERO {
            return false;
        }
        if self.depth > rr_depth {
            let survival = (self.throughput.max_element() * self.eta_scale).min(0.95);
            if rng.next_f32() >= survival {
                return false;
            }
            self.throughput /= survival;
        }
        true
    }
}

/// A 2D value of stratified dimension `dimension` if the sample has one, else from `rng`.
fn draw_2d(stratified: Option<&StratifiedSample>, rng: &mut Pcg32, dimension: Option<u32>) -> glam::Vec2 {
    match (stratified, dimension) {
        (Some(sample), Some(d)) => sample.get_2d(d),
        _ => rng.next_vec2(),
    }
}

impl PreparedScene<'_> {
    /// Radiance arriving at the camera along `ray`, one path sample, with the estimator's
    /// `hooks`. With `stratified`, the first vertices' light and BSDF samples come from it
    /// (see [`crate::qmc`]), the other random numbers from `rng`.
    pub(crate) fn trace_path<H: PathHooks>(
        &self,
        ray: &Ray,
        rng: &mut Pcg32,
        stratified: Option<&StratifiedSample>,
        settings: &PathSettings,
        mut hooks: H,
        scratch: &mut PathScratch,
    ) -> PathRadiance {
        let mut light = Gathered { all: Vec3::ZERO, counted: Vec3::ZERO, filter: settings.path_filter };
        let mut path = PathState::new(ray);
        for vertex in 0..MAX_VERTICES {
            let Some(hit) = self.intersect_from(path.origin, path.direction, path.t_min, f32::INFINITY) else {
                light.add(path.throughput * self.scene.background, path.class.view_bent(None));
                break;
            };
            let wo = -path.direction;
            if let Some(emitter) = hit.emitter {
                if !path.emission_taken && hooks.counts_emitter_hit(&path.class) {
                    light.add(self.emitted_along_path(&path, &hit, emitter, wo), path.class.view_bent(None));
                }
                // Shadow rays through glass stop at the first emitter; so does the chain.
                path.glass_chain = None;
            }
            let Owner::Object { material, .. } = hit.owner else { break };
            let bsdf = Bsdf::new(&self.surface_material(material, hit.uv), hit.shading_normal, settings.material_model);
            if path.depth >= settings.max_depth {
                break;
            }
            let glass = bsdf.is_glass();
            let class_on_arrival = path.class;
            path.class.enter_vertex(glass);
            let here = Vertex { hit: &hit, wo, bsdf: &bsdf, glass, throughput: path.throughput, depth: path.depth, class_on_arrival, class: path.class };

            let Some(elsewhere) = hooks.at_surface(&here, settings, rng, scratch) else { break };
            if elsewhere != Vec3::ZERO {
                light.add(elsewhere, class_on_arrival.view_bent(None));
            }
            let nee = bsdf.has_non_delta() && hooks.traces_shadow_ray(&here);
            let follow_glass = nee && hooks.shadow_rays_follow_glass(&here);
            if nee {
                let draw_light = |rng: &mut Pcg32| draw_2d(stratified, rng, qmc::light_dimension(vertex));
                let direct = self.direct_light(&here, settings, rng, draw_light, follow_glass, scratch);
                light.add(direct, path.class.view_bent(Some(glass)));
            }

            let split = glass && path.delta_prefix && hooks.takes_reflected_emission();
            if split {
                if let Some((reflected, view_bent)) = self.reflected_emission(&here, hooks) {
                    light.add(reflected, view_bent);
                }
            }

            let u_lobe = rng.next_f32();
            let mut u_event = rng.next_f32();
            let u = draw_2d(stratified, rng, qmc::bsdf_dimension(vertex));
            if stratified.is_some() && !bsdf.has_non_delta() {
                // Smooth glass needs no 2D value for its direction: its choice between
                // reflection and transmission takes the stratified first one instead.
                u_event = u.x;
            }
            let Some(sample) = bsdf.sample(wo, u_lobe, u_event, u) else { break };
            path.delta_prefix &= sample.delta;
            path.glass_chain = match sample.delta {
                false => {
                    follow_glass.then_some(GlassChain { origin: hit.position, direction: sample.wi, probability: sample.pdf, interfaces: 0, bends: false })
                }
                true => path.glass_chain.and_then(|chain| chain.through(&bsdf, wo, &sample)),
            };
            path.emission_taken = split && sample.delta && !sample.transmitted;
            let ng = hit.geometric_normal;
            let reflection = sample.wi.dot(ng) * wo.dot(ng) > 0.0;
            if reflection == sample.transmitted && !sample.delta {
                // The shading normal claims a side the geometry contradicts: following the
                // ray would leak light through the surface. (Delta events of glass keep
                // going: the next hit reads the side from the geometry, so nothing leaks,
                // and ending them would darken smooth glass by a fraction of a percent.)
                break;
            }
            if !hooks.continues(&here, &sample) {
                break;
            }
            path.class.leave_vertex(glass, sample.pass_through);
            path.scatter(&hit, &sample);
            if !path.survives_roulette(settings.rr_depth, rng) {
                break;
            }
        }
        PathRadiance { all: light.all, counted: light.counted }
    }

    /// The light that `vertex`'s smooth dielectric lobe reflects straight from an emitter
    /// that its mirror direction meets first, and whether that path's view bent. Taken at
    /// every sample instead of only when [`Bsdf::sample`] picks the reflection (with the
    /// Fresnel reflectance's probability, a few percent), which makes a light seen in glass
    /// a firefly; the sampled reflection then leaves that emitter's light out
    /// (`PathState::emission_taken`). Unbiased: the sampled reflection's weight divided by
    /// its probability is this fraction. A ray is cast only where the mirror direction may
    /// meet an emitter at all.
    fn reflected_emission<H: PathHooks>(&self, vertex: &Vertex, hooks: H) -> Option<(Vec3, bool)> {
        let (wi, fraction) = vertex.bsdf.delta_reflection(vertex.wo)?;
        let origin = offset_origin(vertex.hit.position, vertex.hit.geometric_normal, wi);
        if !self.lights.ray_may_hit_emitter(origin, wi) {
            return None;
        }
        let mut class = vertex.class;
        class.leave_vertex(vertex.glass, false);
        let emitter = self.intersect_from(origin, wi, 0.0, f32::INFINITY)?.emitter?;
        if !hooks.counts_emitter_hit(&class) {
            return None;
        }
        Some((vertex.throughput * fraction * self.lights.emitters[emitter as usize].emitted(-wi), class.view_bent(None)))
    }

    /// What emitter `emitter`, hit at `hit`, sends back along the path, MIS-weighted against
    /// the next-event estimation that could have found it from the path's last non-delta
    /// vertex.
    fn emitted_along_path(&self, path: &PathState, hit: &SurfaceHit, emitter: u32, wo: Vec3) -> Vec3 {
        let emitted = self.lights.emitters[emitter as usize].emitted(wo);
        if emitted == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let weight = match path.glass_chain {
            Some(chain) if chain.bends && chain.interfaces <= MAX_GLASS_INTERFACES => {
                power_heuristic(chain.probability, self.lights.direction_pdf(chain.origin, chain.direction).unwrap_or(0.0))
            }
            _ if path.specular => 1.0,
            _ => power_heuristic(path.mis_pdf, self.lights.pdf(emitter, path.mis_origin, hit.position)),
        };
        path.throughput * emitted * weight
    }

    /// Next-event estimation at `vertex`: one light sample (the emitter picked by a value of
    /// `rng`, the point by `draw_light`'s 2D value, drawn in that order), its shadow ray
    /// through smooth thin panes, MIS-weighted against BSDF sampling. With `follow_glass`,
    /// a shadow ray that does not reach the light straight follows smooth glass instead
    /// ([`PreparedScene::light_through_glass`]).
    fn direct_light(
        &self,
        vertex: &Vertex,
        settings: &PathSettings,
        rng: &mut Pcg32,
        draw_light: impl FnOnce(&mut Pcg32) -> glam::Vec2,
        follow_glass: bool,
        scratch: &mut PathScratch,
    ) -> Vec3 {
        let Vertex { hit, wo, bsdf, throughput, depth, .. } = *vertex;
        let u_select = rng.next_f32();
        let u_light = draw_light(rng);
        let Some(light) = self.lights.sample(hit.position, u_select, u_light) else { return Vec3::ZERO };
        let (ng, ns) = (hit.geometric_normal, hit.shading_normal);
        let wi = light.wi;
        let (f, pdf) = bsdf.eval_pdf(wo, wi);
        let reflection = wi.dot(ng) * wo.dot(ng) > 0.0;
        let shading_reflection = wi.dot(ns) * wo.dot(ns) > 0.0;
        if f == Vec3::ZERO || reflection != shading_reflection {
            return Vec3::ZERO;
        }
        // Aim from the offset origin itself: reusing wi from the surface point would cross
        // the light's plane short of the sampled point and hit the light itself at grazing
        // angles.
        let shadow_origin = offset_origin(hit.position, ng, wi);
        let to_light = light.point - shadow_origin;
        let shadow_distance = to_light.length();
        let t_max = shadow_distance * (1.0 - 1e-4) - ray_epsilon(light.point);
        // Segments the shadow ray may still cross panes with: a path of `depth + 1 +
        // crossings` segments must fit, as the BSDF-sampled one must.
        let crossings_allowed = settings.max_depth - depth - 1;
        let cos = wi.dot(ns).abs();
        let Some((transmittance, crossing_probability)) =
            self.transmittance(shadow_origin, to_light / shadow_distance, t_max, crossings_allowed, settings, &mut scratch.hits)
        else {
            if !follow_glass {
                return Vec3::ZERO;
            }
            let interfaces = crossings_allowed.min(MAX_GLASS_INTERFACES);
            return throughput * f * cos * self.light_through_glass(hit, wi, pdf, interfaces, settings);
        };
        let weight = power_heuristic(light.pdf, pdf * crossing_probability);
        throughput * f * cos * transmittance * light.radiance * (weight / light.pdf)
    }

    /// Next-event estimation through smooth glass: the light sampled in direction `wi` from
    /// `hit` did not arrive straight, so the shadow ray follows smooth glass, refracted by
    /// Snell's law and attenuated by Fresnel transmittance and tint at each of at most
    /// `interfaces` interfaces, or totally reflected inside solid glass where nothing is
    /// transmitted, to whatever emitter it reaches. Returned: that emitter's radiance times
    /// the transmittance, divided by the density of sampling `wi`
    /// ([`LightSampler::direction_pdf`]) and MIS-weighted against BSDF sampling (`bsdf_pdf`
    /// at `hit` times the probabilities of picking each event: `GlassChain`). Under solid
    /// glass lit from above, what only BSDF sampling found before (specular-diffuse-specular
    /// paths, one in tens of samples) this finds at every sample where the glass shifts the
    /// light without turning it away: a slab, a glass's flat bottom under its flat top, its
    /// walls reflecting what reaches them inside. Only paths turned at least once count: the
    /// rest is the straight shadow ray's.
    ///
    /// [`LightSampler::direction_pdf`]: crate::lights::LightSampler::direction_pdf
    fn light_through_glass(&self, hit: &SurfaceHit, wi: Vec3, bsdf_pdf: f32, interfaces: u32, settings: &PathSettings) -> Vec3 {
        let Some(direction_pdf) = self.lights.direction_pdf(hit.position, wi).filter(|&p| p > 0.0) else { return Vec3::ZERO };
        let mut origin = offset_origin(hit.position, hit.geometric_normal, wi);
        let mut direction = wi;
        let (mut transmittance, mut probability, mut bends) = (Vec3::ONE, bsdf_pdf, false);
        for crossed in 0..=interfaces {
            let Some(next) = self.intersect_from(origin, direction, 0.0, f32::INFINITY) else { return Vec3::ZERO };
            if let Some(emitter) = next.emitter {
                if !bends {
                    return Vec3::ZERO;
                }
                let radiance = self.lights.emitters[emitter as usize].emitted(-direction);
                return transmittance * radiance * (power_heuristic(direction_pdf, probability) / direction_pdf);
            }
            if crossed == interfaces {
                break;
            }
            let Owner::Object { material, .. } = next.owner else { return Vec3::ZERO };
            let bsdf = Bsdf::new(&self.surface_material(material, next.uv), next.shading_normal, settings.material_model);
            let Some(DeltaContinuation { wi: onward, fraction, probability: picked, bends: turned, .. }) = bsdf.delta_continuation(-direction) else {
                return Vec3::ZERO;
            };
            transmittance *= fraction;
            probability *= picked;
            bends |= turned;
            origin = offset_origin(next.position, next.geometric_normal, onward);
            direction = onward;
        }
        Vec3::ZERO
    }
}
