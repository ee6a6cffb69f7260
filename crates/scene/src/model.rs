//! The scene model every later stage consumes: meshes, textures, materials, objects, lights,
//! the camera ranges and the named variables.

use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use crate::camera_spec::CameraSpec;
use crate::variables::{Variable, VariableTarget};

/// A triangle mesh in object space. Normals and UVs are per vertex (same length as
/// `positions`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Append another mesh (used by shape builders to combine parts).
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.uvs.extend_from_slice(&other.uvs);
        self.indices.extend(other.indices.iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }

    /// Apply a transform to positions and normals (normals by the inverse transpose).
    pub fn transformed(&self, transform: &Affine3A) -> Mesh {
        let normal_matrix = transform.matrix3.inverse().transpose();
        Mesh {
            positions: self.positions.iter().map(|&p| transform.transform_point3(p)).collect(),
            normals: self.normals.iter().map(|&n| Vec3::from(normal_matrix * glam::Vec3A::from(n)).normalize_or_zero()).collect(),
            uvs: self.uvs.clone(),
            indices: self.indices.clone(),
        }
    }

    /// Axis-aligned bounds (min, max) in object space; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))))
    }

    /// Area-weighted vertex normals from the faces, for meshes loaded without normals.
    pub fn compute_vertex_normals(&mut self) {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for t in &self.indices {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let n = (b - a).cross(c - a);
            for &i in t {
                normals[i as usize] += n;
            }
        }
        self.normals = normals.into_iter().map(|n| n.normalize_or(Vec3::Y)).collect();
    }

    /// Drop triangles of (near) zero area or with an out-of-range index; returns how many
    /// were dropped.
    pub fn drop_degenerate_triangles(&mut self) -> usize {
        let before = self.indices.len();
        let positions = &self.positions;
        self.indices.retain(|t| {
            if t.iter().any(|&i| i as usize >= positions.len()) {
                return false;
            }
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let doubled_area = (b - a).cross(c - a).length();
            let scale = (b - a).length_squared().max((c - a).length_squared()).max(1e-30);
            doubled_area > 1e-7 * scale
        });
        before - self.indices.len()
    }
}

/// A texture in linear RGBA f32 (sRGB colour textures are decoded on load). Sampled with
/// repeat wrapping.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec4>,
    /// Whether the texture holds colour (sRGB-encoded when exported to 8-bit files) rather
    /// than data such as roughness.
    pub is_color: bool,
}

impl Texture {
    pub fn from_fn(name: &str, width: u32, height: u32, is_color: bool, f: impl Fn(f32, f32) -> Vec4) -> Self {
        let mut texels = Vec::with_capacity((width * height) as usize);
        for y in 0..height {
            for x in 0..width {
                let u = (x as f32 + 0.5) / width as f32;
                let v = (y as f32 + 0.5) / height as f32;
                texels.push(f(u, v));
            }
        }
        Texture { name: name.to_string(), width, height, texels, is_color }
    }

    /// The texel at integer coordinates, wrapping around (repeat).
    pub fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width as usize + x]
    }

    /// Bilinear sample with repeat wrapping; v = 0 is the top row (glTF convention).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let [x0, x1] = wrapped_pair(x0 as i64, self.width);
        let [y0, y1] = wrapped_pair(y0 as i64, self.height);
        let row = |y: usize| &self.texels[y * self.width as usize..][..self.width as usize];
        let (top, bottom) = (row(y0), row(y1));
        top[x0].lerp(top[x1], fx).lerp(bottom[x0].lerp(bottom[x1], fx), fy)
    }
}

/// A texture's mip levels: the texture, then each level half the one before on each side
/// (at least one texel), its texels the mean of the 2x2 they cover (the last row or column
/// of an odd side read twice). What a lookup over a footprint many texels wide reads
/// instead of a few point samples of the full-size texture, which alias.
#[derive(Clone, Debug, PartialEq)]
pub struct MipChain {
    pub levels: Vec<Texture>,
}

impl MipChain {
    pub fn new(texture: &Texture) -> MipChain {
        let mut levels = vec![texture.clone()];
        while let Some(last) = levels.last().filter(|t| t.width > 1 || t.height > 1) {
            let (width, height) = ((last.width / 2).max(1), (last.height / 2).max(1));
            let mut texels = Vec::with_capacity((width * height) as usize);
            let at = |x: u32, y: u32| last.texels[(y.min(last.height - 1) * last.width + x.min(last.width - 1)) as usize];
            for y in 0..height {
                for x in 0..width {
                    let (x2, y2) = (2 * x, 2 * y);
                    texels.push((at(x2, y2) + at(x2 + 1, y2) + at(x2, y2 + 1) + at(x2 + 1, y2 + 1)) * 0.25);
                }
            }
            let name = format!("{} (mip {})", texture.name, levels.len());
            levels.push(Texture { name, width, height, texels, is_color: texture.is_color });
        }
        MipChain { levels }
    }

    /// Trilinear: bilinear in the two levels about `lod` (0 the full-size texture, clamped to
    /// the chain), blended by its fraction.
    pub fn sample(&self, uv: Vec2, lod: f32) -> Vec4 {
        let top = (self.levels.len() - 1) as f32;
        let lod = if lod.is_nan() { 0.0 } else { lod.clamp(0.0, top) };
        let level = lod.floor();
        let blend = lod - level;
        let below = self.levels[level as usize].sample(uv);
        if blend == 0.0 {
            return below;
        }
        below.lerp(self.levels[level as usize + 1].sample(uv), blend)
    }
}

/// `i` and `i + 1` wrapped into `0..n` (repeat), as [`Texture::texel`] wraps them. Without a
/// division where both already lie inside, as they do for all but a texture's last row and
/// column: path tracers sample textures at every hit, and 64-bit divisions made up most of
/// the lookup's time.
#[inline]
fn wrapped_pair(i: i64, n: u32) -> [usize; 2] {
    let n = n as i64;
    if i >= 0 && i + 1 < n {
        return [i as usize, i as usize + 1];
    }
    let first = i.rem_euclid(n);
    [first as usize, if first + 1 == n { 0 } else { first as usize + 1 }]
}

/// How light passes through a transmissive material. The tint is the material's base colour
/// (glTF's convention for KHR_materials_transmission).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transmission {
    /// Fraction of non-metallic light that is transmitted rather than diffusely reflected
    /// (glTF `transmissionFactor`); 1 for clear glass.
    pub weight: f32,
    pub ior: f32,
    /// A thin-walled surface (a pane): light enters and leaves at the same point, without
    /// refraction offset. glTF: transmission without KHR_materials_volume, or thickness 0.
    pub thin: bool,
}

/// Below this roughness a dielectric is treated as perfectly smooth.
pub const SMOOTH_ROUGHNESS: f32 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum DielectricKind {
    Smooth,
    /// GGX microfacet transmission (Walter et al. 2007) with the material's roughness.
    Rough,
    Thin,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGB; for transmissive materials also the transmission tint.
    pub base_color: Vec3,
    /// Multiplies `base_color` (index into `Scene::textures`).
    pub base_color_texture: Option<usize>,
    /// GGX roughness parameter (perceptual, as in glTF: alpha = roughness^2).
    pub roughness: f32,
    /// Its green channel multiplies `roughness` (glTF metallic-roughness convention).
    pub roughness_texture: Option<usize>,
    pub metallic: f32,
    /// Strength of the dielectric specular layer over the diffuse base (glTF
    /// KHR_materials_specular `specularFactor`, default 1): 0 is a pure Lambertian surface.
    pub specular: f32,
    /// Its alpha channel multiplies `specular`.
    pub specular_texture: Option<usize>,
    /// Tints the dielectric reflectance at normal incidence: F0 = min(0.04 x colour, 1)
    /// (`specularColorFactor`, linear RGB, default white).
    pub specular_color: Vec3,
    /// Its RGB (sRGB-decoded) multiplies `specular_color`.
    pub specular_color_texture: Option<usize>,
    /// Emitted radiance (glTF emissiveFactor x emissive strength).
    pub emission: Vec3,
    pub transmission: Option<Transmission>,
}

impl Material {
    pub fn diffuse(name: &str, base_color: Vec3) -> Self {
        Material {
            name: name.to_string(),
            base_color,
            base_color_texture: None,
            roughness: 1.0,
            roughness_texture: None,
            metallic: 0.0,
            specular: 1.0,
            specular_texture: None,
            specular_color: Vec3::ONE,
            specular_color_texture: None,
            emission: Vec3::ZERO,
            transmission: None,
        }
    }

    /// A pure Lambertian surface: no specular layer (glTF specularFactor 0, OBJ illum 0/1).
    pub fn lambertian(name: &str, base_color: Vec3) -> Self {
        Material { specular: 0.0, ..Material::diffuse(name, base_color) }
    }

    /// Whether the specular layer has its glTF defaults (so older scene hashes still hold).
    pub fn has_default_specular(&self) -> bool {
        self.specular == 1.0 && self.specular_color == Vec3::ONE && self.specular_texture.is_none() && self.specular_color_texture.is_none()
    }

    pub fn glass(name: &str, tint: Vec3, roughness: f32, ior: f32, thin: bool) -> Self {
        Material { roughness, transmission: Some(Transmission { weight: 1.0, ior, thin }), ..Material::diffuse(name, tint) }
    }

    pub fn is_transmissive(&self) -> bool {
        self.transmission.is_some_and(|t| t.weight > 0.0)
    }

    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    pub fn dielectric_kind(&self) -> Option<DielectricKind> {
        let t = self.transmission?;
        Some(if t.thin {
            DielectricKind::Thin
        } else if self.roughness < SMOOTH_ROUGHNESS {
            DielectricKind::Smooth
        } else {
            DielectricKind::Rough
        })
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub name: String,
    /// Index into `Scene::meshes`.
    pub mesh: usize,
    /// Index into `Scene::materials`.
    pub material: usize,
    /// Object-to-world transform.
    pub transform: Affine3A,
    /// Transparent objects each get their own transparency buffer.
    pub transparent: bool,
}

/// A one-sided (unless `two_sided`) rectangular area light emitting uniform radiance from the
/// side of `edge_u x edge_v`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RectLight {
    pub name: String,
    pub corner: Vec3,
    pub edge_u: Vec3,
    pub edge_v: Vec3,
    pub radiance: Vec3,
    #[serde(default)]
    pub two_sided: bool,
}

impl RectLight {
    pub fn normal(&self) -> Vec3 {
        self.edge_u.cross(self.edge_v).normalize()
    }
    pub fn area(&self) -> f32 {
        self.edge_u.cross(self.edge_v).length()
    }
    pub fn center(&self) -> Vec3 {
        self.corner + 0.5 * (self.edge_u + self.edge_v)
    }
    /// Corners in counter-clockwise order seen from the emitting side.
    pub fn corners(&self) -> [Vec3; 4] {
        let c = self.corner;
        [c, c + self.edge_u, c + self.edge_u + self.edge_v, c + self.edge_v]
    }
    /// The light as two triangles facing its emitting side.
    pub fn to_mesh(&self) -> Mesh {
        let n = self.normal();
        Mesh {
            positions: self.corners().to_vec(),
            normals: vec![n; 4],
            uvs: vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)],
            indices: vec![[0, 1, 2], [0, 2, 3]],
        }
    }
}

/// A complete scene: geometry, appearance, lights, the camera ranges and the variables.
/// Cloning is cheap (meshes and textures are shared), which is what makes
/// [`Scene::instantiate`] cheap.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub meshes: Vec<Arc<Mesh>>,
    pub textures: Vec<Arc<Texture>>,
    pub materials: Vec<Material>,
    pub objects: Vec<Object>,
    pub rect_lights: Vec<RectLight>,
    pub camera: CameraSpec,
    pub variables: Vec<Variable>,
    /// Constant radiance seen where rays leave the scene.
    pub background: Vec3,
    /// Warnings raised while loading (dropped triangles, unsupported extensions, ...).
    pub load_warnings: Vec<String>,
}

impl Scene {
    /// Name of what `variable` acts on (a material, an object or a light), for display.
    pub fn variable_target_name(&self, variable: &Variable) -> &str {
        match variable.target {
            VariableTarget::Roughness { material } | VariableTarget::Hue { material, .. } | VariableTarget::EmissionIntensity { material } => {
                &self.materials[material].name
            }
            VariableTarget::Translation { object, .. } => &self.objects[object].name,
            VariableTarget::LightTranslation { light, .. } | VariableTarget::LightIntensity { light } => &self.rect_lights[light].name,
        }
    }

    /// A scene with nothing in it, a camera framing the unit cube, and no variables.
    pub fn empty(name: &str) -> Scene {
        Scene {
            name: name.to_string(),
            meshes: Vec::new(),
            textures: Vec::new(),
            materials: Vec::new(),
            objects: Vec::new(),
            rect_lights: Vec::new(),
            camera: CameraSpec::framing(Vec3::splat(-1.0), Vec3::ONE),
            variables: Vec::new(),
            background: Vec3::ZERO,
            load_warnings: Vec::new(),
        }
    }

    /// Indices (into `objects`) of the transparent objects; transparency buffer `k` belongs
    /// to the `k`-th of them.
    pub fn transparent_objects(&self) -> Vec<usize> {
        (0..self.objects.len()).filter(|&i| self.objects[i].transparent).collect()
    }

    pub fn transparent_count(&self) -> usize {
        self.objects.iter().filter(|o| o.transparent).count()
    }

    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| self.meshes[o.mesh].triangle_count()).sum()
    }

    /// Objects whose material emits light (emissive-mesh area lights).
    pub fn emissive_objects(&self) -> Vec<usize> {
        (0..self.objects.len()).filter(|&i| self.materials[self.objects[i].material].is_emissive()).collect()
    }

    pub fn light_count(&self) -> usize {
        self.rect_lights.len() + self.emissive_objects().len()
    }

    pub fn object_index(&self, name: &str) -> Option<usize> {
        self.objects.iter().position(|o| o.name == name)
    }
    pub fn material_index(&self, name: &str) -> Option<usize> {
        self.materials.iter().position(|m| m.name == name)
    }
    pub fn light_index(&self, name: &str) -> Option<usize> {
        self.rect_lights.iter().position(|l| l.name == name)
    }

    /// An object's mesh in world space.
    pub fn world_mesh(&self, object: usize) -> Mesh {
        let o = &self.objects[object];
        self.meshes[o.mesh].transformed(&o.transform)
    }

    /// World-space bounds of all objects and lights.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut acc: Option<(Vec3, Vec3)> = None;
        let mut add = |p: Vec3| {
            acc = Some(match acc {
                None => (p, p),
                Some((lo, hi)) => (lo.min(p), hi.max(p)),
            })
        };
        for o in &self.objects {
            for &p in &self.meshes[o.mesh].positions {
                add(o.transform.transform_point3(p));
            }
        }
        for l in &self.rect_lights {
            for p in l.corners() {
                add(p);
            }
        }
        acc
    }

    /// Non-fatal problems a user should hear about.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = self.load_warnings.clone();
        if self.transparent_count() == 0 {
            w.push("the scene has no transparent object: GlassNet degenerates to a plain G-buffer renderer".into());
        }
        if self.light_count() == 0 {
            w.push("the scene has no light (no rectangle light, no emissive mesh): it renders black".into());
        }
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_sample_interpolates_between_texel_centres_and_wraps_at_the_seam() {
        let texture = Texture::from_fn("ramp", 4, 2, false, |u, v| Vec4::new(u, v, u * v, 1.0));
        // At a texel's centre the sample is that texel.
        assert_eq!(texture.sample(Vec2::new(2.5 / 4.0, 0.5 / 2.0)), texture.texels[2]);
        // Halfway between two centres, their mean.
        assert_eq!(texture.sample(Vec2::new(2.0 / 4.0, 0.5 / 2.0)), (texture.texels[1] + texture.texels[2]) * 0.5);
        // On the left edge, halfway between the last column and the first (repeat wrapping),
        // and the same one period over in u and v.
        let seam = (texture.texels[0] + texture.texels[3]) * 0.5;
        assert_eq!(texture.sample(Vec2::new(0.0, 0.5 / 2.0)), seam);
        assert_eq!(texture.sample(Vec2::new(-3.0, 1.0 + 0.5 / 2.0)), seam);
    }

    #[test]
    fn a_mip_chain_halves_to_one_texel_keeping_the_mean() {
        // A 4x2 checker of 0 and 1 (odd texel sums): level 1 is 2x1 of 0.5, level 2 one texel.
        let texture = Texture::from_fn("checker", 4, 2, false, |u, v| Vec4::splat((((u * 4.0) as u32 + (v * 2.0) as u32) % 2) as f32));
        let chain = MipChain::new(&texture);
        let sizes: Vec<(u32, u32)> = chain.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(4, 2), (2, 1), (1, 1)]);
        assert!(chain.levels[1].texels.iter().chain(&chain.levels[2].texels).all(|&t| t == Vec4::splat(0.5)));
        // An odd side: 3x3 of its indices; level 1 is one texel over the first 2x2.
        let odd = Texture::from_fn("odd", 3, 3, false, |u, v| Vec4::splat((u * 3.0).floor() + 3.0 * (v * 3.0).floor()));
        let odd_chain = MipChain::new(&odd);
        assert_eq!(odd_chain.levels.len(), 2);
        assert_eq!(odd_chain.levels[1].texels, [Vec4::splat((0.0 + 1.0 + 3.0 + 4.0) / 4.0)]);
    }

    #[test]
    fn a_mip_lookup_blends_the_two_levels_about_its_level_and_clamps() {
        let texture = Texture::from_fn("ramp", 8, 8, false, |u, v| Vec4::new(u, v, u * v, 1.0));
        let chain = MipChain::new(&texture);
        let uv = Vec2::new(0.3, 0.6);
        assert_eq!(chain.sample(uv, 0.0), texture.sample(uv));
        assert_eq!(chain.sample(uv, -3.0), texture.sample(uv));
        let (one, two) = (chain.levels[1].sample(uv), chain.levels[2].sample(uv));
        assert!((chain.sample(uv, 1.25) - (one * 0.75 + two * 0.25)).abs().max_element() < 1e-6);
        // Past the last level: the texture's mean, one texel.
        let mean = texture.texels.iter().fold(Vec4::ZERO, |s, &t| s + t) / 64.0;
        assert!((chain.sample(uv, 9.0) - mean).abs().max_element() < 1e-6);
        assert_eq!(chain.sample(uv, f32::NAN), texture.sample(uv));
    }

    #[test]
    fn neighbouring_texels_wrap_as_single_texels_do() {
        for n in 1..6u32 {
            for i in -13..13i64 {
                let expected = [i.rem_euclid(n as i64) as usize, (i + 1).rem_euclid(n as i64) as usize];
                assert_eq!(wrapped_pair(i, n), expected, "i {i}, n {n}");
            }
        }
    }
}
