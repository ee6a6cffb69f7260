//! A scene instance as the flat arrays of vec4s that `shaders/trace.wgsl` reads. The record
//! sizes here and the `*_VEC4S` constants there describe the same layouts.

use glassbake_core::Result;
use glassbake_scene::Scene;
use glassbake_trace::lights::Shape;
use glassbake_trace::{PreparedScene, SurfaceMaterial};

pub use glassbake_rays::gpu_bvh::MAX_BVH_DEPTH;
use glassbake_rays::gpu_bvh::{GpuBvhs, GpuTriangle};
use glassbake_rays::gpu_scene::{self, bits, v4};

pub(crate) use glassbake_rays::gpu_scene::{ATTR_PASS_THROUGH, NONE};

/// Record sizes in vec4s of the tracer's own records (the triangles' are `gpu_scene`'s).
/// These constants, not copies, reach the shader (`tracer::shared_constants`).
pub(crate) const MATERIAL_VEC4S: usize = 4;
pub(crate) const EMITTER_VEC4S: usize = 6;

type Vec4s = Vec<[f32; 4]>;

/// Everything the trace kernel reads about one scene instance.
pub struct SceneBuffers {
    pub nodes: Vec4s,
    pub triangles: Vec4s,
    pub attributes: Vec4s,
    /// Materials, then the texture table from `texture_table` (in vec4s).
    pub materials: Vec4s,
    pub texture_table: u32,
    pub texels: Vec4s,
    pub emitters: Vec4s,
    pub emitter_count: u32,
    /// Whether any triangle may let shadow rays through (a thin pane).
    pub has_panes: bool,
    /// Deepest leaf of the BVH (the root has depth 0).
    pub bvh_depth: usize,
}

impl SceneBuffers {
    /// Flatten `scene` for the plain estimator's light sampling. Fails (naming the scene) when
    /// the BVH is deeper than the shader's traversal stack.
    pub fn build(scene: &Scene) -> Result<Self> {
        let prepared = PreparedScene::new(scene);
        let attributes_cpu = &prepared.geometry.attributes;

        let mut attributes = Vec::new();
        gpu_scene::push_attributes(attributes_cpu, &mut attributes);

        let bvh_triangles: Vec<GpuTriangle> = attributes_cpu
            .iter()
            .enumerate()
            .map(|(index, a)| GpuTriangle { positions: a.positions, attribute: index as u32, flags: if a.may_pass_through { ATTR_PASS_THROUGH } else { 0 } })
            .collect();
        let mut bvh = GpuBvhs::default();
        bvh.push(&bvh_triangles, &scene.name)?;

        let texture_ref = |t: Option<usize>| match t {
            Some(i) if i < scene.textures.len() => i as u32,
            _ => NONE,
        };
        let mut materials = Vec::with_capacity(scene.materials.len() * MATERIAL_VEC4S + scene.textures.len());
        for m in &scene.materials {
            let surface = SurfaceMaterial {
                base_color: m.base_color,
                roughness: m.roughness,
                metallic: m.metallic,
                specular: m.specular,
                specular_color: m.specular_color,
                transmission: m.transmission,
            };
            materials.extend(material_vec4s(&surface));
            materials.push([
                bits(texture_ref(m.base_color_texture)),
                bits(texture_ref(m.roughness_texture)),
                bits(texture_ref(m.specular_texture)),
                bits(texture_ref(m.specular_color_texture)),
            ]);
        }
        let mut texels = Vec::new();
        let texture_table = gpu_scene::push_textures(scene, &mut materials, &mut texels);

        let lights = &prepared.lights;
        let mut emitters = Vec::with_capacity(lights.emitters.len() * EMITTER_VEC4S);
        for (i, e) in lights.emitters.iter().enumerate() {
            let (is_triangle, p0, edge1, edge2) = match e.shape {
                Shape::Parallelogram { corner, edge_u, edge_v } => (0, corner, edge_u, edge_v),
                Shape::Triangle { v0, edge1, edge2 } => (1, v0, edge1, edge2),
            };
            let (pmf, cdf) = lights.selection(i);
            emitters.push(v4(p0, bits(is_triangle)));
            emitters.push(v4(edge1, e.area));
            emitters.push(v4(edge2, bits(e.two_sided as u32)));
            emitters.push(v4(e.normal, pmf));
            emitters.push(v4(e.radiance, bits(lights.is_rectangle(e) as u32)));
            emitters.push([cdf as f32, 0.0, 0.0, 0.0]);
        }
        // Nothing to pick when no emitter has power (the CPU sampler's empty case).
        let emitter_count = if lights.is_empty() { 0 } else { lights.emitters.len() as u32 };

        Ok(SceneBuffers {
            nodes: bvh.nodes,
            triangles: bvh.triangles,
            attributes,
            materials,
            texture_table,
            texels,
            emitters,
            emitter_count,
            has_panes: attributes_cpu.iter().any(|a| a.may_pass_through),
            bvh_depth: bvh.depth,
        })
    }

    /// The arrays in binding order (1..=6) with their names, for upload and limit checks.
    pub fn arrays(&self) -> [(&'static str, &Vec4s); 6] {
        [
            ("BVH nodes", &self.nodes),
            ("triangles", &self.triangles),
            ("triangle attributes", &self.attributes),
            ("materials", &self.materials),
            ("texels", &self.texels),
            ("emitters", &self.emitters),
        ]
    }
}

/// A material's constant parameters as the shaders read them (`surface_material` in
/// trace.wgsl, the probe's first three records): (base colour, roughness), (specular colour,
/// specular), (metallic, transmission weight, ior, thin); no transmission is weight 0.
pub(crate) fn material_vec4s(m: &SurfaceMaterial) -> [[f32; 4]; 3] {
    let (weight, ior, thin) = match m.transmission {
        Some(t) => (t.weight, t.ior, if t.thin { 1.0 } else { 0.0 }),
        None => (0.0, 1.5, 0.0),
    };
    [v4(m.base_color, m.roughness), v4(m.specular_color, m.specular), [m.metallic, weight, ior, thin]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use glassbake_scene::builtin::builtin;

    #[test]
    fn emitter_table_ends_with_a_cumulative_probability_of_one() {
        let scene = builtin("cornellbox").unwrap();
        let buffers = SceneBuffers::build(&scene).unwrap();
        assert!(buffers.emitter_count > 0);
        let count = buffers.emitter_count as usize;
        let pmf_sum: f32 = (0..count).map(|i| buffers.emitters[EMITTER_VEC4S * i + 3][3]).sum();
        assert!((pmf_sum - 1.0).abs() < 1e-5, "{pmf_sum}");
        let last_cdf = buffers.emitters[EMITTER_VEC4S * (count - 1) + 5][0];
        assert!((last_cdf - 1.0).abs() < 1e-6, "{last_cdf}");
    }
}
