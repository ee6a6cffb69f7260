//! Sampling helpers shared by the BSDFs, the lights and the integrator.

use std::f32::consts::{FRAC_1_PI, PI, TAU};

use glam::{Vec2, Vec3};

/// An orthonormal frame whose `normal` is local +z.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub tangent: Vec3,
    pub bitangent: Vec3,
    pub normal: Vec3,
}

impl Frame {
    /// Branchless orthonormal basis from a unit normal (Duff et al. 2017, "Building an
    /// Orthonormal Basis, Revisited", JCGT 6(1)).
    pub fn from_normal(normal: Vec3) -> Self {
        let sign = 1.0f32.copysign(normal.z);
        let a = -1.0 / (sign + normal.z);
        let b = normal.x * normal.y * a;
        let tangent = Vec3::new(1.0 + sign * normal.x * normal.x * a, sign * b, -sign * normal.x);
        let bitangent = Vec3::new(b, sign + normal.y * normal.y * a, -normal.y);
        Frame { tangent, bitangent, normal }
    }

    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.tangent), v.dot(self.bitangent), v.dot(self.normal))
    }

    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.tangent * v.x + self.bitangent * v.y + self.normal * v.z
    }
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method over a concentric disk,
/// Shirley & Chiu 1997).
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    Vec3::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt())
}

pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform point on the unit disk, area-preserving (Shirley & Chiu 1997).
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let p = 2.0 * u - Vec2::ONE;
    if p == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if p.x.abs() > p.y.abs() { (p.x, 0.25 * PI * (p.y / p.x)) } else { (p.y, 0.5 * PI - 0.25 * PI * (p.x / p.y)) };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Barycentric coordinates (b1, b2) of a uniform point on a triangle (the square-root
/// parameterisation, Osada et al. 2002).
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let s = u.x.sqrt();
    Vec2::new(1.0 - s, u.y * s)
}

/// Uniform direction on the unit sphere.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Veach's power heuristic with exponent 2 for two strategies, one sample each.
pub fn power_heuristic(pdf_this: f32, pdf_other: f32) -> f32 {
    let (a, b) = (pdf_this * pdf_this, pdf_other * pdf_other);
    if a == 0.0 {
        return 0.0;
    }
    if !b.is_finite() {
        return 0.0;
    }
    if !a.is_finite() {
        return 1.0;
    }
    a / (a + b)
}

pub use glassbake_core::color::luminance;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    #[test]
    fn frames_are_orthonormal() {
        let mut rng = Pcg32::new(3, 0);
        for _ in 0..1000 {
            let n = uniform_sphere(rng.next_vec2());
            let f = Frame::from_normal(n);
            assert!((f.tangent.length() - 1.0).abs() < 1e-4);
            assert!((f.bitangent.length() - 1.0).abs() < 1e-4);
            assert!(f.tangent.dot(n).abs() < 1e-4 && f.bitangent.dot(n).abs() < 1e-4);
            assert!(f.tangent.dot(f.bitangent).abs() < 1e-4);
            let v = uniform_sphere(rng.next_vec2());
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-4);
        }
    }

    #[test]
    fn cosine_samples_have_the_cosine_mean() {
        // E[cos] under the cosine density is 2/3.
        let mut rng = Pcg32::new(5, 0);
        let n = 200_000;
        let mean: f64 = (0..n).map(|_| cosine_hemisphere(rng.next_vec2()).z as f64).sum::<f64>() / n as f64;
        assert!((mean - 2.0 / 3.0).abs() < 3e-3, "{mean}");
    }
}
