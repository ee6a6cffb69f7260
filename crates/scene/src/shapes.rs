//! Procedural meshes for the built-in scenes and for tests. All are centred on the origin
//! (cylinders stand on y = 0), with outward normals, counter-clockwise front faces and UVs
//! in [0, 1] per face.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use crate::model::Mesh;

/// A rectangle in the xy-plane facing +z, `width` along x and `height` along y.
pub fn quad(width: f32, height: f32) -> Mesh {
    let (hw, hh) = (0.5 * width, 0.5 * height);
    Mesh {
        positions: vec![Vec3::new(-hw, -hh, 0.0), Vec3::new(hw, -hh, 0.0), Vec3::new(hw, hh, 0.0), Vec3::new(-hw, hh, 0.0)],
        normals: vec![Vec3::Z; 4],
        // v = 0 is the top of a texture (glTF), so the top edge gets v = 0.
        uvs: vec![Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)],
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// A rectangle with an arbitrary frame: `origin` is its centre, `u` and `v` its full edge
/// vectors; it faces `u x v`. Texture coordinates are scaled by `uv_scale` (tiling).
pub fn rect(origin: Vec3, u: Vec3, v: Vec3, uv_scale: Vec2) -> Mesh {
    let n = u.cross(v).normalize();
    let c = origin - 0.5 * (u + v);
    Mesh {
        positions: vec![c, c + u, c + u + v, c + v],
        normals: vec![n; 4],
        uvs: vec![Vec2::new(0.0, uv_scale.y), Vec2::new(uv_scale.x, uv_scale.y), Vec2::new(uv_scale.x, 0.0), Vec2::new(0.0, 0.0)],
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// An axis-aligned box with the given half extents; each face has its own vertices so that
/// normals are flat.
pub fn cuboid(half: Vec3) -> Mesh {
    let mut mesh = Mesh::default();
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    for (n, u, v) in faces {
        let extent = |axis: Vec3| (axis.abs() * half).element_sum();
        let face = rect(n * extent(n), u * 2.0 * extent(u), v * 2.0 * extent(v), Vec2::ONE);
        mesh.append(&face);
    }
    mesh
}

/// A UV sphere with `segments` around the equator and `rings` from pole to pole.
pub fn uv_sphere(radius: f32, segments: u32, rings: u32) -> Mesh {
    let mut mesh = radial_surface(segments, rings, |_, _| radius);
    // The exact normals: face averages are off at the poles and along the seam.
    mesh.normals = mesh.positions.iter().map(|p| p.normalize()).collect();
    mesh
}

/// A closed star-shaped surface: `radius(theta, phi)` with theta from the +y pole and phi
/// the azimuth. Normals are area-weighted face averages (approximate at the poles and the
/// seam, where vertices are duplicated).
pub fn radial_surface(segments: u32, rings: u32, radius: impl Fn(f32, f32) -> f32) -> Mesh {
    let mut mesh = Mesh::default();
    for r in 0..=rings {
        let theta = PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = TAU * s as f32 / segments as f32;
            let dir = Vec3::new(theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos());
            mesh.positions.push(dir * radius(theta, phi));
            mesh.normals.push(dir);
            mesh.uvs.push(Vec2::new(s as f32 / segments as f32, r as f32 / rings as f32));
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let b = a + row;
            if r != 0 {
                mesh.indices.push([a, b, a + 1]);
            }
            if r != rings - 1 {
                mesh.indices.push([a + 1, b, b + 1]);
            }
        }
    }
    mesh.compute_vertex_normals();
    mesh
}

/// A closed cylinder standing on y = 0 with flat caps.
pub fn cylinder(radius: f32, height: f32, segments: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for s in 0..=segments {
        let phi = TAU * s as f32 / segments as f32;
        let n = Vec3::new(phi.sin(), 0.0, phi.cos());
        for (y, v) in [(0.0, 1.0), (height, 0.0)] {
            mesh.positions.push(n * radius + Vec3::Y * y);
            mesh.normals.push(n);
            mesh.uvs.push(Vec2::new(s as f32 / segments as f32, v));
        }
    }
    for s in 0..segments {
        let a = 2 * s;
        mesh.indices.push([a, a + 2, a + 1]);
        mesh.indices.push([a + 1, a + 2, a + 3]);
    }
    for (y, n) in [(0.0, Vec3::NEG_Y), (height, Vec3::Y)] {
        let centre = mesh.positions.len() as u32;
        mesh.positions.push(Vec3::Y * y);
        mesh.normals.push(n);
        mesh.uvs.push(Vec2::splat(0.5));
        for s in 0..=segments {
            let phi = TAU * s as f32 / segments as f32;
            let d = Vec3::new(phi.sin(), 0.0, phi.cos());
            mesh.positions.push(d * radius + Vec3::Y * y);
            mesh.normals.push(n);
            mesh.uvs.push(Vec2::new(0.5 + 0.5 * d.x, 0.5 + 0.5 * d.z));
        }
        for s in 0..segments {
            let (a, b) = (centre + 1 + s, centre + 2 + s);
            if n.y > 0.0 {
                mesh.indices.push([centre, a, b]);
            } else {
                mesh.indices.push([centre, b, a]);
            }
        }
    }
    mesh
}

/// A blobby bunny stand-in: a body with a head, two long ears and a tail as smooth bumps on
/// a sphere, about 0.5 units tall, resting on y = 0.
pub fn blob_bunny() -> Mesh {
    let bumps: [(Vec3, f32, f32); 5] = [
        (Vec3::new(0.0, 0.45, 0.55).normalize(), 0.55, 0.35),  // head
        (Vec3::new(-0.25, 1.0, 0.35).normalize(), 1.10, 0.10), // left ear
        (Vec3::new(0.25, 1.0, 0.35).normalize(), 1.10, 0.10),  // right ear
        (Vec3::new(0.0, 0.1, -1.0).normalize(), 0.25, 0.12),   // tail
        (Vec3::new(0.0, -1.0, 0.0), -0.35, 0.6),               // flattened base
    ];
    let mut mesh = radial_surface(64, 48, |theta, phi| {
        let dir = Vec3::new(theta.sin() * phi.sin(), theta.cos(), theta.sin() * phi.cos());
        let mut r = 0.2;
        for (axis, height, width) in bumps {
            let d = 1.0 - dir.dot(axis);
            r += 0.2 * height * (-d * d / (width * width) * 4.0).exp();
        }
        r
    });
    let lowest = mesh.positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    for p in &mut mesh.positions {
        p.y -= lowest;
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed volume by the divergence theorem: positive iff faces wind outward.
    fn volume(mesh: &Mesh) -> f32 {
        mesh.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn closed_shapes_have_their_analytic_volume_and_outward_faces() {
        let b = cuboid(Vec3::new(0.5, 1.0, 1.5));
        assert!((volume(&b) - 6.0).abs() < 1e-4, "{}", volume(&b));
        let s = uv_sphere(1.0, 128, 64);
        assert!((volume(&s) - 4.0 / 3.0 * PI).abs() < 0.01, "{}", volume(&s));
        let c = cylinder(0.5, 2.0, 256);
        assert!((volume(&c) - PI * 0.25 * 2.0).abs() < 0.001, "{}", volume(&c));
        assert!(volume(&blob_bunny()) > 0.0);
    }

    #[test]
    fn vertex_normals_point_outward() {
        for mesh in [cuboid(Vec3::ONE), uv_sphere(1.0, 16, 8), cylinder(1.0, 1.0, 16)] {
            for t in &mesh.indices {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                let face = (b - a).cross(c - a);
                for &i in t {
                    assert!(face.dot(mesh.normals[i as usize]) > 0.0);
                }
            }
            assert_eq!(mesh.normals.len(), mesh.positions.len());
            assert_eq!(mesh.uvs.len(), mesh.positions.len());
        }
    }

    #[test]
    fn quad_faces_plus_z() {
        let q = quad(2.0, 1.0);
        let [a, b, c] = q.indices[0].map(|i| q.positions[i as usize]);
        assert!((b - a).cross(c - a).z > 0.0);
    }
}
