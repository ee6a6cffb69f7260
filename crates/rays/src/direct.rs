//! Direct light from the rectangle lights where the rasterizer's G-buffer cannot give it: at a
//! surface a through buffer's ray reaches that the camera does not see (hidden behind
//! something, or outside the frame). It has the G-buffer's diffuse meaning: the polygon form
//! factor of each light in closed form, times the light's radiance and the surface's diffuse
//! albedo, with the light's visibility found by a shadow ray instead of a shadow map. The
//! GPU twin is `shaders/polygon.wgsl` (the form factor, which the rasterizer's G-buffer shader
//! shares) and `unseen_direct_light` in `shaders/through.wgsl`.

use glam::{Mat3, Vec3};
use glassbake_scene::model::Material;
use glassbake_scene::Scene;

use crate::geometry::SceneGeometry;
use crate::through::{FOOTPRINT, SELF_HIT, VIEW_SLACK};

/// [`polygon_form_factor`] in WGSL (`integrate_edge`, `polygon_form_factor`, and
/// `frame_around` for the frame it takes), for the through pass and the G-buffer's shader.
pub const POLYGON_WGSL: &str = include_str!("../shaders/polygon.wgsl");

/// The form factor of the quadrilateral `q` seen from a point on a surface, `q`'s corners
/// given relative to the point in a frame whose +z is the surface's normal: the integral of
/// cos(theta) / pi over the solid angle of its part above the surface (Lambert's polygon
/// formula, as in Arvo 1995, "Applications of Irradiance Tensors to the Simulation of
/// Non-Lambertian Phenomena", eq. 8). The winding's sign is dropped: which side of the light
/// emits is the caller's to decide.
pub fn polygon_form_factor(q: [Vec3; 4]) -> f32 {
    // Clip to z >= 0: a quadrilateral cut by a plane keeps at most 5 corners.
    let mut clipped = [Vec3::ZERO; 5];
    let mut count = 0;
    for i in 0..4 {
        let (a, b) = (q[i], q[(i + 1) % 4]);
        if a.z >= 0.0 {
            clipped[count] = a;
            count += 1;
        }
        if (a.z >= 0.0) != (b.z >= 0.0) {
            let t = a.z / (a.z - b.z);
            clipped[count] = Vec3::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, 0.0);
            count += 1;
        }
    }
    if count < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..count {
        let (a, b) = (clipped[i], clipped[(i + 1) % count]);
        if a.length_squared() > 0.0 && b.length_squared() > 0.0 {
            sum += edge_integral(a.normalize(), b.normalize());
        }
    }
    sum.abs() / std::f32::consts::TAU
}

/// The z component of the integral over the great arc from unit `a` to unit `b`: the angle
/// between them times the z of the unit normal of their plane.
fn edge_integral(a: Vec3, b: Vec3) -> f32 {
    let c = a.cross(b);
    let s = c.length();
    if s < 1e-12 {
        return 0.0;
    }
    s.atan2(a.dot(b)) * c.z / s
}

/// The share of a material's base colour that reflects diffusely, as the rasterizer's
/// G-buffer shades it: none of a metal's, none of what glass transmits.
pub fn diffuse_share(material: &Material) -> f32 {
    (1.0 - material.metallic.clamp(0.0, 1.0)) * (1.0 - material.transmission.map_or(0.0, |t| t.weight.clamp(0.0, 1.0)))
}

/// The point on a rectangle light (in its (u, v) parameters) that a through buffer's
/// footprint path `point` sends its shadow ray to: the footprint's own pattern (`FOOTPRINT`)
/// moved onto the light, so that a pixel's paths see four places on it, one in each quarter,
/// and its mean is a soft shadow's rather than a hard one's.
pub fn light_point(point: usize) -> [f32; 2] {
    let [u, v] = FOOTPRINT[point % FOOTPRINT.len()];
    [u + 0.5, v + 0.5]
}

/// The direct light of `scene`'s rectangle lights at `position` on a surface with unit
/// shading `normal` (on the side it is seen from) and diffuse albedo `diffuse_albedo`, the
/// shadow rays cast in `opaque` (the opaque scene): each light in front of the point brings its
/// radiance times the albedo times its form factor, if the segment to its
/// [`light_point`]`(point)` is clear. As in the rasterizer's shadow maps, glass casts no shadow;
/// unlike them, one light's quad shadows another's light.
pub fn unseen_direct_light(scene: &Scene, opaque: &SceneGeometry, position: Vec3, normal: Vec3, diffuse_albedo: Vec3, point: usize) -> Vec3 {
    if diffuse_albedo == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let frame = frame_around(normal);
    let mut total = Vec3::ZERO;
    for light in &scene.rect_lights {
        let side = (position - light.corner).dot(light.normal());
        if !(side > 0.0 || (light.two_sided && side < 0.0)) {
            continue;
        }
        let form_factor = polygon_form_factor(light.corners().map(|c| frame * (c - position)));
        if form_factor <= 0.0 {
            continue;
        }
        let [u, v] = light_point(point);
        let to_light = light.corner + light.edge_u * u + light.edge_v * v - position;
        let distance = to_light.length();
        if opaque.occluded(position, to_light / distance, SELF_HIT, distance * (1.0 - VIEW_SLACK)) {
            continue;
        }
        total += light.radiance * diffuse_albedo * form_factor;
    }
    total
}

/// Rows t1, t2, n: world to a frame whose +z is unit `n` (the form factor does not depend on
/// the rotation about it).
fn frame_around(n: Vec3) -> Mat3 {
    let (t1, t2) = n.any_orthonormal_pair();
    Mat3::from_cols(t1, t2, n).transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The form factor from a point under one corner of an a x b rectangle parallel to its
    /// surface at height c (Howell, "A Catalog of Radiation Heat Transfer Configuration
    /// Factors", B-3).
    fn corner_form_factor(a: f64, b: f64, c: f64) -> f64 {
        let (x, y) = (a / c, b / c);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / std::f64::consts::TAU
    }

    fn rect(corner: Vec3, u: Vec3, v: Vec3) -> [Vec3; 4] {
        [corner, corner + u, corner + u + v, corner + v]
    }

    #[test]
    fn a_parallel_rectangle_has_the_catalogued_form_factor() {
        for (a, b, c) in [(1.0, 1.0, 1.0), (2.0, 0.5, 1.0), (0.3, 4.0, 0.7), (10.0, 10.0, 0.1)] {
            let q = rect(Vec3::new(0.0, 0.0, c), Vec3::X * a, Vec3::Y * b);
            let expected = corner_form_factor(a.into(), b.into(), c.into());
            let got = f64::from(polygon_form_factor(q));
            assert!((got - expected).abs() < 1e-5, "{a} x {b} at {c}: {got} vs {expected}");
            // Winding either way: the same.
            let reversed = [q[3], q[2], q[1], q[0]];
            assert!((f64::from(polygon_form_factor(reversed)) - expected).abs() < 1e-5);
        }
        // A point under the middle of a rectangle sees four corner rectangles.
        let centred = polygon_form_factor(rect(Vec3::new(-1.0, -0.5, 0.8), Vec3::X * 2.0, Vec3::Y));
        let expected = 4.0 * corner_form_factor(1.0, 0.5, 0.8);
        assert!((f64::from(centred) - expected).abs() < 1e-5, "{centred} vs {expected}");
    }

    /// The clamped cosine over a light's solid angle by brute force: `n` x `n` midpoints of
    /// the rectangle, cos at the point (0 below its surface) times cos at the light over pi r^2.
    fn form_factor_by_quadrature(corner: Vec3, u: Vec3, v: Vec3, n: usize) -> f64 {
        let area = f64::from(u.cross(v).length());
        let light_normal = u.cross(v).normalize().as_dvec3();
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let p = corner.as_dvec3() + u.as_dvec3() * ((i as f64 + 0.5) / n as f64) + v.as_dvec3() * ((j as f64 + 0.5) / n as f64);
                let r2 = p.length_squared();
                let w = p / r2.sqrt();
                sum += w.z.max(0.0) * w.dot(light_normal).abs() / (std::f64::consts::PI * r2);
            }
        }
        sum * area / (n * n) as f64
    }

    #[test]
    fn a_tilted_rectangle_cut_by_the_horizon_matches_quadrature() {
        let cases = [
            (Vec3::new(-0.5, -0.3, 0.4), Vec3::new(1.0, 0.2, 0.3), Vec3::new(-0.1, 0.8, 0.5)),
            // Partly below the surface: only its upper part counts.
            (Vec3::new(0.2, -0.6, -0.5), Vec3::new(0.1, 1.2, 0.0), Vec3::new(0.3, 0.0, 1.4)),
            (Vec3::new(1.0, 0.0, -0.2), Vec3::new(0.0, 0.0, 0.6), Vec3::new(0.0, 0.9, 0.0)),
        ];
        for (corner, u, v) in cases {
            let expected = form_factor_by_quadrature(corner, u, v, 1500);
            let got = f64::from(polygon_form_factor(rect(corner, u, v)));
            assert!((got - expected).abs() < 2e-4 * expected.max(0.05), "{corner} {u} {v}: {got} vs {expected}");
        }
        // Wholly below: nothing.
        assert_eq!(polygon_form_factor(rect(Vec3::new(0.0, 0.0, -0.1), Vec3::X, Vec3::Y)), 0.0);
    }

    #[test]
    fn the_light_points_see_each_quarter_of_the_light_once() {
        let mut quarters: Vec<(bool, bool)> = (0..FOOTPRINT.len()).map(light_point).map(|[u, v]| (u < 0.5, v < 0.5)).collect();
        assert!((0..FOOTPRINT.len()).flat_map(light_point).all(|x| x > 0.0 && x < 1.0));
        quarters.sort();
        quarters.dedup();
        assert_eq!(quarters.len(), 4);
    }
}
