//! Scenes built in the tests, and a CPU ray caster for quads to know what every pixel must
//! hold.

#![allow(dead_code)]

use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3};
use glassbake_core::Camera;
use glassbake_raster::{Rasterizer, RasterizerOptions};
use glassbake_scene::shapes::rect;
use glassbake_scene::{Material, Object, RectLight, Scene};

pub fn rasterizer() -> Rasterizer {
    Rasterizer::new(RasterizerOptions::default()).expect("a Vulkan adapter (lavapipe: apt-get install mesa-vulkan-drivers)")
}

pub fn empty_scene(name: &str) -> Scene {
    Scene::empty(name)
}

/// A quad as the test knows it: centre, full edge vectors (facing u x v), material values.
#[derive(Clone, Copy, Debug)]
pub struct Quad {
    pub centre: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    pub albedo: Vec3,
    pub roughness: f32,
    pub transparent: bool,
}

impl Quad {
    pub fn normal(&self) -> Vec3 {
        self.u.cross(self.v).normalize()
    }

    /// Ray parameter of the hit, if the ray hits the quad.
    pub fn hit(&self, origin: Vec3, dir: Vec3) -> Option<f32> {
        let n = self.normal();
        let denom = dir.dot(n);
        if denom.abs() < 1e-9 {
            return None;
        }
        let t = (self.centre - origin).dot(n) / denom;
        if t <= 0.0 {
            return None;
        }
        let p = origin + dir * t - self.centre;
        let a = p.dot(self.u) / self.u.length_squared();
        let b = p.dot(self.v) / self.v.length_squared();
        (a.abs() <= 0.5 && b.abs() <= 0.5).then_some(t)
    }
}

/// Add quads to a scene as objects (each its own mesh and material).
pub fn add_quads(scene: &mut Scene, quads: &[Quad]) {
    for (i, q) in quads.iter().enumerate() {
        scene.meshes.push(Arc::new(rect(q.centre, q.u, q.v, Vec2::ONE)));
        let material = if q.transparent {
            Material::glass(&format!("glass{i}"), q.albedo, q.roughness, 1.5, true)
        } else {
            Material { roughness: q.roughness, ..Material::diffuse(&format!("m{i}"), q.albedo) }
        };
        scene.materials.push(material);
        scene.objects.push(Object {
            name: format!("quad{i}"),
            mesh: scene.meshes.len() - 1,
            material: scene.materials.len() - 1,
            transform: Affine3A::IDENTITY,
            transparent: q.transparent,
        });
    }
}

pub fn light(corner: Vec3, edge_u: Vec3, edge_v: Vec3, radiance: Vec3) -> RectLight {
    RectLight { name: "light".into(), corner, edge_u, edge_v, radiance, two_sided: false }
}

pub fn camera(position: Vec3, target: Vec3, fov: f32) -> Camera {
    Camera { position, target, up: Vec3::Y, fov_x_deg: fov, near: 0.05, far: 100.0 }
}
