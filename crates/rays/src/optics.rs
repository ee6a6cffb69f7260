//! Light at a smooth dielectric interface: Fresnel reflectance, Snell's refraction, mirror
//! reflection. The ground-truth tracer's glass BSDFs and the frame's refraction pass
//! (`through.rs`) both use these, so both bend light the same way.

use glam::Vec3;

/// Unpolarised Fresnel reflectance of a dielectric interface. `cos_i` is signed: positive
/// when the incident direction is on the side of the normal, where `eta` = n_inside /
/// n_outside applies; negative means the ray comes from inside.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)
}

/// Reflectance of a thin slab with two parallel interfaces, summing all internal
/// reflections: R' = R + T^2 R / (1 - R^2) with T = 1 - R, which simplifies to 2R / (1 + R).
pub fn thin_slab_reflectance(cos_i: f32, eta: f32) -> f32 {
    let r = fresnel_dielectric(cos_i.abs(), eta);
    if r >= 1.0 {
        return 1.0;
    }
    2.0 * r / (1.0 + r)
}

pub fn reflect(w: Vec3, m: Vec3) -> Vec3 {
    2.0 * w.dot(m) * m - w
}

/// Refract `w` (pointing away from the surface) through a surface with normal `n`; `eta` is
/// the IOR ratio n_inside / n_outside with `n` pointing outside. Returns the refracted
/// direction and the relative IOR eta_t / eta_i it crossed, or `None` on total internal
/// reflection.
pub fn refract(w: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(w);
    let (mut n, mut eta) = (n, eta);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-w / eta + (cos_i / eta - cos_t) * n, eta))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_known_values() {
        // Normal incidence on glass of IOR 1.5: ((1.5-1)/(1.5+1))^2 = 0.04.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(-1.0, 1.5) - 0.04).abs() < 1e-6);
        // Total internal reflection beyond the critical angle from inside.
        assert_eq!(fresnel_dielectric(-0.3, 1.5), 1.0);
        // Brewster's angle: parallel reflectance vanishes, so R = R_perp / 2.
        let brewster = 1.5f32.atan();
        let r = fresnel_dielectric(brewster.cos(), 1.5);
        assert!(r > 0.0 && r < 0.1);
        // Thin slab at normal incidence: 2 * 0.04 / 1.04.
        assert!((thin_slab_reflectance(1.0, 1.5) - 0.08 / 1.04).abs() < 1e-6);
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = Vec3::Z;
        let w = Vec3::new(0.6, 0.0, 0.8);
        let (t, eta) = refract(w, n, 1.5).unwrap();
        assert_eq!(eta, 1.5);
        let sin_i = 0.6f32;
        let sin_t = (t.x * t.x + t.y * t.y).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-5);
        assert!(t.z < 0.0 && (t.length() - 1.0).abs() < 1e-5);
        // Refracting the inside direction back out gives the original direction.
        let (back, eta_back) = refract(t, n, 1.5).unwrap();
        assert!((eta_back - 1.0 / 1.5).abs() < 1e-6);
        assert!((back - w).length() < 1e-5, "{back}");
    }
}
