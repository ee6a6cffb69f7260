//! A content hash of a scene (geometry, textures, materials, lights, ranges, variables), so a
//! dataset can refuse to be extended with frames of a different scene.

use sha2::{Digest, Sha256};

use crate::camera_spec::CameraPosition;
use crate::model::Scene;
use crate::variables::VariableTarget;

fn floats(h: &mut Sha256, values: &[f32]) {
    for v in values {
        h.update(v.to_le_bytes());
    }
}

impl Scene {
    /// Hex SHA-256 over everything that affects rendering or sampling.
    pub fn content_hash(&self) -> String {
        let mut h = Sha256::new();
        for m in &self.meshes {
            h.update((m.positions.len() as u64).to_le_bytes());
            for p in &m.positions {
                floats(&mut h, &p.to_array());
            }
            for n in &m.normals {
                floats(&mut h, &n.to_array());
            }
            for uv in &m.uvs {
                floats(&mut h, &uv.to_array());
            }
            for t in &m.indices {
                for i in t {
                    h.update(i.to_le_bytes());
                }
            }
        }
        for t in &self.textures {
            h.update(t.width.to_le_bytes());
            h.update(t.height.to_le_bytes());
            for texel in &t.texels {
                floats(&mut h, &texel.to_array());
            }
        }
        for m in &self.materials {
            h.update(m.name.as_bytes());
            floats(&mut h, &m.base_color.to_array());
            floats(&mut h, &[m.roughness, m.metallic]);
            floats(&mut h, &m.emission.to_array());
            h.update(format!("{:?}{:?}{:?}", m.base_color_texture, m.roughness_texture, m.transmission).as_bytes());
            // Only when set, so scenes without a specular layer keep their old hash.
            if !m.has_default_specular() {
                floats(&mut h, &[m.specular]);
                floats(&mut h, &m.specular_color.to_array());
                h.update(format!("specular {:?}{:?}", m.specular_texture, m.specular_color_texture).as_bytes());
            }
        }
        for o in &self.objects {
            h.update(o.name.as_bytes());
            h.update(format!("{} {} {}", o.mesh, o.material, o.transparent).as_bytes());
            floats(&mut h, &o.transform.to_cols_array());
        }
        for l in &self.rect_lights {
            h.update(format!("{l:?}").as_bytes());
        }
        let c = &self.camera;
        match c.position {
            CameraPosition::Box { min, max } => h.update(format!("box{min}{max}").as_bytes()),
            CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => {
                h.update(format!("orbit{center}{radius:?}{azimuth_deg:?}{elevation_deg:?}").as_bytes())
            }
        }
        h.update(format!("{}{}{}{:?}{}{}", c.target, c.target_jitter, c.up, c.fov_x_deg, c.near, c.far).as_bytes());
        for v in &self.variables {
            let target = match v.target {
                VariableTarget::Roughness { material } => format!("r{material}"),
                t => format!("{t:?}"),
            };
            h.update(format!("{}{}{}{}{target}", v.name, v.min, v.max, v.default).as_bytes());
        }
        floats(&mut h, &self.background.to_array());
        h.finalize().iter().map(|b| format!("{b:02x}")).collect()
    }
}
