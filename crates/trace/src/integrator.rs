//! The unidirectional path tracer: next-event estimation with multiple importance sampling
//! (Veach 1997, power heuristic), Russian roulette, a maximum path length, and shadow rays
//! that pass straight through smooth thin panes (exact for a pane, since it does not bend
//! light), with MIS that counts the pane crossings on both strategies.
//!
//! With a learned [`SdTree`] (the guided estimator), diffuse and glossy vertices draw their
//! next direction from a one-sample mixture of the BSDF and the learned incident light
//! (Müller et al. 2017); the mixture's density is what MIS and the path weight use, so the
//! estimate stays unbiased whatever was learned. While learning, every such vertex leaves a
//! [`GuidingRecord`] of the radiance that the rest of its path brought back.

use std::cell::Cell;

use glam::{Vec2, Vec3};
use glassbake_core::Ray;
use glassbake_scene::Scene;

use crate::bsdf::{Bsdf, BsdfSample, MaterialModel, SurfaceMaterial};
use crate::geometry::{Hit, Owner, SceneGeometry};
use crate::guiding::{GuidingRecord, SdTree};
use crate::light_tracing::PathClass;
use crate::lights::LightSampler;
use crate::photon_merging::{MergeQuery, PhotonMap};
use crate::qmc::{self, StratifiedSample};
use crate::rng::Pcg32;
use crate::sampling::{luminance, power_heuristic};

thread_local! {
    /// Rays this thread has cast (closest-hit and shadow queries): the cost with which the
    /// light tracer's budget is weighed against the camera's (`light_tracing::balanced_light_paths`).
    /// Counted rather than timed so that the budget, and so the image, is deterministic.
    static RAYS_CAST: Cell<u64> = const { Cell::new(0) };
}

fn count_ray() {
    RAYS_CAST.with(|count| count.set(count.get() + 1));
}

/// Rays cast by the calling thread so far; differences of two readings on one thread count
/// the rays of the work in between.
pub(crate) fn rays_cast() -> u64 {
    RAYS_CAST.with(Cell::get)
}

/// What one camera path brought back: all of it, and the part its settings' [`PathFilter`]
/// counts (the same unless a filter is set).
#[derive(Clone, Copy, Debug)]
pub struct PathRadiance {
    pub all: Vec3,
    pub counted: Vec3,
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
    /// Leave out the paths that the light tracer takes (`light_tracing.rs`): the `caustic`
    /// estimator's path-tracing half.
    pub leave_caustics_to_light_tracing: bool,
    /// Which paths' light is counted: an analysis tool, [`PathFilter::All`] for images.
    pub path_filter: PathFilter,
}

/// Which of the paths an image counts. The two parts add up to the whole image, sample by
/// sample (tested), so rendering each says where an estimator's noise comes from (the
/// `trace_convergence` example's `--paths`). Not an estimator: an image of a part is not the
/// scene's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PathFilter {
    #[default]
    All,
    /// Paths whose view from the camera bends at glass (a reflection, or a refraction through
    /// solid or rough glass) before meeting anything opaque: what the camera sees in or
    /// through bending glass. No connection to the camera can reach these, so the light
    /// tracer cannot help with them; caustics seen this way are specular-diffuse-specular
    /// paths, which no unbiased estimator here samples well.
    BentView,
    /// The rest: paths that reach their first opaque surface (or a light, or the background)
    /// in a straight line, straight crossings of smooth thin panes included. Every light
    /// tracer path is one.
    StraightView,
}

impl PathFilter {
    pub fn name(self) -> &'static str {
        match self {
            PathFilter::All => "all",
            PathFilter::BentView => "bent-view",
            PathFilter::StraightView => "straight-view",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        [PathFilter::All, PathFilter::BentView, PathFilter::StraightView].into_iter().find(|f| f.name() == name)
    }

    fn counts(self, view_bent: bool) -> bool {
        match self {
            PathFilter::All => true,
            PathFilter::BentView => view_bent,
            PathFilter::StraightView => !view_bent,
        }
    }
}

/// Which light-transport estimator traces the paths. All four are unbiased and converge to
/// the same image; `docs/trace.md` has their measured efficiency. `Caustic` is what the CLI
/// and new CPU datasets use; `Plain` stays the library's default because it is the one
/// estimator that every tracer (the GPU one too) implements.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Integrator {
    /// Rectangle lights sampled by area, BSDF sampling only (the default).
    #[default]
    Plain,
    /// Rectangle lights sampled by solid angle, no guiding.
    SolidAngle,
    /// Rectangle lights sampled by solid angle and path guiding learned over the first
    /// quarter of the samples.
    Guided,
    /// The path tracer without the caustic paths, rectangle lights sampled by solid angle
    /// near them, plus a light tracer for the caustic paths (`light_tracing.rs`): light that
    /// reached opaque surfaces through glass.
    Caustic,
}

impl Integrator {
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Plain => "plain",
            Integrator::SolidAngle => "solid-angle",
            Integrator::Guided => "guided",
            Integrator::Caustic => "caustic",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        match name {
            "plain" => Some(Integrator::Plain),
            "solid-angle" => Some(Integrator::SolidAngle),
            "guided" => Some(Integrator::Guided),
            "caustic" => Some(Integrator::Caustic),
            _ => None,
        }
    }
}

/// How wide, in photon radii, a blurred view's footprint must be for a path to take all
/// scattered light at its first opaque vertex from the global photons: narrower, the
/// photons' noise is not averaged away (the frosted cylinder, alpha 0.02, close to what it
/// shows) and merging only the caustics does better.
const GATHER_FOOTPRINT_IN_RADII: f32 = 4.0;

/// Share of a guided vertex's samples drawn from the learned distribution (the rest from
/// the BSDF); Müller et al. use one half.
const GUIDED_FRACTION: f32 = 0.25;

/// What a path reads besides the scene (learned guiding, photons) and records into.
#[derive(Default)]
pub struct Guide<'a> {
    /// The distribution learned so far; `None` samples BSDFs only.
    pub tree: Option<&'a SdTree>,
    /// Where to leave records while learning.
    pub records: Option<&'a mut Vec<GuidingRecord>>,
    /// Photons of caustics seen through glass (`photon_merging.rs`): with them, the
    /// `caustic` estimator's path tracer leaves those paths to the photons' density estimate.
    pub photons: Option<&'a PhotonMap>,
    /// Photons of all light that scattered (`photon_merging.rs`): with them, a path whose
    /// view is blurred by rough glass takes everything but direct light at its first opaque
    /// vertex from their density estimate and ends there.
    pub global_photons: Option<&'a PhotonMap>,
}

/// Reusable per-thread storage for [`PreparedScene::trace_path`].
#[derive(Default)]
pub struct PathScratch {
    pub(crate) hits: Vec<Hit>,
    vertices: Vec<PendingRecord>,
    photons_found: Vec<u32>,
}

/// A guided vertex waiting for its path to end to learn the radiance that came back.
#[derive(Clone, Copy)]
struct PendingRecord {
    position: Vec3,
    direction: Vec3,
    /// The path's radiance when this vertex scattered, and its throughput just after.
    radiance_before: Vec3,
    throughput_after: Vec3,
    pdf: f32,
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
pub(crate) const MAX_VERTICES: u32 = 4096;

impl<'a> PreparedScene<'a> {
    /// Ready for the default estimator's light sampling.
    pub fn new(scene: &'a Scene) -> Self {
        Self::for_integrator(scene, Integrator::default())
    }

    pub fn for_integrator(scene: &'a Scene, integrator: Integrator) -> Self {
        let solid_angle = matches!(integrator, Integrator::SolidAngle | Integrator::Guided | Integrator::Caustic);
        let lights = LightSampler::new(scene, solid_angle, integrator == Integrator::Caustic);
        let geometry = SceneGeometry::build(scene, &|owner, index| lights.emitter_of(owner, index));
        PreparedScene { scene, geometry, lights }
    }

    /// The closest surface along `ray` (no minimum distance).
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        self.intersect_from(ray.origin, ray.direction, 0.0, f32::INFINITY)
    }

    pub(crate) fn intersect_from(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<SurfaceHit> {
        count_ray();
        let hit = self.geometry.closest_hit(origin, direction, t_min, t_max)?;
        Some(self.surface_hit(&hit))
    }

    fn surface_hit(&self, hit: &Hit) -> SurfaceHit {
        let a = &self.geometry.attributes[hit.triangle as usize];
        let b0 = 1.0 - hit.b1 - hit.b2;
        let [p0, p1, p2] = a.positions;
        let position = p0 * b0 + p1 * hit.b1 + p2 * hit.b2;
        let mut geometric_normal = (p1 - p0).cross(p2 - p0).normalize();
        let shading_normal = match a.normals {
            Some([n0, n1, n2]) => (n0 * b0 + n1 * hit.b1 + n2 * hit.b2).normalize_or(geometric_normal),
            None => geometric_normal,
        };
        if geometric_normal.dot(shading_normal) < 0.0 {
            geometric_normal = -geometric_normal;
        }
        let [t0, t1, t2] = a.uvs;
        SurfaceHit { position, distance: hit.t, geometric_normal, shading_normal, uv: t0 * b0 + t1 * hit.b1 + t2 * hit.b2, owner: a.owner, emitter: a.emitter }
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

    /// Radiance arriving at the camera along `ray`, one path sample.
    /// With `stratified`, the first vertices' light and BSDF samples come from it (see
    /// [`crate::qmc`]), the other random numbers from `rng`.
    pub fn trace_path(
        &self,
        ray: &Ray,
        rng: &mut Pcg32,
        stratified: Option<&StratifiedSample>,
        settings: &PathSettings,
        guide: &mut Guide,
        scratch: &mut PathScratch,
    ) -> PathRadiance {
        scratch.vertices.clear();
        let (radiance, counted) = self.trace_path_inner(ray, rng, stratified, settings, guide, scratch);
        if let Some(records) = guide.records.as_deref_mut() {
            for v in &scratch.vertices {
                // Radiance that arrived along the sampled direction: what the path gathered
                // after this vertex, divided by the throughput it had then.
                let gathered = radiance - v.radiance_before;
                let incident = Vec3::select(v.throughput_after.cmpgt(Vec3::ZERO), gathered / v.throughput_after, Vec3::ZERO);
                let value = luminance(incident).max(0.0) / v.pdf;
                records.push(GuidingRecord { position: v.position, direction: v.direction, value: if value.is_finite() { value } else { 0.0 } });
            }
        }
        PathRadiance { all: radiance, counted }
    }

    fn trace_path_inner(
        &self,
        ray: &Ray,
        rng: &mut Pcg32,
        stratified: Option<&StratifiedSample>,
        settings: &PathSettings,
        guide: &Guide,
        scratch: &mut PathScratch,
    ) -> (Vec3, Vec3) {
        // A 2D value of stratified dimension `dimension` if there is one, else from `rng`.
        let draw_2d = |rng: &mut Pcg32, dimension: Option<u32>| match (stratified, dimension) {
            (Some(sample), Some(d)) => sample.get_2d(d),
            _ => rng.next_vec2(),
        };
        let background = self.scene.background;
        let mut radiance = Vec3::ZERO;
        // The part of `radiance` that `settings.path_filter` counts.
        let mut counted = Vec3::ZERO;
        let filter = settings.path_filter;
        let mut throughput = Vec3::ONE;
        let mut origin = ray.origin;
        let mut direction = ray.direction;
        let mut t_min = 0.0;
        // Segments so far, counting the one being traced.
        let mut depth = 1u32;
        // Product of the IOR ratios crossed, squared, undoing the radiance scaling of
        // refraction for Russian roulette.
        let mut eta_scale = 1.0f32;
        // MIS state: whether the path since its last non-delta vertex is something only BSDF
        // sampling can produce, that vertex, and the density of reaching here from it.
        let mut specular = true;
        let mut mis_origin = origin;
        let mut mis_pdf = 0.0f32;
        // Which of the light tracer's paths this one may become.
        let mut class = PathClass::default();
        let split = settings.leave_caustics_to_light_tracing;
        let merging = split && guide.photons.is_some();
        // The path has taken all light that scattered after its first opaque vertex from the
        // global photons: what is left to find is light straight from an emitter (through
        // panes at most).
        let mut gathered = false;
        // The path took the caustics at its first opaque vertex from the caustic photons: the
        // paths they carry are left out below.
        let mut caustics_merged = false;
        // (GGX alpha, distance since): see where it is updated.
        let mut blur = (0.0f32, 0.0f32);
        // The same for a view that met an opaque surface first: that surface's narrowest
        // lobe and the distance since it.
        let mut straight_blur: Option<(f32, f32)> = None;

        for vertex in 0..MAX_VERTICES {
            let Some(hit) = self.intersect_from(origin, direction, t_min, f32::INFINITY) else {
                let light = throughput * background;
                radiance += light;
                if filter.counts(class.view_bent(None)) {
                    counted += light;
                }
                break;
            };
            let wo = -direction;

            if let Some(emitter) = hit.emitter {
                let emitted = self.lights.emitters[emitter as usize].emitted(wo);
                if emitted != Vec3::ZERO && !(split && class.light_traced()) && !(caustics_merged && class.merged()) {
                    let weight = if specular { 1.0 } else { power_heuristic(mis_pdf, self.lights.pdf(emitter, mis_origin, hit.position)) };
                    let light = throughput * emitted * weight;
                    radiance += light;
                    if filter.counts(class.view_bent(None)) {
                        counted += light;
                    }
                }
            }
            let Owner::Object { material, .. } = hit.owner else { break };
            let surface = self.surface_material(material, hit.uv);
            let bsdf = Bsdf::new(&surface, hit.shading_normal, settings.material_model);
            if depth >= settings.max_depth {
                break;
            }
            let glass = bsdf.is_glass();
            if gathered && !glass {
                break;
            }
            // Photon merging at the first opaque vertex of a bent view: where the view is
            // blurred, of all the light there that scattered since the light (the path then only
            // looks for direct light, by next-event estimation and MIS-weighted BSDF sampling),
            // otherwise of the caustics.
            let merge_here = merging && class.first_opaque_of_bent_view(glass);
            blur.1 += hit.distance;
            if let Some(straight) = &mut straight_blur {
                straight.1 += hit.distance;
            }
            // The view's footprint here, about the lobe's angular width (2 alpha for a
            // refraction through a GGX lobe) times the distance: gather where it spans several
            // photon radii, so that the pixel averages the photons' noise over many disks.
            let spans_radii = |(alpha, distance): (f32, f32), photons: &PhotonMap| 2.0 * alpha * distance >= GATHER_FOOTPRINT_IN_RADII * photons.radius();
            // A final gather: at the second opaque vertex of a straight view, seen from a
            // surface whose lobes all blur it over several radii. The light tracer's paths
            // (the light's first opaque vertex after bending glass) stay with it.
            let final_gather = merging && class.second_opaque_of_straight_view(glass);
            let global = guide.global_photons.filter(|photons| {
                bsdf.suits_merging()
                    && ((merge_here && spans_radii(blur, photons)) || (final_gather && straight_blur.is_some_and(|straight| spans_radii(straight, photons))))
            });
            // Caustics only on a surface that suits merging: on a narrow lobe (chrome) the odd
            // photon's f is huge, and BSDF sampling finds the same light well.
            let caustic_merge = merge_here && global.is_none() && bsdf.suits_merging();
            caustics_merged |= caustic_merge && guide.photons.is_some();
            if let Some(photons) = global.or(guide.photons.filter(|_| caustic_merge)) {
                let u_subset = rng.next_f32();
                let query = MergeQuery {
                    position: hit.position,
                    normal: hit.geometric_normal,
                    wo,
                    max_segments: settings.max_depth - depth,
                    skip_caustic_starts: !merge_here,
                };
                let light = throughput * photons.radiance(&query, &bsdf, u_subset, &mut scratch.photons_found);
                radiance += light;
                if filter.counts(class.view_bent(None)) {
                    counted += light;
                }
            }
            class.enter_vertex(glass);
            if merging && !glass && class.at_first_opaque_of_straight_view() {
                straight_blur = bsdf.suits_merging().then(|| (bsdf.base_alpha(), 0.0));
            }
            // Segments a shadow ray from here may still cross panes with: a path of
            // `depth + 1 + crossings` segments must fit, as the BSDF-sampled one must.
            let crossings_allowed = settings.max_depth - depth - 1;
            let ng = hit.geometric_normal;
            let wo_side = wo.dot(ng);

            // The learned distribution here, if this vertex is one to guide.
            let guided = match guide.tree {
                Some(tree) if bsdf.suits_guiding() => tree.directions_at(hit.position),
                _ => None,
            };

            // Next-event estimation.
            // Shadow rays from here that the light tracer or the photons take instead.
            let shadow_ray_left_out = (split && class.light_traced_by_shadow_ray(glass)) || (caustics_merged && class.merged_by_shadow_ray(glass));
            if !gathered && bsdf.has_non_delta() && !shadow_ray_left_out {
                let u_select = rng.next_f32();
                let u_light = draw_2d(rng, qmc::light_dimension(vertex));
                if let Some(light) = self.lights.sample(hit.position, u_select, u_light) {
                    let wi = light.wi;
                    let reflection = wi.dot(ng) * wo_side > 0.0;
                    let (f, pdf) = bsdf.eval_pdf(wo, wi);
                    let shading_reflection = wi.dot(hit.shading_normal) * wo.dot(hit.shading_normal) > 0.0;
                    if f != Vec3::ZERO && reflection == shading_reflection {
                        // Aim from the offset origin itself: reusing wi from the surface point
                        // would cross the light's plane short of the sampled point and hit the
                        // light itself at grazing angles.
                        let shadow_origin = offset_origin(hit.position, ng, wi);
                        let to_light = light.point - shadow_origin;
                        let shadow_distance = to_light.length();
                        let t_max = shadow_distance * (1.0 - 1e-4) - ray_epsilon(light.point);
                        if let Some((transmittance, crossing_probability)) =
                            self.transmittance(shadow_origin, to_light / shadow_distance, t_max, crossings_allowed, settings, &mut scratch.hits)
                        {
                            let bsdf_pdf = guided_pdf(guided, pdf, wi) * crossing_probability;
                            let weight = power_heuristic(light.pdf, bsdf_pdf);
                            let cos = wi.dot(hit.shading_normal).abs();
                            let light = throughput * f * cos * transmittance * light.radiance * (weight / light.pdf);
                            radiance += light;
                            if filter.counts(class.view_bent(Some(glass))) {
                                counted += light;
                            }
                        }
                    }
                }
            }

            // Continue the path.
            // Drawn only at guided vertices, so the plain estimator's random streams are
            // what they always were.
            let u_guide = if guided.is_some() { rng.next_f32() } else { 1.0 };
            let u_lobe = rng.next_f32();
            let u_event = rng.next_f32();
            let u = draw_2d(rng, qmc::bsdf_dimension(vertex));
            let sample = match guided {
                Some(directions) => {
                    // One sample of the mixture: the learned light or the BSDF, then the
                    // mixture's density for the weight.
                    let wi = if u_guide < GUIDED_FRACTION {
                        directions.sample(u).0
                    } else {
                        let Some(s) = bsdf.sample(wo, u_lobe, u_event, u) else { break };
                        s.wi
                    };
                    let (f, bsdf_pdf) = bsdf.eval_pdf(wo, wi);
                    let pdf = GUIDED_FRACTION * directions.pdf(wi) + (1.0 - GUIDED_FRACTION) * bsdf_pdf;
                    if pdf.is_nan() || pdf <= 0.0 || f == Vec3::ZERO {
                        break;
                    }
                    let transmitted = wi.dot(hit.shading_normal) * wo.dot(hit.shading_normal) < 0.0;
                    let weight = f * wi.dot(hit.shading_normal).abs() / pdf;
                    BsdfSample { wi, weight, pdf, delta: false, transmitted, etap: 1.0, pass_through: false }
                }
                None => {
                    let Some(s) = bsdf.sample(wo, u_lobe, u_event, u) else { break };
                    s
                }
            };
            let reflection = sample.wi.dot(ng) * wo_side > 0.0;
            if reflection == sample.transmitted && !sample.delta {
                // The shading normal claims a side the geometry contradicts: following the
                // ray would leak light through the surface. (Delta events of glass keep
                // going: the next hit reads the side from the geometry, so nothing leaks,
                // and ending them would darken smooth glass by a fraction of a percent.)
                break;
            }
            if gathered && !sample.pass_through {
                break;
            }
            gathered |= global.is_some();
            throughput *= sample.weight;
            class.leave_vertex(glass, sample.pass_through);
            // The blur of the view: the widest rough glass lobe passed before anything opaque,
            // and the distance travelled since.
            if merging && !class.seen_opaque() {
                if let Some(alpha) = bsdf.rough_glass_alpha().filter(|_| !sample.delta) {
                    blur = (blur.0.max(alpha), 0.0);
                }
            }
            if guide.records.is_some() && bsdf.suits_guiding() {
                scratch.vertices.push(PendingRecord {
                    position: hit.position,
                    direction: sample.wi,
                    radiance_before: radiance,
                    throughput_after: throughput,
                    pdf: sample.pdf,
                });
            }
            if sample.transmitted && sample.etap != 1.0 {
                eta_scale *= sample.etap * sample.etap;
            }
            depth += 1;
            if sample.pass_through {
                mis_pdf *= sample.pdf;
            } else {
                specular = sample.delta;
                mis_pdf = sample.pdf;
                mis_origin = hit.position;
            }
            origin = offset_origin(hit.position, ng, sample.wi);
            direction = sample.wi;
            t_min = 0.0;

            if throughput == Vec3::ZERO {
                break;
            }
            if depth > settings.rr_depth {
                let survival = (throughput.max_element() * eta_scale).min(0.95);
                if rng.next_f32() >= survival {
                    break;
                }
                throughput /= survival;
            }
        }
        (radiance, counted)
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

/// The density of a direction under the sampling a vertex uses: the BSDF's alone, or its
/// mixture with the learned distribution.
fn guided_pdf(guided: Option<&crate::guiding::DirectionalTree>, bsdf_pdf: f32, wi: Vec3) -> f32 {
    match guided {
        Some(directions) => GUIDED_FRACTION * directions.pdf(wi) + (1.0 - GUIDED_FRACTION) * bsdf_pdf,
        None => bsdf_pdf,
    }
}

/// Distance by which new rays start off a surface, relative to the scene's magnitude at
/// that point (f32 positions carry about 7 significant digits).
fn ray_epsilon(p: Vec3) -> f32 {
    1e-4 * p.abs().max_element().max(1.0)
}

/// A ray origin just off the surface at `p`, on the side `direction` leaves to.
pub fn offset_origin(p: Vec3, geometric_normal: Vec3, direction: Vec3) -> Vec3 {
    let side = if direction.dot(geometric_normal) >= 0.0 { 1.0 } else { -1.0 };
    p + geometric_normal * (side * ray_epsilon(p))
}
