//! The GGX (Trowbridge-Reitz) microfacet distribution with the height-correlated Smith
//! masking-shadowing function, visible-normal sampling, and Schlick's Fresnel term (the
//! dielectric's exact one is glassbake-rays' `optics`). All in the
//! local shading frame (normal = +z), isotropic.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

// The dielectric interface (Fresnel, Snell) is shared with the frame's refraction pass.
pub use glassbake_rays::optics::{fresnel_dielectric, reflect, refract, thin_slab_reflectance};

/// Smallest alpha we evaluate: below this, f32 GGX peaks overflow the useful range.
pub const MIN_ALPHA: f32 = 1e-4;

#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    pub fn new(alpha: f32) -> Self {
        Ggx { alpha: alpha.max(MIN_ALPHA) }
    }

    /// Normal distribution D(m) (Walter et al. 2007, eq. 33), m.z = cos(theta_m).
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let cos2 = m.z * m.z;
        let t = cos2 * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith Lambda for GGX (Heitz 2014, "Understanding the Masking-Shadowing Function").
    pub fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (1.0 - cos2).max(0.0) / cos2;
        0.5 * (-1.0 + (1.0 + self.alpha * self.alpha * tan2).sqrt())
    }

    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing G2 (Heitz 2014, eq. 99).
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals D_wo(m) = G1(wo) |wo.m| D(m) / |wo.z| (Heitz 2018).
    pub fn visible_pdf(&self, wo: Vec3, m: Vec3) -> f32 {
        if wo.z == 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(m).abs() * self.d(m) / wo.z.abs()
    }

    /// A microfacet normal drawn from the visible normals seen from `wo` (wo.z > 0), per
    /// Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4).
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = TAU * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// Schlick's approximation (Schlick 1994) with a colour F0, as glTF's metallic-roughness
/// model prescribes.
pub fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ggx_is_normalised_over_projected_area() {
        // Integral of D(m) cos(theta_m) over the hemisphere is 1 (Walter et al. 2007, eq. 4):
        // 2 pi * integral over mu = cos(theta) in [0, 1] of D(mu) mu, by a fine midpoint rule.
        for alpha in [0.05f32, 0.2, 0.5, 1.0] {
            let ggx = Ggx::new(alpha);
            let n = 1_000_000;
            let mut sum = 0.0f64;
            for k in 0..n {
                let mu = (k as f64 + 0.5) / n as f64;
                let m = Vec3::new((1.0 - mu * mu).sqrt() as f32, 0.0, mu as f32);
                sum += ggx.d(m) as f64 * mu / n as f64;
            }
            let integral = sum * std::f64::consts::TAU;
            assert!((integral - 1.0).abs() < 1e-3, "alpha {alpha}: {integral}");
        }
    }
}
