//! Scattering at a surface point: glTF metallic-roughness (Lambertian diffuse + GGX
//! specular over a dielectric base whose strength and F0 colour KHR_materials_specular sets,
//! a GGX conductor for metals, lerped by `metallic`), mixed
//! by `transmission.weight` with one of three dielectrics: smooth (Fresnel + Snell), rough
//! (GGX microfacet transmission, Walter et al. 2007) and thin (a pane; both faces, internal
//! reflections summed, no offset).
//!
//! Everything works in the local shading frame (normal = +z, pointing to the outside of the
//! surface as the mesh's vertex normals say). `wo` points to where light goes (towards the
//! camera), `wi` to where it comes from. `eval` returns the BSDF value f(wo, wi) in radiance
//! form (transmission into a denser medium is scaled by 1/eta^2), so the integrator
//! multiplies by |cos(wi)| itself.
//!
//! Rough thin panes (roughness above `SMOOTH_ROUGHNESS`): a thin slab whose two faces carry
//! the same microfacet roughness has no single correct single-scattering model. We use the
//! GGX reflection lobe with the slab's summed reflectance R'(wo.m), and for transmission the
//! same lobe mirrored through the pane's plane, weighted by 1 - R' (glTF
//! KHR_materials_transmission defines its thin-walled BTDF the same way: the half vector of
//! the mirrored light direction). So a rough pane blurs what is seen through it exactly as
//! much as it blurs reflections, conserves energy like the GGX reflection lobe, and becomes
//! the smooth pane (straight through, no offset) as roughness goes to zero.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};
use glassbake_scene::model::SMOOTH_ROUGHNESS;
use glassbake_scene::Transmission;

use crate::microfacet::{fresnel_dielectric, reflect, refract, schlick, thin_slab_reflectance, Ggx};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, luminance, Frame};

/// Specular reflectance at normal incidence of glTF's dielectric base (IOR 1.5).
pub use glassbake_core::wgsl::DIELECTRIC_F0;
/// Opaque GGX lobes never go below this alpha: a mirror-like opaque surface stays a (very
/// narrow) microfacet lobe, which NEE and MIS handle, instead of becoming a delta.
pub const MIN_OPAQUE_ALPHA: f32 = 1e-3;

/// Narrowest specular lobe (GGX alpha; roughness 0.3) of a surface that photon merging
/// gathers all scattered light at: below, a chrome fitting's lobe (roughness 0.12) turned
/// single photons into fireflies in the bathroom.
pub const MIN_MERGING_ALPHA: f32 = 0.09;

/// How materials are interpreted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaterialModel {
    /// glTF 2.0 metallic-roughness with KHR_materials_transmission / ior (the default).
    #[default]
    Gltf,
    /// Every surface is Lambertian with its (textured) base colour and nothing else: a
    /// debugging aid and what the white-furnace tests need.
    Lambertian,
}

/// Material parameters at one surface point, textures applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceMaterial {
    pub base_color: Vec3,
    /// Perceptual roughness (alpha = roughness^2).
    pub roughness: f32,
    pub metallic: f32,
    /// KHR_materials_specular: the specular layer's strength (0 = Lambertian base) and F0
    /// tint, textures applied.
    pub specular: f32,
    pub specular_color: Vec3,
    pub transmission: Option<Transmission>,
}

impl SurfaceMaterial {
    /// A material without a specular extension (specular 1, white specular colour).
    pub fn new(base_color: Vec3, roughness: f32, metallic: f32, transmission: Option<Transmission>) -> Self {
        SurfaceMaterial { base_color, roughness, metallic, specular: 1.0, specular_color: Vec3::ONE, transmission }
    }
}

#[derive(Clone, Copy, Debug)]
enum Dielectric {
    None,
    Smooth { eta: f32, tint: Vec3 },
    Rough { eta: f32, tint: Vec3, ggx: Ggx },
    ThinSmooth { eta: f32, tint: Vec3 },
    ThinRough { eta: f32, tint: Vec3, ggx: Ggx },
}

impl Dielectric {
    fn is_delta(&self) -> bool {
        matches!(self, Dielectric::Smooth { .. } | Dielectric::ThinSmooth { .. })
    }
}

/// The BSDF at one surface point.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    pub frame: Frame,
    base_color: Vec3,
    ggx: Ggx,
    lambertian: bool,
    /// Mixture weights of the dielectric base (diffuse + specular), the conductor and the
    /// transmissive dielectric; they sum to 1.
    base_weight: f32,
    /// The dielectric base's specular layer: F0 colour (0.04 x specular colour, at most 1)
    /// and the layer's weight (glTF's fresnel_mix).
    specular_f0: Vec3,
    specular_weight: f32,
    metal_weight: f32,
    glass_weight: f32,
    dielectric: Dielectric,
}

/// Where light passing smooth glass at a given `wo` comes from ([`Bsdf::delta_continuation`]).
#[derive(Clone, Copy, Debug)]
pub struct DeltaContinuation {
    /// World space, unit length.
    pub wi: Vec3,
    /// Fraction of the radiance arriving along `wi` that leaves along `wo`.
    pub fraction: Vec3,
    /// Probability that [`Bsdf::sample`] picks this event.
    pub probability: f32,
    /// Turned by solid glass: refracted, or totally reflected inside it (a thin pane's
    /// transmission goes straight on).
    pub bends: bool,
    /// Total internal reflection (otherwise a transmission).
    pub reflected: bool,
}

/// A sampled incident direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// World space, unit length.
    pub wi: Vec3,
    /// f(wo, wi) |cos(wi)| / pdf, in radiance form.
    pub weight: Vec3,
    /// Solid-angle density of the non-delta lobes for non-delta samples; for delta samples
    /// the discrete probability of the chosen event (used only by the pass-through MIS).
    pub pdf: f32,
    pub delta: bool,
    /// wi is on the other side of the surface from wo.
    pub transmitted: bool,
    /// Relative IOR eta_t / eta_i crossed (1 for reflection and thin panes).
    pub etap: f32,
    /// Straight through a smooth thin pane (wi = -wo): shadow rays can follow this path
    /// too, so MIS treats it as a null event.
    pub pass_through: bool,
}

impl Bsdf {
    /// `normal` is the unit shading normal, pointing to the outside of the surface.
    pub fn new(material: &SurfaceMaterial, normal: Vec3, model: MaterialModel) -> Self {
        let frame = Frame::from_normal(normal);
        let base_color = material.base_color.max(Vec3::ZERO);
        let roughness = material.roughness.clamp(0.0, 1.0);
        let ggx = Ggx::new((roughness * roughness).max(MIN_OPAQUE_ALPHA));
        if model == MaterialModel::Lambertian {
            return Bsdf {
                frame,
                base_color,
                ggx,
                lambertian: true,
                base_weight: 1.0,
                specular_f0: Vec3::ZERO,
                specular_weight: 0.0,
                metal_weight: 0.0,
                glass_weight: 0.0,
                dielectric: Dielectric::None,
            };
        }
        let metallic = material.metallic.clamp(0.0, 1.0);
        let (transmission_weight, dielectric) = match material.transmission {
            Some(t) if t.weight > 0.0 => {
                let eta = if t.ior > 0.0 && t.ior.is_finite() { t.ior } else { 1.5 };
                let tint = base_color;
                let smooth = roughness < SMOOTH_ROUGHNESS;
                let glass_ggx = Ggx::new(roughness * roughness);
                let d = match (t.thin, smooth) {
                    (false, true) => Dielectric::Smooth { eta, tint },
                    (false, false) => Dielectric::Rough { eta, tint, ggx: glass_ggx },
                    (true, true) => Dielectric::ThinSmooth { eta, tint },
                    (true, false) => Dielectric::ThinRough { eta, tint, ggx: glass_ggx },
                };
                (t.weight.min(1.0), d)
            }
            _ => (0.0, Dielectric::None),
        };
        Bsdf {
            frame,
            base_color,
            ggx,
            lambertian: false,
            base_weight: (1.0 - metallic) * (1.0 - transmission_weight),
            specular_f0: (DIELECTRIC_F0 * material.specular_color.max(Vec3::ZERO)).min(Vec3::ONE),
            specular_weight: material.specular.clamp(0.0, 1.0),
            metal_weight: metallic,
            glass_weight: (1.0 - metallic) * transmission_weight,
            dielectric,
        }
    }

    /// Whether some lobe is not a Dirac delta (so light sampling can help).
    pub fn has_non_delta(&self) -> bool {
        self.base_weight > 0.0
            || self.metal_weight > 0.0
            || (self.glass_weight > 0.0 && !matches!(self.dielectric, Dielectric::None) && !self.dielectric.is_delta())
    }

    /// Whether the surface has a transmissive dielectric lobe (glass, smooth or rough, thin
    /// or solid): the light tracer's split of paths (`light_tracing.rs`) reads it.
    pub fn is_glass(&self) -> bool {
        self.glass_weight > 0.0 && !matches!(self.dielectric, Dielectric::None)
    }

    /// GGX alpha of a rough dielectric lobe (rough glass, solid or thin), if there is one.
    pub fn rough_glass_alpha(&self) -> Option<f32> {
        match self.dielectric {
            Dielectric::Rough { ggx, .. } | Dielectric::ThinRough { ggx, .. } if self.glass_weight > 0.0 => Some(ggx.alpha),
            _ => None,
        }
    }

    /// Whether a density estimate of photons suits this surface: it is mostly the diffuse
    /// base, and the base's specular lobe is not narrow (alpha >= [`MIN_MERGING_ALPHA`]).
    /// On a narrow lobe the few photons that arrive along it carry f values far above the
    /// rest, and each becomes a firefly.
    pub fn suits_merging(&self) -> bool {
        self.lambertian || (self.base_weight >= 0.5 && self.ggx.alpha >= MIN_MERGING_ALPHA)
    }

    /// The GGX alpha of the base's specular lobe (1 for a Lambertian surface): how narrow
    /// the narrowest lobe of a surface that [`Bsdf::suits_merging`] is.
    pub fn base_alpha(&self) -> f32 {
        if self.lambertian {
            1.0
        } else {
            self.ggx.alpha
        }
    }

    /// Probabilities of picking the diffuse, specular (base), conductor and dielectric lobes
    /// when sampling from `wo` (local).
    fn lobe_probabilities(&self, wo: Vec3) -> [f32; 4] {
        if self.lambertian {
            return [1.0, 0.0, 0.0, 0.0];
        }
        let cos_o = wo.z.abs();
        let fresnel = self.specular_weight * schlick(self.specular_f0, cos_o).max_element();
        let diffuse = self.base_weight * (1.0 - fresnel) * luminance(self.base_color);
        let specular = self.base_weight * fresnel;
        let glass = if matches!(self.dielectric, Dielectric::None) { 0.0 } else { self.glass_weight };
        let p = [diffuse, specular, self.metal_weight, glass];
        let sum: f32 = p.iter().sum();
        if sum > 0.0 {
            p.map(|x| x / sum)
        } else {
            [0.0; 4]
        }
    }

    /// f(wo, wi), world space, excluding delta lobes.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// Solid-angle density with which `sample` produces `wi` through its non-delta lobes.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// `eval` and `pdf` at once, cheaper than both.
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.eval_pdf_local(self.frame.to_local(wo), self.frame.to_local(wi))
    }

    /// If this surface is a smooth thin pane (at least partly), the attenuation of light
    /// passing straight through it along -wo, and the probability that `sample` picks that
    /// event.
    pub fn pass_through(&self, wo: Vec3) -> Option<(Vec3, f32)> {
        let Dielectric::ThinSmooth { eta, tint } = self.dielectric else { return None };
        if self.lambertian || self.glass_weight <= 0.0 {
            return None;
        }
        let wo_local = self.frame.to_local(wo);
        let transmitted = 1.0 - thin_slab_reflectance(wo_local.z, eta);
        let p = self.lobe_probabilities(wo_local)[3];
        Some((self.glass_weight * tint * transmitted, p * transmitted))
    }

    /// The mirror reflection of a smooth dielectric lobe (solid glass or a thin pane) at
    /// `wo`: its direction and the fraction of the light arriving along it that the surface
    /// sends to `wo` (the lobe's weight times its Fresnel reflectance), which is what
    /// [`Bsdf::sample`]'s delta reflection returns on average. `None` without such a lobe.
    pub fn delta_reflection(&self, wo: Vec3) -> Option<(Vec3, f32)> {
        let wo_local = self.frame.to_local(wo);
        if wo_local.z == 0.0 || self.lambertian || self.lobe_probabilities(wo_local)[3] <= 0.0 {
            return None;
        }
        let reflectance = match self.dielectric {
            Dielectric::Smooth { eta, .. } => fresnel_dielectric(wo_local.z, eta),
            Dielectric::ThinSmooth { eta, .. } => thin_slab_reflectance(wo_local.z, eta),
            _ => return None,
        };
        let wi = Vec3::new(-wo_local.x, -wo_local.y, wo_local.z);
        Some((self.frame.to_world(wi).normalize(), self.glass_weight * reflectance))
    }

    /// How light passes a surface that is smooth glass alone (solid or a thin pane, no
    /// non-delta lobe) to leave along `wo`: by transmission, or by total internal reflection
    /// where nothing is transmitted. The direction [`Bsdf::sample`] takes for that event, the
    /// fraction of the light arriving along it that reaches `wo` (what the sampled event
    /// returns on average: the lobe's weight x tint x (1 - Fresnel reflectance), radiance
    /// scaled by the IOR ratio; the lobe's weight under total internal reflection), and the
    /// probability with which `sample` picks it. `None` for any other surface.
    pub fn delta_continuation(&self, wo: Vec3) -> Option<DeltaContinuation> {
        let wo_local = self.frame.to_local(wo);
        if wo_local.z == 0.0 || self.has_non_delta() || !self.is_glass() {
            return None;
        }
        let p = self.lobe_probabilities(wo_local)[3];
        if p <= 0.0 {
            return None;
        }
        let event = |wi_local: Vec3, fraction: Vec3, probability: f32, bends: bool, reflected: bool| DeltaContinuation {
            wi: self.frame.to_world(wi_local).normalize(),
            fraction: self.glass_weight * fraction,
            probability: p * probability,
            bends,
            reflected,
        };
        match self.dielectric {
            Dielectric::Smooth { eta, tint } => {
                let reflectance = fresnel_dielectric(wo_local.z, eta);
                if reflectance >= 1.0 {
                    return Some(event(Vec3::new(-wo_local.x, -wo_local.y, wo_local.z), Vec3::ONE, 1.0, true, true));
                }
                let (wi, etap) = refract(wo_local, Vec3::Z, eta)?;
                Some(event(wi, tint * ((1.0 - reflectance) / (etap * etap)), 1.0 - reflectance, true, false))
            }
            Dielectric::ThinSmooth { eta, tint } => {
                let reflectance = thin_slab_reflectance(wo_local.z, eta);
                (reflectance < 1.0).then(|| event(-wo_local, tint * (1.0 - reflectance), 1.0 - reflectance, false, false))
            }
            _ => None,
        }
    }

    pub fn sample(&self, wo: Vec3, u_lobe: f32, u_event: f32, u: Vec2) -> Option<BsdfSample> {
        let wo_local = self.frame.to_local(wo);
        if wo_local.z == 0.0 {
            return None;
        }
        let p = self.lobe_probabilities(wo_local);
        let side = wo_local.z.signum();
        let mirror = |w: Vec3| Vec3::new(w.x, w.y, w.z * side);
        let wi_local = if u_lobe < p[0] {
            mirror(cosine_hemisphere(u))
        } else if u_lobe < p[0] + p[1] + p[2] {
            let o = mirror(wo_local);
            let m = self.ggx.sample_visible(o, u);
            let i = reflect(o, m);
            if i.z <= 0.0 {
                return None;
            }
            mirror(i)
        } else {
            match self.dielectric {
                Dielectric::None => return None,
                Dielectric::Smooth { eta, tint } => {
                    let reflectance = fresnel_dielectric(wo_local.z, eta);
                    let scale = self.glass_weight / p[3];
                    if u_event < reflectance {
                        let wi = Vec3::new(-wo_local.x, -wo_local.y, wo_local.z);
                        return Some(self.delta_sample(wo_local.z, wi, Vec3::splat(scale), p[3] * reflectance, 1.0, false));
                    }
                    let (wi, etap) = refract(wo_local, Vec3::Z, eta)?;
                    let weight = scale * tint / (etap * etap);
                    return Some(self.delta_sample(wo_local.z, wi, weight, p[3] * (1.0 - reflectance), etap, false));
                }
                Dielectric::ThinSmooth { eta, tint } => {
                    let reflectance = thin_slab_reflectance(wo_local.z, eta);
                    let scale = self.glass_weight / p[3];
                    if u_event < reflectance {
                        let wi = Vec3::new(-wo_local.x, -wo_local.y, wo_local.z);
                        return Some(self.delta_sample(wo_local.z, wi, Vec3::splat(scale), p[3] * reflectance, 1.0, false));
                    }
                    return Some(self.delta_sample(wo_local.z, -wo_local, scale * tint, p[3] * (1.0 - reflectance), 1.0, true));
                }
                Dielectric::Rough { eta, ggx, .. } => {
                    // Visible normals of the side wo is on; m is then flipped to face +z.
                    let o = wo_local * side;
                    let m = ggx.sample_visible(o, u);
                    let reflectance = fresnel_dielectric(wo_local.dot(m), eta);
                    if u_event < reflectance {
                        let wi = reflect(wo_local, m);
                        if wi.z * wo_local.z <= 0.0 {
                            return None;
                        }
                        wi
                    } else {
                        let (wi, _) = refract(wo_local, m, eta)?;
                        if wi.z * wo_local.z >= 0.0 {
                            return None;
                        }
                        wi
                    }
                }
                Dielectric::ThinRough { eta, ggx, .. } => {
                    let o = mirror(wo_local);
                    let m = ggx.sample_visible(o, u);
                    let i = reflect(o, m);
                    if i.z <= 0.0 {
                        return None;
                    }
                    if u_event < thin_slab_reflectance(o.dot(m), eta) {
                        mirror(i)
                    } else {
                        mirror(Vec3::new(i.x, i.y, -i.z))
                    }
                }
            }
        };
        let (f, pdf) = self.eval_pdf_local(wo_local, wi_local);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let transmitted = wi_local.z * wo_local.z < 0.0;
        let etap = match self.dielectric {
            Dielectric::Rough { eta, .. } if transmitted => {
                if wo_local.z > 0.0 {
                    eta
                } else {
                    1.0 / eta
                }
            }
            _ => 1.0,
        };
        Some(BsdfSample {
            wi: self.frame.to_world(wi_local).normalize(),
            weight: f * wi_local.z.abs() / pdf,
            pdf,
            delta: false,
            transmitted,
            etap,
            pass_through: false,
        })
    }

    fn delta_sample(&self, wo_z: f32, wi_local: Vec3, weight: Vec3, probability: f32, etap: f32, pass_through: bool) -> BsdfSample {
        BsdfSample {
            wi: self.frame.to_world(wi_local).normalize(),
            weight,
            pdf: probability,
            delta: true,
            transmitted: wi_local.z * wo_z < 0.0,
            etap,
            pass_through,
        }
    }

    /// f(wo, wi) of the non-delta lobes and the density with which `sample` produces wi,
    /// together: they share the half vector, D and the Fresnel terms.
    fn eval_pdf_local(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z == 0.0 || wi.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let p = self.lobe_probabilities(wo);
        let mut f = Vec3::ZERO;
        let mut pdf = 0.0;
        if wo.z * wi.z > 0.0 {
            // The opaque lobes are two-sided: mirror both directions to the upper side.
            let (o, i) = (Vec3::new(wo.x, wo.y, wo.z.abs()), Vec3::new(wi.x, wi.y, wi.z.abs()));
            pdf += p[0] * cosine_hemisphere_pdf(i.z);
            if self.lambertian {
                return (self.base_color * FRAC_1_PI, pdf);
            }
            let h = (o + i).normalize_or_zero();
            let opaque = self.base_weight > 0.0 || self.metal_weight > 0.0;
            if h != Vec3::ZERO && (opaque || p[1] + p[2] > 0.0) {
                let d = self.ggx.d(h);
                let cos_oh = o.dot(h);
                if opaque {
                    let specular = d * self.ggx.g2(o, i) / (4.0 * o.z * i.z);
                    if self.base_weight > 0.0 {
                        // glTF's fresnel_mix of the diffuse base and the specular layer,
                        // except that the diffuse part is weighted by the Fresnel term of
                        // the view angle, 1 - F(wo.n), rather than of each microfacet,
                        // 1 - F(wo.h): with F(wo.h) a white base reflects up to 15% more
                        // than it receives at grazing angles.
                        // KHR_materials_specular scales the layer by its weight and tints F0;
                        // the diffuse part keeps what the strongest channel leaves.
                        let diffuse_fresnel = self.specular_weight * schlick(self.specular_f0, o.z).max_element();
                        let specular_fresnel = schlick(self.specular_f0, cos_oh) * self.specular_weight;
                        f += self.base_weight * ((1.0 - diffuse_fresnel) * self.base_color * FRAC_1_PI + specular_fresnel * specular);
                    }
                    if self.metal_weight > 0.0 {
                        f += self.metal_weight * schlick(self.base_color, cos_oh) * specular;
                    }
                }
                // Visible-normal sampling of the reflection: D_wo(h) / (4 wo.h).
                pdf += (p[1] + p[2]) * self.ggx.g1(o) * d / (4.0 * o.z);
            }
        }
        if self.glass_weight > 0.0 {
            let (fd, pd) = self.eval_pdf_dielectric(wo, wi);
            f += self.glass_weight * fd;
            pdf += p[3] * pd;
        }
        (f, pdf)
    }

    fn eval_pdf_dielectric(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self.dielectric {
            Dielectric::Rough { eta, tint, ggx } => {
                let Some((m, etap)) = dielectric_half_vector(wo, wi, eta) else { return (Vec3::ZERO, 0.0) };
                let reflectance = fresnel_dielectric(wo.dot(m), eta);
                let d = ggx.d(m);
                let g = ggx.g2(wo, wi);
                let visible = ggx.visible_pdf(wo, m);
                if etap == 1.0 {
                    let f = Vec3::splat(d * g * reflectance / (4.0 * wi.z * wo.z).abs());
                    (f, visible / (4.0 * wo.dot(m).abs()) * reflectance)
                } else {
                    // Walter et al. 2007, eq. 21, radiance form. With eta_o = 1 on wo's side,
                    // eta_o^2 / (eta_i i.m + eta_o o.m)^2 becomes 1 / (etap i.m + o.m)^2.
                    let denom = wi.dot(m) * etap + wo.dot(m);
                    let value = d * g * (1.0 - reflectance) * (wi.dot(m) * wo.dot(m) / (wi.z * wo.z)).abs() / (denom * denom);
                    // Jacobian of the refracted half vector (Walter et al. 2007, eq. 17).
                    let pdf_denom = wi.dot(m) + wo.dot(m) / etap;
                    let pdf = visible * wi.dot(m).abs() / (pdf_denom * pdf_denom) * (1.0 - reflectance);
                    (tint * value, pdf)
                }
            }
            Dielectric::ThinRough { eta, tint, ggx } => {
                let side = wo.z.signum();
                let o = Vec3::new(wo.x, wo.y, wo.z * side);
                let transmitted = wo.z * wi.z < 0.0;
                // Transmission: wi mirrored through the pane's plane, then to wo's side.
                let i = Vec3::new(wi.x, wi.y, if transmitted { -wi.z * side } else { wi.z * side });
                let h = (o + i).normalize_or_zero();
                if h == Vec3::ZERO {
                    return (Vec3::ZERO, 0.0);
                }
                let d = ggx.d(h);
                let lobe = d * ggx.g2(o, i) / (4.0 * o.z * i.z);
                let lobe_pdf = ggx.g1(o) * d / (4.0 * o.z);
                let reflectance = thin_slab_reflectance(o.dot(h), eta);
                if transmitted {
                    (tint * (lobe * (1.0 - reflectance)), lobe_pdf * (1.0 - reflectance))
                } else {
                    (Vec3::splat(lobe * reflectance), lobe_pdf * reflectance)
                }
            }
            _ => (Vec3::ZERO, 0.0),
        }
    }
}

/// The microfacet normal (facing +z) that scatters wo into wi at a rough dielectric
/// interface, and the relative IOR crossed (1 for reflection); `None` for configurations
/// no microfacet produces.
fn dielectric_half_vector(wo: Vec3, wi: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let reflect = wo.z * wi.z > 0.0;
    let etap = if reflect {
        1.0
    } else if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let mut m = wi * etap + wo;
    if m.length_squared() == 0.0 {
        return None;
    }
    m = m.normalize();
    if m.z < 0.0 {
        m = -m;
    }
    // Both directions must be on the sides of the microfacet their macro sides say.
    if m.dot(wi) * wi.z <= 0.0 || m.dot(wo) * wo.z <= 0.0 {
        return None;
    }
    Some((m, etap))
}
