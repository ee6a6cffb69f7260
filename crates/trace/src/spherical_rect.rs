//! Uniform sampling of the solid angle a rectangle subtends (Ureña, Fajardo and King, "An
//! Area-Preserving Parametrization for Spherical Rectangles", EGSR 2013).
//!
//! Area sampling a rectangle light gives the shading point a density proportional to
//! distance^2 / cos(light), which explodes for points close to the light or seeing it at a
//! grazing angle (walls next to a ceiling light). Sampling the subtended solid angle
//! uniformly removes both factors: every sample carries the same weight up to the BSDF and
//! the receiver's cosine. The arithmetic is in f64: the parametrization subtracts nearly
//! equal angles when the rectangle is small or far away.

use std::f64::consts::PI;

use glam::{DVec3, Vec2, Vec3};

/// A rectangle as seen from one point, ready to sample.
#[derive(Clone, Copy, Debug)]
pub struct SphericalRect {
    origin: DVec3,
    x: DVec3,
    y: DVec3,
    z: DVec3,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    z0: f64,
    b0: f64,
    b1: f64,
    k: f64,
    /// The solid angle, in steradians.
    pub solid_angle: f64,
}

impl SphericalRect {
    /// The rectangle `corner + s * edge_u + t * edge_v` (s, t in [0, 1]; the edges must be
    /// orthogonal) seen from `origin`. `None` when the point lies in the rectangle's plane or
    /// the solid angle is too small to represent.
    pub fn new(corner: Vec3, edge_u: Vec3, edge_v: Vec3, origin: Vec3) -> Option<Self> {
        let (corner, edge_u, edge_v, origin) = (corner.as_dvec3(), edge_u.as_dvec3(), edge_v.as_dvec3(), origin.as_dvec3());
        let (length_x, length_y) = (edge_u.length(), edge_v.length());
        let x = edge_u / length_x;
        let y = edge_v / length_y;
        let mut z = x.cross(y);
        let d = corner - origin;
        let x0 = d.dot(x);
        let y0 = d.dot(y);
        let mut z0 = d.dot(z);
        // Work in the frame where the rectangle lies below the origin (z0 < 0).
        if z0 > 0.0 {
            z0 = -z0;
            z = -z;
        }
        if z0.abs() < 1e-9 * (length_x + length_y) {
            return None;
        }
        let (x1, y1) = (x0 + length_x, y0 + length_y);
        let v00 = DVec3::new(x0, y0, z0);
        let v01 = DVec3::new(x0, y1, z0);
        let v10 = DVec3::new(x1, y0, z0);
        let v11 = DVec3::new(x1, y1, z0);
        // Normals of the planes through the origin and each edge, pointing inwards.
        let n0 = v00.cross(v10).normalize();
        let n1 = v10.cross(v11).normalize();
        let n2 = v11.cross(v01).normalize();
        let n3 = v01.cross(v00).normalize();
        // Interior angles of the spherical quadrilateral.
        let g0 = (-n0.dot(n1)).clamp(-1.0, 1.0).acos();
        let g1 = (-n1.dot(n2)).clamp(-1.0, 1.0).acos();
        let g2 = (-n2.dot(n3)).clamp(-1.0, 1.0).acos();
        let g3 = (-n3.dot(n0)).clamp(-1.0, 1.0).acos();
        let k = 2.0 * PI - g2 - g3;
        let solid_angle = g0 + g1 - k;
        if !solid_angle.is_finite() || solid_angle <= 1e-12 {
            return None;
        }
        Some(SphericalRect { origin, x, y, z, x0, x1, y0, y1, z0, b0: n0.z, b1: n2.z, k, solid_angle })
    }

    /// The point on the rectangle for `u` in [0, 1)^2; uniform in solid angle seen from the
    /// origin, so its density is `1 / solid_angle`.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let (u, v) = (u.x as f64, u.y as f64);
        // The x coordinate: the sub-rectangle [x0, xu] must subtend u * solid_angle.
        let au = u * self.solid_angle + self.k;
        let fu = (au.cos() * self.b0 - self.b1) / au.sin();
        let cu = ((1.0 / (fu * fu + self.b0 * self.b0).sqrt()) * fu.signum()).clamp(-1.0, 1.0);
        let xu = (-(cu * self.z0) / (1.0 - cu * cu).max(1e-30).sqrt()).clamp(self.x0, self.x1);
        // The y coordinate: uniform in the projected height along the chosen column.
        let d = (xu * xu + self.z0 * self.z0).sqrt();
        let h0 = self.y0 / (d * d + self.y0 * self.y0).sqrt();
        let h1 = self.y1 / (d * d + self.y1 * self.y1).sqrt();
        let hv = h0 + v * (h1 - h0);
        let hv2 = hv * hv;
        let yv = if hv2 < 1.0 - 1e-12 { (hv * d) / (1.0 - hv2).sqrt() } else { self.y1 };
        let yv = yv.clamp(self.y0, self.y1);
        (self.origin + xu * self.x + yv * self.y + self.z0 * self.z).as_vec3()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Solid angle of the rectangle by midpoint quadrature of cos / r^2 over its area:
    /// independent of the spherical-quadrilateral formula above.
    fn quadrature_solid_angle(corner: Vec3, edge_u: Vec3, edge_v: Vec3, origin: Vec3, s: (f64, f64), t: (f64, f64)) -> f64 {
        let n = 200;
        let (corner, edge_u, edge_v, origin) = (corner.as_dvec3(), edge_u.as_dvec3(), edge_v.as_dvec3(), origin.as_dvec3());
        let normal = edge_u.cross(edge_v).normalize();
        let cell_area = edge_u.length() * edge_v.length() * (s.1 - s.0) * (t.1 - t.0) / (n * n) as f64;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let a = s.0 + (s.1 - s.0) * (i as f64 + 0.5) / n as f64;
                let b = t.0 + (t.1 - t.0) * (j as f64 + 0.5) / n as f64;
                let p = corner + a * edge_u + b * edge_v;
                let r = p - origin;
                let d2 = r.length_squared();
                sum += normal.dot(r).abs() / (d2 * d2.sqrt()) * cell_area;
            }
        }
        sum
    }

    fn configurations() -> Vec<(Vec3, Vec3, Vec3, Vec3)> {
        vec![
            // Ceiling light seen from a floor point below it.
            (Vec3::new(-0.5, 2.0, -0.5), Vec3::X, Vec3::Z, Vec3::new(0.1, 0.0, 0.2)),
            // Seen from far off to the side, at a grazing angle.
            (Vec3::new(-0.5, 2.0, -0.5), Vec3::X * 0.8, Vec3::Z * 0.6, Vec3::new(3.0, 1.9, 0.4)),
            // Very close: a point 1 cm below a corner.
            (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.6, 0.0, 0.6), Vec3::new(-0.3, 0.0, 0.3), Vec3::new(0.01, 0.99, 0.01)),
            // Tilted, seen from its back side.
            (Vec3::ZERO, Vec3::new(0.0, 0.7, 0.7), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.4, 1.0, -1.0)),
        ]
    }

    #[test]
    fn solid_angle_matches_quadrature() {
        for (corner, u, v, origin) in configurations() {
            let rect = SphericalRect::new(corner, u, v, origin).unwrap();
            let expected = quadrature_solid_angle(corner, u, v, origin, (0.0, 1.0), (0.0, 1.0));
            let relative = (rect.solid_angle - expected).abs() / expected;
            assert!(relative < 1e-3, "{corner} {origin}: {} vs quadrature {expected}", rect.solid_angle);
        }
    }

    /// Chi-square test: the rectangle split into 6x6 cells, the expected share of samples in
    /// each cell is its solid angle (by quadrature) over the whole's.
    #[test]
    fn samples_are_uniform_in_solid_angle_chi_square() {
        const CELLS: usize = 6;
        const SAMPLES: usize = 200_000;
        for (corner, edge_u, edge_v, origin) in configurations() {
            let rect = SphericalRect::new(corner, edge_u, edge_v, origin).unwrap();
            let mut counts = [0u32; CELLS * CELLS];
            let mut rng = crate::rng::Pcg32::for_pixel(7, 11);
            let (du, dv) = (edge_u.as_dvec3(), edge_v.as_dvec3());
            for _ in 0..SAMPLES {
                let p = rect.sample(rng.next_vec2()).as_dvec3() - corner.as_dvec3();
                let s = p.dot(du) / du.length_squared();
                let t = p.dot(dv) / dv.length_squared();
                let off_plane = (p - s * du - t * dv).length();
                assert!(
                    off_plane < 1e-4 && (-1e-4..=1.0 + 1e-4).contains(&s) && (-1e-4..=1.0 + 1e-4).contains(&t),
                    "sample off the rectangle: {s} {t} {off_plane}"
                );
                let i = ((s * CELLS as f64) as usize).min(CELLS - 1);
                let j = ((t * CELLS as f64) as usize).min(CELLS - 1);
                counts[i * CELLS + j] += 1;
            }
            let mut chi2 = 0.0;
            for i in 0..CELLS {
                for j in 0..CELLS {
                    let cell = |k: usize| (k as f64 / CELLS as f64, (k + 1) as f64 / CELLS as f64);
                    let share = quadrature_solid_angle(corner, edge_u, edge_v, origin, cell(i), cell(j)) / rect.solid_angle;
                    let expected = share * SAMPLES as f64;
                    let observed = counts[i * CELLS + j] as f64;
                    chi2 += (observed - expected).powi(2) / expected;
                }
            }
            // 35 degrees of freedom: the 99.9th percentile of chi-square(35) is 66.6.
            assert!(chi2 < 66.6, "{corner} seen from {origin}: chi-square {chi2:.1} over 35 degrees of freedom");
        }
    }

    #[test]
    fn a_point_in_the_plane_has_nothing_to_sample() {
        assert!(SphericalRect::new(Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(3.0, 0.0, 0.0)).is_none());
    }
}
