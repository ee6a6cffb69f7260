//! What each transparent object shows through itself: camera rays from the centre and over
//! the footprint of every pixel it covers, refracted at each of its surfaces (Snell's law with
//! its IOR, total internal reflection followed), to the first opaque surface or light behind
//! it, or the background where it leaves the scene, reading textures over each ray's share of
//! the footprint (through the footprint's ray differential, or at a mip level). The other
//! transparent objects are ignored, so a through buffer depends on its own object only, as
//! GlassNet's permutation-invariant sum of per-object terms needs. Channels:
//! `layout::THROUGH_ATTRIBUTES`.
//!
//! The pass casts rays on the CPU in two BVHs per ray (the opaque scene with its lights, and
//! the object alone), so neither the BVHs nor the rays depend on the other transparent objects.

use std::sync::Arc;

use glam::{Mat2, Vec2, Vec3, Vec4};
use glassbake_core::camera::Camera;
use glassbake_core::image::PlanarImage;
use glassbake_core::layout::{self, opaque, through, transparent};
use glassbake_scene::model::SMOOTH_ROUGHNESS;
use glassbake_scene::{MipChain, Scene, Texture};
use rayon::prelude::*;

use crate::direct::{diffuse_share, unseen_direct_light};
use crate::geometry::{scene_triangles, SceneGeometry};
use crate::optics::{fresnel_dielectric, reflect, refract, thin_slab_reflectance};
use crate::triangle::{Hit, Owner, TriangleAttributes};

/// Surfaces of the object a ray may cross (refractions and internal reflections) before it
/// is given up. A convex lens takes 2; a hollow globe 4; the rest is total internal
/// reflection bouncing inside thick glass, which loses no light and can take many surfaces:
/// on cornellbox8 the rays of 3.3% of the pixels its glass bunny covers crossed more than 8,
/// 1.2% more than 16 and 0.3% more than 32 (the test split), and those pixels are brighter
/// than the rest of the bunny.
pub const MAX_INTERFACES: usize = 32;

/// A hit closer than this (in scene units) to where the ray left a surface is that surface.
pub(crate) const SELF_HIT: f32 = 1e-4;

/// A hit is in view of the camera when nothing opaque lies between them, short of the hit by
/// this share of its distance (so the hit's own surface does not hide it).
pub(crate) const VIEW_SLACK: f32 = 1e-3;

/// The BVHs a frame's through buffers are cast in: the opaque scene (its lights included)
/// and each transparent object alone, in `Scene::transparent_objects` order.
pub struct ThroughScene {
    opaque: SceneGeometry,
    objects: Vec<SceneGeometry>,
    object_indices: Vec<usize>,
    /// `Scene::textures`' mip chains, for lookups over a footprint, and the textures they
    /// were made from.
    mips: Vec<MipChain>,
    textures: Vec<Arc<Texture>>,
}

impl ThroughScene {
    pub fn build(scene: &Scene) -> ThroughScene {
        let object_indices = scene.transparent_objects();
        let opaque = SceneGeometry::from_triangles(scene_triangles(scene, &|o| !scene.objects[o].transparent, true, &|_, _| None));
        let objects = object_indices.iter().map(|&k| SceneGeometry::from_triangles(scene_triangles(scene, &|o| o == k, false, &|_, _| None))).collect();
        let mips = scene.textures.iter().map(|t| MipChain::new(t)).collect();
        ThroughScene { opaque, objects, object_indices, mips, textures: scene.textures.clone() }
    }

    /// [`Self::build`] for a new instance of the same scene (a variable moved an object or a
    /// light, or no geometry at all): each BVH whose triangle count is unchanged is refit
    /// rather than built (`SceneGeometry::refit_or_build`).
    pub fn refit_or_build(self, scene: &Scene) -> ThroughScene {
        let object_indices = scene.transparent_objects();
        if object_indices != self.object_indices {
            return Self::build(scene);
        }
        let opaque = self.opaque.refit_or_build(scene_triangles(scene, &|o| !scene.objects[o].transparent, true, &|_, _| None));
        let objects = self
            .objects
            .into_iter()
            .zip(&object_indices)
            .map(|(geometry, &k)| geometry.refit_or_build(scene_triangles(scene, &|o| o == k, false, &|_, _| None)))
            .collect();
        // An instance shares its textures with the scene it came from; a new set is new mips.
        let same_textures = self.textures.len() == scene.textures.len() && self.textures.iter().zip(&scene.textures).all(|(a, b)| Arc::ptr_eq(a, b));
        let mips = if same_textures { self.mips } else { scene.textures.iter().map(|t| MipChain::new(t)).collect() };
        ThroughScene { opaque, objects, object_indices, mips, textures: scene.textures.clone() }
    }

    pub fn object_count(&self) -> usize {
        self.objects.len()
    }
}

/// Where a ray through transparent object k ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThroughHit {
    pub position: Vec3,
    /// The shading normal, on the side the ray arrives from.
    pub normal: Vec3,
    /// The base colour times the full-size texture's colour at the hit.
    pub albedo: Vec3,
    /// The share of the albedo that reflects diffusely (`direct::diffuse_share`); 0 on a
    /// light or the background.
    pub diffuse: f32,
    /// Where the hit reads a texture: its material and UV.
    pub textured: Option<(usize, Vec2)>,
    /// A light's radiance where the ray meets a light's emitting side, the background's where
    /// it leaves the scene; for a surface, its emission (the G-buffer's L_d is looked up
    /// separately, see [`through_buffer`]).
    pub emitted: Vec3,
    /// The ray ends on a light: a rectangle light, or the background.
    pub is_light: bool,
    /// The ray left the scene: `position` is where it last left a surface of the object,
    /// `normal` faces back along it, and the background's light is what it brings.
    pub background: bool,
    pub transmittance: f32,
    /// Distance travelled inside the object.
    pub length: f32,
    /// Distance travelled from the ray's origin, inside the object and out.
    pub path_length: f32,
    /// Surfaces of the object crossed or reflected from.
    pub interfaces: usize,
}

/// Follow the ray from `origin` along unit `direction` through transparent object `k` of
/// `geometry` (index into `Scene::transparent_objects`), bent by the shading normal at every
/// surface: for rough glass the mean direction of its lobe. A ray that leaves the scene ends
/// on the background ([`ThroughHit::background`]), as a path of the tracer does; `None` when
/// it crosses more than [`MAX_INTERFACES`] surfaces.
pub fn trace_through(scene: &Scene, geometry: &ThroughScene, k: usize, origin: Vec3, direction: Vec3) -> Option<ThroughHit> {
    trace_path(scene, geometry, k, origin, direction, &mut |n, _| n)
}

/// [`trace_through`] with the normal at the `i`-th surface crossed chosen by
/// `normal_at(shading normal, i)`: a microfacet normal of rough glass. A thin pane sends the
/// ray on mirrored through its plane after reflecting it about that normal (the tracer's thin
/// rough BTDF, `glassbake_trace::bsdf`), which for the shading normal itself is straight on.
fn trace_path(
    scene: &Scene,
    geometry: &ThroughScene,
    k: usize,
    origin: Vec3,
    direction: Vec3,
    normal_at: &mut dyn FnMut(Vec3, usize) -> Vec3,
) -> Option<ThroughHit> {
    let object = &scene.objects[geometry.object_indices[k]];
    let transmission = scene.materials[object.material].transmission;
    let ior = transmission.map_or(1.0, |t| t.ior);
    let thin = transmission.is_some_and(|t| t.thin);
    let glass = &geometry.objects[k];
    let (mut origin, mut direction) = (origin, direction);
    let (mut inside, mut transmittance, mut length, mut interfaces) = (false, 1.0f32, 0.0f32, 0usize);
    let mut path_length = 0.0f32;
    let mut t_min = 0.0;
    loop {
        let glass_hit = glass.closest_hit(origin, direction, t_min, f32::INFINITY);
        let opaque_hit = geometry.opaque.closest_hit(origin, direction, t_min, glass_hit.map_or(f32::INFINITY, |h| h.t));
        if let Some(hit) = opaque_hit {
            if inside {
                length += hit.t;
            }
            let path = Path { transmittance, length, path_length: path_length + hit.t, interfaces };
            let triangle = &geometry.opaque.attributes[hit.triangle as usize];
            return Some(surface_hit(scene, triangle, &hit, origin, direction, path));
        }
        let Some(hit) = glass_hit else {
            return Some(background_end(scene, origin, direction, Path { transmittance, length, path_length, interfaces }));
        };
        if interfaces == MAX_INTERFACES {
            return None;
        }
        if inside {
            length += hit.t;
        }
        path_length += hit.t;
        let position = origin + direction * hit.t;
        let triangle = &glass.attributes[hit.triangle as usize];
        let n = triangle.shading_normal(&hit, triangle.face_normal());
        let m = normal_at(n, interfaces);
        interfaces += 1;
        let wo = -direction;
        if thin {
            let reflected = reflect(wo, m);
            if reflected.dot(n).signum() != wo.dot(n).signum() {
                return None;
            }
            transmittance *= 1.0 - thin_slab_reflectance(m.dot(wo), ior);
            direction = (reflected - 2.0 * reflected.dot(n) * n).normalize();
        } else {
            // The normal on the outside: towards the ray's origin while it is outside.
            let outward = if (n.dot(wo) > 0.0) != inside { m } else { -m };
            match refract(wo, outward, ior) {
                Some((refracted, _)) => {
                    transmittance *= 1.0 - fresnel_dielectric(outward.dot(wo), ior);
                    direction = refracted.normalize();
                    inside = !inside;
                }
                None => direction = reflect(wo, outward).normalize(),
            }
        }
        origin = position;
        t_min = SELF_HIT;
    }
}

/// Rays per pixel through rough glass: what it shows is the mean over its lobe.
pub const LOBE_SAMPLES: usize = 16;

/// The points of a pixel its footprint's rays start from, in pixels from its centre (right,
/// down): the rotated grid of Direct3D 11's standard 4x multisample pattern (sample positions
/// (-2, -6), (6, -2), (-6, 2), (2, 6) in sixteenths of a pixel), which sees each quarter of
/// the pixel once and no two points on one row or column. Rough glass's lobe samples start
/// from them in turn.
pub const FOOTPRINT: [[f32; 2]; 4] = [[-0.125, -0.375], [0.375, -0.125], [-0.375, 0.125], [0.125, 0.375]];

/// The RMS distance of [`FOOTPRINT`]'s points from the pixel's centre, in pixels: the spread
/// of their hits on a surface facing the camera with nothing between, per pixel of distance.
pub const FOOTPRINT_RMS: f32 = 0.395_284_7;

/// The `spread` channel (`layout::THROUGH_ATTRIBUTES`) for the footprint hits at `positions`
/// of a pixel whose centre's path is `path_length` long, `pixel_size` the side of a pixel at
/// distance 1 from the camera (2 tan(fov_y / 2) / height).
pub fn footprint_spread(positions: &[Vec3], path_length: f32, pixel_size: f32) -> f32 {
    if positions.is_empty() || path_length.is_nan() || path_length <= 0.0 {
        return 0.0;
    }
    let n = positions.len() as f32;
    let mean = positions.iter().fold(Vec3::ZERO, |sum, &p| sum + p) / n;
    let rms = (positions.iter().map(|&p| (p - mean).length_squared()).sum::<f32>() / n).sqrt();
    (1.0 + rms / (FOOTPRINT_RMS * path_length * pixel_size)).log2()
}

/// A GGX microfacet normal about `n` (alpha = roughness^2, the tracer's and the rasterizer's
/// convention), from the distribution of normals D(m) cos(theta_m): tan^2 theta = alpha^2 u /
/// (1 - u) (Walter et al. 2007, eq. 35-36).
fn ggx_normal(n: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let tan2 = alpha * alpha * u.x / (1.0 - u.x).max(1e-6);
    let cos = 1.0 / (1.0 + tan2).sqrt();
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    let (t, b) = n.any_orthonormal_pair();
    (t * (sin * phi.cos()) + b * (sin * phi.sin()) + n * cos).normalize()
}

/// The `s`-th of [`LOBE_SAMPLES`] points for surface `interface` of pixel (`x`, `y`) of
/// object `k`: a Hammersley set, shifted per pixel and surface (Cranley-Patterson) so that
/// neighbours do not share it. The GPU pass (`shaders/through.wgsl`) draws the same points.
fn lobe_point(s: usize, interface: usize, x: u32, y: u32, k: usize) -> Vec2 {
    let shift = pcg4d([x, y, k as u32, interface as u32]);
    let unit = |v: u32| (v >> 8) as f32 / (1u32 << 24) as f32;
    let u = Vec2::new((s as f32 + 0.5) / LOBE_SAMPLES as f32, (s as u32).reverse_bits() as f32 / 4_294_967_296.0);
    Vec2::new((u.x + unit(shift[0])).fract(), (u.y + unit(shift[1])).fract())
}

/// pcg4d (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering", JCGT 9(3)): four
/// well-mixed words from four, in 32-bit arithmetic a shader has too.
fn pcg4d(input: [u32; 4]) -> [u32; 4] {
    let mut v = input.map(|w| w.wrapping_mul(1_664_525).wrapping_add(1_013_904_223));
    let mix = |v: &mut [u32; 4]| {
        v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[3]));
        v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
        v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
        v[3] = v[3].wrapping_add(v[1].wrapping_mul(v[2]));
    };
    mix(&mut v);
    v = v.map(|w| w ^ (w >> 16));
    mix(&mut v);
    v
}

/// What a path carried to the surface it ends on.
struct Path {
    transmittance: f32,
    length: f32,
    path_length: f32,
    interfaces: usize,
}

fn surface_hit(scene: &Scene, triangle: &TriangleAttributes, hit: &Hit, origin: Vec3, direction: Vec3, path: Path) -> ThroughHit {
    let Path { transmittance, length, path_length, interfaces } = path;
    let position = origin + direction * hit.t;
    let n = triangle.shading_normal(hit, triangle.face_normal());
    let normal = if n.dot(direction) > 0.0 { -n } else { n };
    let (albedo, diffuse, textured, emitted, is_light) = match triangle.owner {
        Owner::Object { material: index, .. } => {
            let material = &scene.materials[index as usize];
            let uv = triangle.uv(hit);
            let texture = material.base_color_texture.map_or(Vec3::ONE, |t| scene.textures[t].sample(uv).truncate());
            let textured = material.base_color_texture.map(|_| (index as usize, uv));
            (material.base_color * texture, diffuse_share(material), textured, material.emission, false)
        }
        Owner::RectLight { light } => {
            let light = &scene.rect_lights[light as usize];
            let front = light.normal().dot(direction) < 0.0;
            (Vec3::ZERO, 0.0, None, if front || light.two_sided { light.radiance } else { Vec3::ZERO }, true)
        }
    };
    ThroughHit { position, normal, albedo, diffuse, textured, emitted, is_light, background: false, transmittance, length, path_length, interfaces }
}

/// Where a ray leaving the scene from `origin` along `direction` ends: on the background,
/// whose radiance it brings, as the tracer's escaped paths do (on desk, 14% of the pixels the
/// glass block covers send their rays out of the scene after internal reflections).
fn background_end(scene: &Scene, origin: Vec3, direction: Vec3, path: Path) -> ThroughHit {
    let Path { transmittance, length, path_length, interfaces } = path;
    ThroughHit {
        position: origin,
        normal: -direction,
        albedo: Vec3::ZERO,
        diffuse: 0.0,
        textured: None,
        emitted: scene.background,
        is_light: true,
        background: true,
        transmittance,
        length,
        path_length,
        interfaces,
    }
}

/// The mip level a hit reads its texture at so that it averages its share of the pixel: the
/// footprint's `paths` paths each stand for 1/`paths` of its area, whose side in texels is
/// estimated from how far the hits `uvs` on the same material spread (their RMS distance from
/// their mean over the footprint's own, [`FOOTPRINT_RMS`] pixels), over `size` texels.
/// Level 0 where fewer than two hits share the material, or where the footprint spans less
/// than a texel a path. The GPU pass (`shaders/through.wgsl`) computes the same.
pub fn footprint_lod(uvs: &[Vec2], size: Vec2, paths: usize) -> f32 {
    if uvs.len() < 2 {
        return 0.0;
    }
    let n = uvs.len() as f32;
    let mean = uvs.iter().fold(Vec2::ZERO, |sum, &uv| sum + uv) / n;
    let rms = (uvs.iter().map(|&uv| ((uv - mean) * size).length_squared()).sum::<f32>() / n).sqrt();
    let side = rms / (FOOTPRINT_RMS * (paths as f32).sqrt());
    side.max(1.0).log2()
}

/// How a footprint's texture coordinates move across the pixel, per pixel right and down:
/// the least-squares affine map from [`FOOTPRINT`]'s offsets to the `uvs` its rays hit, one
/// each in its order, in texels of a texture `size` texels large. A ray differential measured
/// on the rays themselves, so it holds through every refraction the paths took.
pub fn footprint_gradients(uvs: &[Vec2; 4], size: Vec2) -> Mat2 {
    let n = FOOTPRINT.len() as f32;
    let offsets = FOOTPRINT.map(Vec2::from_array);
    let (mean_offset, mean_uv) = (offsets.iter().sum::<Vec2>() / n, uvs.iter().sum::<Vec2>() / n);
    let outer = |a: Vec2, b: Vec2| Mat2::from_cols(a * b.x, a * b.y);
    let (mut spread, mut moved) = (Mat2::ZERO, Mat2::ZERO);
    for (&d, &uv) in offsets.iter().zip(uvs) {
        spread += outer(d - mean_offset, d - mean_offset);
        moved += outer((uv - mean_uv) * size, d - mean_offset);
    }
    moved * spread.inverse()
}

/// The sub-cells a footprint ray's texture is read over: the four quarters of its own quarter
/// of the pixel, each read with half its side's gradients so that the 16 lookups' filters
/// tile the pixel rather than overlap (the G-buffers read textures the same way,
/// `glassbake_raster`'s `footprint_sample`). Offsets in pixels from the ray's quarter's centre.
pub const CELL_TAPS: [[f32; 2]; 4] = [[-0.125, -0.125], [0.125, -0.125], [-0.125, 0.125], [0.125, 0.125]];

/// The mean of `chain` over quarter `point` of a pixel whose footprint ray there hit `uv`, the
/// pixel's texture coordinates moving by `gradients` (texels per pixel, [`footprint_gradients`]).
pub fn footprint_cell_sample(chain: &MipChain, uv: Vec2, point: usize, gradients: Mat2) -> Vec4 {
    let size = Vec2::new(chain.levels[0].width as f32, chain.levels[0].height as f32);
    let ray = Vec2::from_array(FOOTPRINT[point]);
    let quarter = Vec2::new(0.25_f32.copysign(ray.x), 0.25_f32.copysign(ray.y));
    let half_cell = 0.125 * gradients.x_axis.length().max(gradients.y_axis.length());
    let lod = half_cell.max(1.0).log2();
    CELL_TAPS.iter().map(|&tap| chain.sample(uv + gradients * (quarter + Vec2::from_array(tap) - ray) / size, lod)).sum::<Vec4>() / CELL_TAPS.len() as f32
}

/// The albedo of `hit`, one of a pixel's footprint `hits`, its texture read over its share
/// of the footprint rather than at one point. Where all [`FOOTPRINT`]'s rays reach the same
/// textured material, over its quarter's sub-cells through the rays' own differential
/// ([`footprint_cell_sample`]); otherwise (rough glass's lobe, lost rays, an edge between
/// materials) at the mip level of its share ([`footprint_lod`]). `last` keeps what was worked
/// out for the last material asked for: a footprint's hits mostly share one, and it depends on
/// all of them.
fn footprint_albedo(
    scene: &Scene,
    mips: &[MipChain],
    point: usize,
    hit: &ThroughHit,
    hits: &[ThroughHit],
    paths: usize,
    last: &mut Option<(usize, TextureRead)>,
) -> Vec3 {
    let Some((index, uv)) = hit.textured else { return hit.albedo };
    let material = &scene.materials[index];
    let Some(texture) = material.base_color_texture else { return hit.albedo };
    let chain = &mips[texture];
    let read = match *last {
        Some((m, read)) if m == index => read,
        _ => {
            let mut uvs = [Vec2::ZERO; LOBE_SAMPLES];
            let mut count = 0;
            for (_, uv) in hits.iter().filter_map(|h| h.textured).filter(|&(m, _)| m == index) {
                uvs[count] = uv;
                count += 1;
            }
            let size = Vec2::new(chain.levels[0].width as f32, chain.levels[0].height as f32);
            let read = if paths == FOOTPRINT.len() && count == paths {
                TextureRead::Cells(footprint_gradients(&[uvs[0], uvs[1], uvs[2], uvs[3]], size))
            } else {
                TextureRead::Level(footprint_lod(&uvs[..count], size, paths))
            };
            *last = Some((index, read));
            read
        }
    };
    let texel = match read {
        TextureRead::Cells(gradients) => footprint_cell_sample(chain, uv, point, gradients),
        TextureRead::Level(lod) => chain.sample(uv, lod),
    };
    material.base_color * texel.truncate()
}

/// How a footprint's hits on one material read its texture.
#[derive(Clone, Copy)]
enum TextureRead {
    /// Over each ray's quarter of the pixel, with the footprint's uv gradients.
    Cells(Mat2),
    /// At one point, at this mip level.
    Level(f32),
}

/// The through buffer of transparent object `k` for a frame: `layout::through_channel_names(k)`,
/// cast for the pixels where its transparency buffer's `coverage` plane is above 0: the
/// surface the pixel's centre sees, and its albedo and light averaged over the pixel's
/// [`FOOTPRINT`] (or its lobe's samples through rough glass), with how far that footprint
/// spreads. L_d comes from `opaque_gbuffer` where the camera sees the hit, at the pixel it
/// projects to; where it does not, it is the hit's emission and the lights' direct diffuse
/// light there ([`unseen_direct_light`]); a light's is its radiance, the background's where
/// the ray leaves the scene.
pub fn through_buffer(scene: &Scene, geometry: &ThroughScene, k: usize, camera: &Camera, opaque_gbuffer: &PlanarImage, coverage: &[f32]) -> PlanarImage {
    let (width, height) = (opaque_gbuffer.width(), opaque_gbuffer.height());
    let pixels = (width * height) as usize;
    assert_eq!(coverage.len(), pixels, "one coverage value per pixel of the frame");
    let material = &scene.materials[scene.objects[geometry.object_indices[k]].material];
    let alpha = (material.roughness >= SMOOTH_ROUGHNESS).then_some(material.roughness * material.roughness);
    // `albedo` is the hit's over its share of the footprint, `point` its path's index there.
    let light_at = |hit: &ThroughHit, view: Option<((u32, u32), bool)>, albedo: Vec3, point: usize| match view {
        _ if hit.is_light => hit.emitted,
        Some(((sx, sy), true)) => opaque_light(opaque_gbuffer, sx, sy),
        _ => hit.emitted + unseen_direct_light(scene, &geometry.opaque, hit.position, hit.normal, albedo * hit.diffuse, point),
    };
    let rays = camera.primary_rays(width, height);
    let pixel_size = 2.0 * camera.tan_half_fov(width, height).1 / height as f32;
    let footprint_ray = |x: u32, y: u32, point: usize| {
        let [dx, dy] = FOOTPRINT[point % FOOTPRINT.len()];
        rays.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy)
    };
    let rows: Vec<Vec<[f32; layout::THROUGH_CHANNELS]>> = (0..height)
        .into_par_iter()
        .map(|y| {
            (0..width)
                .map(|x| {
                    let mut out = [0.0; layout::THROUGH_CHANNELS];
                    if coverage[(y * width + x) as usize] <= 0.0 {
                        return out;
                    }
                    let ray = rays.ray(x as f32 + 0.5, y as f32 + 0.5);
                    let Some(hit) = trace_through(scene, geometry, k, ray.origin, ray.direction) else { return out };
                    // The background is nowhere on screen.
                    let view = if hit.background { None } else { on_screen(camera, geometry, opaque_gbuffer, hit.position) };
                    // What the pixel shows is the mean over its footprint: a path a ray loses
                    // (it is reflected away, or crosses too many surfaces) adds nothing.
                    let paths = match alpha {
                        None => FOOTPRINT.len(),
                        Some(_) => LOBE_SAMPLES,
                    };
                    let mut hits = Vec::with_capacity(paths);
                    for sample in 0..paths {
                        let ray = footprint_ray(x, y, sample);
                        let end = match alpha {
                            None => trace_through(scene, geometry, k, ray.origin, ray.direction),
                            Some(alpha) => {
                                let mut microfacet = |n: Vec3, interface: usize| ggx_normal(n, alpha, lobe_point(sample, interface, x, y, k));
                                trace_path(scene, geometry, k, ray.origin, ray.direction, &mut microfacet)
                            }
                        };
                        hits.extend(end);
                    }
                    let (mut albedo, mut light, mut transmittance) = (Vec3::ZERO, Vec3::ZERO, 0.0);
                    let mut positions = [Vec3::ZERO; LOBE_SAMPLES];
                    let mut last_read = None;
                    for (j, h) in hits.iter().enumerate() {
                        let hit_albedo = footprint_albedo(scene, &geometry.mips, j, h, &hits, paths, &mut last_read);
                        albedo += hit_albedo * h.transmittance;
                        let view = if h.is_light { None } else { on_screen(camera, geometry, opaque_gbuffer, h.position) };
                        light += light_at(h, view, hit_albedo, j) * h.transmittance;
                        transmittance += h.transmittance;
                        positions[j] = h.position;
                    }
                    let positions = &positions[..hits.len()];
                    // Albedo and light as seen: weighted by what each path lets through.
                    if transmittance > 0.0 {
                        (albedo, light) = (albedo / transmittance, light / transmittance);
                    }
                    transmittance /= paths as f32;
                    if let Some(((sx, sy), shown)) = view {
                        out[through::SCREEN_OFFSET] = sx as f32 - x as f32;
                        out[through::SCREEN_OFFSET + 1] = sy as f32 - y as f32;
                        out[through::ON_SCREEN] = f32::from(u8::from(shown));
                    }
                    out[through::POSITION..through::POSITION + 3].copy_from_slice(&hit.position.to_array());
                    out[through::NORMAL..through::NORMAL + 3].copy_from_slice(&hit.normal.to_array());
                    out[through::ALBEDO..through::ALBEDO + 3].copy_from_slice(&albedo.to_array());
                    out[through::LD..through::LD + 3].copy_from_slice(&light.to_array());
                    out[through::TRANSMITTANCE] = transmittance;
                    out[through::LENGTH] = hit.length;
                    out[through::SPREAD] = footprint_spread(positions, hit.path_length, pixel_size);
                    out
                })
                .collect()
        })
        .collect();
    let mut data = vec![0.0; layout::THROUGH_CHANNELS * pixels];
    for (i, pixel) in rows.iter().flatten().enumerate() {
        for (c, &v) in pixel.iter().enumerate() {
            data[c * pixels + i] = v;
        }
    }
    PlanarImage::from_planes(width, height, layout::through_channel_names(k), data).expect("the through planes match their names")
}

/// The pixel `position` projects to, if inside the frame, and whether the camera sees that
/// point there: a ray from the camera to it meets nothing opaque before it. (Comparing with
/// the G-buffer's position at that pixel instead missed 40% of the hits on cornellbox8's
/// bunny that were in view: on a floor seen at a grazing angle one pixel spans more than any
/// fixed tolerance.)
fn on_screen(camera: &Camera, geometry: &ThroughScene, opaque_gbuffer: &PlanarImage, position: Vec3) -> Option<((u32, u32), bool)> {
    let (width, height) = (opaque_gbuffer.width(), opaque_gbuffer.height());
    let (px, py) = camera.project(position, width, height)?;
    if !(0.0..width as f32).contains(&px) || !(0.0..height as f32).contains(&py) {
        return None;
    }
    let to_hit = position - camera.position;
    let distance = to_hit.length();
    let blocked = geometry.opaque.occluded(camera.position, to_hit / distance, 0.0, distance * (1.0 - VIEW_SLACK));
    Some(((px as u32, py as u32), !blocked))
}

fn opaque_light(opaque_gbuffer: &PlanarImage, x: u32, y: u32) -> Vec3 {
    Vec3::new(opaque_gbuffer.get(opaque::LD, x, y), opaque_gbuffer.get(opaque::LD + 1, x, y), opaque_gbuffer.get(opaque::LD + 2, x, y))
}

/// Every transparency buffer's through buffer for a frame, with BVHs built for `scene`.
pub fn through_buffers(scene: &Scene, camera: &Camera, opaque_gbuffer: &PlanarImage, transparency_buffers: &[PlanarImage]) -> Vec<PlanarImage> {
    let geometry = ThroughScene::build(scene);
    assert_eq!(geometry.object_count(), transparency_buffers.len(), "one transparency buffer per transparent object");
    transparency_buffers
        .iter()
        .enumerate()
        .map(|(k, buffer)| through_buffer(scene, &geometry, k, camera, opaque_gbuffer, buffer.plane(transparent::COVERAGE)))
        .collect()
}
