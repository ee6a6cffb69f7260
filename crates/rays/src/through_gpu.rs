//! The through pass on a GPU: the rays of `through.rs`, cast by a wgpu compute kernel
//! (`shaders/through.wgsl`) in BVHs `gpu_bvh.rs` lays out. Same surfaces, same optics, same
//! lobe points for rough glass: the two agree up to rounding (tests/through_gpu.rs).
//!
//! [`GpuThroughPass::through_buffer`] takes its inputs from the host and reads the buffer back,
//! as the CPU pass does; [`GpuThroughPass::cast_into`] reads and writes GPU buffers (the
//! real-time frame's zero-copy path: the network's input tensors).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use glassbake_core::camera::Camera;
use glassbake_core::image::PlanarImage;
use glassbake_core::layout::{self, opaque, through};
use glassbake_core::{Error, Result};
use glassbake_scene::model::SMOOTH_ROUGHNESS;
use glassbake_scene::{MipChain, Scene, Texture};
use wgpu::util::DeviceExt;

use crate::direct::{diffuse_share, POLYGON_WGSL};
use crate::geometry::{scene_triangles, TriangleAttributes};
use crate::gpu_bvh::{GpuBvhs, GpuTriangle, COMMON_WGSL, OPTICS_WGSL};
use crate::gpu_cache::Recent;
use crate::gpu_scene::{self, bits, v4, ATTRIBUTE_VEC4S, NONE};
use crate::gpu_stats::{created, GpuObject};
use crate::through::{CELL_TAPS, FOOTPRINT, FOOTPRINT_RMS, LOBE_SAMPLES, MAX_INTERFACES, SELF_HIT, VIEW_SLACK};

/// Record sizes in vec4s of the through pass's own records (the triangles' are
/// `gpu_scene`'s): these constants reach the shader (`shader_source`).
const MATERIAL_VEC4S: usize = 2;
const LIGHT_VEC4S: usize = 5;
const WORKGROUP_SIDE: u32 = 8;

/// The kernel's uniform block (`Params` in through.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    view_projection: [[f32; 4]; 4],
    camera_position: [f32; 4],
    camera_forward: [f32; 4],
    camera_right: [f32; 4],
    camera_up: [f32; 4],
    background: [f32; 4],
    width: u32,
    height: u32,
    opaque_root: u32,
    object_root: u32,
    ior: f32,
    thin: u32,
    rough: u32,
    alpha: f32,
    object: u32,
    texture_table: u32,
    ld_offset: u32,
    coverage_offset: u32,
    through_offset: u32,
    pixel_size: f32,
    light_count: u32,
    _pad: u32,
}

fn shader_source() -> String {
    let integers: [(&str, usize); 14] = [
        ("MATERIAL_VEC4S", MATERIAL_VEC4S),
        ("LIGHT_VEC4S", LIGHT_VEC4S),
        ("NO_SAMPLE", NONE as usize),
        ("MAX_INTERFACES", MAX_INTERFACES),
        ("LOBE_SAMPLES", LOBE_SAMPLES),
        ("THROUGH_CHANNELS", layout::THROUGH_CHANNELS),
        ("THROUGH_POSITION", through::POSITION),
        ("THROUGH_NORMAL", through::NORMAL),
        ("THROUGH_ALBEDO", through::ALBEDO),
        ("THROUGH_LD", through::LD),
        ("THROUGH_TRANSMITTANCE", through::TRANSMITTANCE),
        ("THROUGH_LENGTH", through::LENGTH),
        ("THROUGH_SPREAD", through::SPREAD),
        ("FOOTPRINT_POINTS", FOOTPRINT.len()),
    ];
    let mut source = gpu_scene::wgsl_constants();
    source.extend(integers.iter().map(|(name, value)| format!("const {name}: u32 = {value}u;\n")));
    source.push_str(&format!(
        "const THROUGH_SCREEN_OFFSET: u32 = {}u;\nconst THROUGH_ON_SCREEN: u32 = {}u;\nconst SELF_HIT: f32 = {SELF_HIT:e};\nconst VIEW_SLACK: f32 = {VIEW_SLACK:e};\n",
        through::SCREEN_OFFSET,
        through::ON_SCREEN
    ));
    for (name, points) in [("FOOTPRINT", &FOOTPRINT), ("CELL_TAPS", &CELL_TAPS)] {
        let points: Vec<String> = points.iter().map(|[x, y]| format!("vec2f({x:?}, {y:?})")).collect();
        source.push_str(&format!("const {name}: array<vec2f, {n}> = array<vec2f, {n}>({});\n", points.join(", "), n = points.len()));
    }
    source.push_str(&format!("const FOOTPRINT_RMS: f32 = {FOOTPRINT_RMS:?};\n"));
    for part in [GpuBvhs::wgsl().as_str(), OPTICS_WGSL, COMMON_WGSL, POLYGON_WGSL, include_str!("../shaders/through.wgsl")] {
        source.push_str(part);
        source.push('\n');
    }
    source
}

/// The compiled kernel on a wgpu device (the rasterizer's, to share it), and what its
/// dispatches bind, kept across frames.
pub struct GpuThroughPass {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    /// The parameters each dispatch writes before it is submitted.
    uniform: wgpu::Buffer,
    bound: std::sync::Mutex<Bound>,
}

/// The L_d planes' copy (grown to the largest frame yet) and the bind groups, by the
/// scene upload, the copy and the planes they bind.
struct Bound {
    ld_copy: Option<wgpu::Buffer>,
    groups: Recent<([wgpu::Buffer; 6], wgpu::Buffer, wgpu::Buffer, u64, u64), wgpu::BindGroup>,
}

/// Bind groups kept: a frame's objects write into a few tensors of burn's pool.
const KEPT_GROUPS: usize = 16;

/// One scene instance uploaded for the kernel: the BVHs of the opaque scene and of each
/// transparent object (in `Scene::transparent_objects` order), their triangles' attributes,
/// the materials, textures and rectangle lights, and the background's radiance.
pub struct GpuThroughScene {
    arrays: [wgpu::Buffer; 6],
    opaque_root: u32,
    objects: Vec<ObjectParams>,
    texture_table: u32,
    background: Vec3,
    light_count: u32,
    geometry: BuiltGeometry,
    textures: PackedTextures,
}

/// The host's copy of an upload's BVHs, kept so that the next instance of the scene can
/// refit them instead of building them again.
struct BuiltGeometry {
    bvhs: GpuBvhs,
    /// The opaque scene's root, then each transparent object's.
    roots: Vec<u32>,
    /// Triangles per BVH, in `roots`' order: a refit needs the same.
    triangle_counts: Vec<usize>,
    /// Refits since the BVHs were built.
    refits: u64,
}

impl GpuThroughScene {
    /// How many uploads refit this upload's BVHs since they were built (0: built for it).
    pub fn refits_since_build(&self) -> u64 {
        self.geometry.refits
    }
}

#[derive(Clone, Copy)]
struct ObjectParams {
    root: u32,
    ior: f32,
    thin: bool,
    /// GGX alpha (roughness squared) of rough glass; `None` for smooth glass.
    alpha: Option<f32>,
}

impl GpuThroughPass {
    /// Compile the kernel on `device`.
    pub fn new(device: wgpu::Device, queue: wgpu::Queue) -> Result<GpuThroughPass> {
        let scope = crate::gpu_errors::ValidationScope::push(&device);
        let module =
            device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("through.wgsl"), source: wgpu::ShaderSource::Wgsl(shader_source().into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("through pass"),
            layout: None,
            module: &module,
            entry_point: Some("through_pass"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = scope.pop() {
            return Err(Error::Internal(format!("compiling through.wgsl: {e}")));
        }
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("through params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(GpuThroughPass {
            device,
            queue,
            pipeline: created(GpuObject::Pipeline, pipeline),
            uniform: created(GpuObject::Buffer, uniform),
            bound: std::sync::Mutex::new(Bound { ld_copy: None, groups: Recent::new(KEPT_GROUPS) }),
        })
    }

    /// Upload `scene`'s geometry, materials, textures and lights. Fails, naming the scene or
    /// object, when a BVH is deeper than the kernel's traversal stack.
    pub fn upload(&self, scene: &Scene) -> Result<GpuThroughScene> {
        self.upload_reusing(scene, None)
    }

    /// [`Self::upload`] into `previous`'s buffers where the new arrays fit in them (written
    /// with `queue.write_buffer`, after the work already submitted that reads them): what a
    /// frame does when a variable moves an object or a light, so that it makes no GPU object.
    ///
    /// When every BVH holds as many triangles as in `previous` (a variable moved an object or
    /// a light, or changed no geometry at all), `previous`'s BVHs are refit to the new
    /// positions instead of built again (`GpuBvhs::refit`).
    pub fn upload_reusing(&self, scene: &Scene, previous: Option<GpuThroughScene>) -> Result<GpuThroughScene> {
        let mut sets = vec![(scene_triangles(scene, &|o| !scene.objects[o].transparent, true, &|_, _| None), scene.name.clone())];
        for index in scene.transparent_objects() {
            let name = format!("{} (object {})", scene.name, scene.objects[index].name);
            sets.push((scene_triangles(scene, &|o| o == index, false, &|_, _| None), name));
        }
        let triangle_counts: Vec<usize> = sets.iter().map(|(triangles, _)| triangles.len()).collect();
        let (previous_arrays, refittable, previous_textures) = match previous {
            Some(p) => {
                let refittable = (p.geometry.triangle_counts == triangle_counts).then_some(p.geometry);
                (Some(p.arrays), refittable, Some(p.textures))
            }
            None => (None, None, None),
        };
        // An instance shares its textures with the scene it came from: their mip chains are
        // packed once, and their buffer written once.
        let (textures, textures_unchanged) = match previous_textures {
            Some(packed) if packed.made_from(scene) => (packed, true),
            _ => (PackedTextures::new(scene), false),
        };
        let (attributes, firsts) = triangle_attributes(&sets);
        let geometry = match refittable {
            Some(mut geometry) => {
                let corners = |attribute: u32| {
                    let a = &attributes[attribute as usize * ATTRIBUTE_VEC4S..];
                    [0, 1, 2].map(|c| Vec3::from_slice(&a[c][..3]))
                };
                geometry.bvhs.refit(&geometry.roots, &corners);
                geometry.refits += 1;
                geometry
            }
            None => {
                let mut bvhs = GpuBvhs::default();
                let mut roots = Vec::with_capacity(sets.len());
                for ((triangles, name), &first) in sets.iter().zip(&firsts) {
                    let bvh_triangles: Vec<GpuTriangle> =
                        triangles.iter().enumerate().map(|(i, t)| GpuTriangle { positions: t.positions, attribute: first + i as u32, flags: 0 }).collect();
                    roots.push(bvhs.push(&bvh_triangles, name)?);
                }
                BuiltGeometry { bvhs, roots, triangle_counts, refits: 0 }
            }
        };
        let opaque_root = geometry.roots[0];
        let mut objects = Vec::new();
        for (index, &root) in scene.transparent_objects().into_iter().zip(&geometry.roots[1..]) {
            let object = &scene.objects[index];
            let material = &scene.materials[object.material];
            let transmission = material.transmission;
            objects.push(ObjectParams {
                root,
                ior: transmission.map_or(1.0, |t| t.ior),
                thin: transmission.is_some_and(|t| t.thin),
                alpha: (material.roughness >= SMOOTH_ROUGHNESS).then_some(material.roughness * material.roughness),
            });
        }

        let PackedMaterials { materials, texture_table, lights } = pack_materials(scene, &textures);
        let texels = &textures.texels;

        let limit = self.device.limits().max_storage_buffer_binding_size.min(self.device.limits().max_buffer_size);
        for (what, data) in [
            ("BVH nodes", &geometry.bvhs.nodes),
            ("triangles", &geometry.bvhs.triangles),
            ("triangle attributes", &attributes),
            ("materials", &materials),
            ("texels", texels),
        ] {
            let bytes = (data.len() * 16) as u64;
            if bytes > limit {
                return Err(Error::bad_input(&scene.name, what, format!("{bytes} bytes for the GPU through pass; this GPU binds at most {limit}")));
            }
        }
        let mut kept = previous_arrays.map(|arrays| arrays.map(Some));
        let mut storage = |array: usize, label: &str, data: &[[f32; 4]], unchanged: bool| {
            // Bindings cannot be empty: an empty array travels as one unused vec4.
            let padded: &[[f32; 4]] = if data.is_empty() { &[[0.0; 4]] } else { data };
            let bytes: &[u8] = bytemuck::cast_slice(padded);
            match kept.as_mut().and_then(|k| k[array].take()).filter(|b| b.size() >= bytes.len() as u64) {
                Some(buffer) => {
                    if !unchanged {
                        self.queue.write_buffer(&buffer, 0, bytes);
                    }
                    buffer
                }
                None => {
                    // Room to the next power of two: a moved object's BVH may need a few more
                    // nodes, which then fit.
                    let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size: (bytes.len() as u64).next_power_of_two(),
                        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    });
                    self.queue.write_buffer(&buffer, 0, bytes);
                    created(GpuObject::Buffer, buffer)
                }
            }
        };
        Ok(GpuThroughScene {
            arrays: [
                storage(0, "through BVH nodes", &geometry.bvhs.nodes, false),
                storage(1, "through triangles", &geometry.bvhs.triangles, false),
                storage(2, "through attributes", &attributes, false),
                storage(3, "through materials", &materials, false),
                storage(4, "through texels", texels, textures_unchanged),
                storage(5, "through lights", &lights, false),
            ],
            opaque_root,
            objects,
            texture_table,
            background: scene.background,
            light_count: scene.rect_lights.len() as u32,
            geometry,
            textures,
        })
    }

    /// The through buffer of transparent object `k` of `scene` for a frame, as
    /// `through::through_buffer` computes it: cast where `coverage` is above 0, L_d read
    /// from `opaque_gbuffer`. Uploads its inputs and reads the buffer back.
    pub fn through_buffer(&self, scene: &GpuThroughScene, k: usize, camera: &Camera, opaque_gbuffer: &PlanarImage, coverage: &[f32]) -> Result<PlanarImage> {
        let (width, height) = (opaque_gbuffer.width(), opaque_gbuffer.height());
        let pixels = (width * height) as usize;
        assert_eq!(coverage.len(), pixels, "one coverage value per pixel of the frame");
        let ld = &opaque_gbuffer.data()[opaque::LD * pixels..(opaque::LD + 3) * pixels];
        let storage = |label: &str, contents: &[f32], usage: wgpu::BufferUsages| {
            let buffer =
                self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: bytemuck::cast_slice(contents), usage });
            created(GpuObject::Buffer, buffer)
        };
        let light = storage("through direct light", ld, wgpu::BufferUsages::COPY_SRC);
        // The coverage plane, then room for the through planes.
        let mut planes = vec![0.0f32; (1 + layout::THROUGH_CHANNELS) * pixels];
        planes[..pixels].copy_from_slice(coverage);
        let object = storage("through object planes", &planes, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
        let out_bytes = (layout::THROUGH_CHANNELS * pixels * 4) as u64;
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("through readback"),
            size: out_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let readback = created(GpuObject::Buffer, readback);
        self.cast_into(scene, k, camera, width, height, PlanesAt { buffer: &light, byte_offset: 0, plane: 0 }, &object, 0, 0, 1)?;
        let bytes = crate::gpu_readback::read_back(&self.device, &self.queue, &object, (pixels * 4) as u64, &readback, out_bytes)?;
        let data: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        PlanarImage::from_planes(width, height, layout::through_channel_names(k), data)
    }

    /// Cast object `k`'s through buffer for a `width` x `height` frame on the GPU, without
    /// host copies: L_d read from the opaque G-buffer's planes in `gbuffer` (its L_d plane
    /// index `gbuffer.plane` is taken as the first of the three; they are copied out, so the
    /// buffer needs `COPY_SRC`), the coverage read from plane
    /// `coverage` of the planes at `object_byte_offset` in `object`, the
    /// [`layout::THROUGH_CHANNELS`] through planes written from plane `through` on there. The
    /// real-time frame passes the network's input tensors' buffers. Submits one command buffer
    /// on the queue, after whatever wrote the inputs.
    #[allow(clippy::too_many_arguments)]
    pub fn cast_into(
        &self,
        scene: &GpuThroughScene,
        k: usize,
        camera: &Camera,
        width: u32,
        height: u32,
        gbuffer: PlanesAt,
        object: &wgpu::Buffer,
        object_byte_offset: u64,
        coverage: u64,
        through: u64,
    ) -> Result<()> {
        let pixels = u64::from(width) * u64::from(height);
        let object_planes = PlanesAt { buffer: object, byte_offset: object_byte_offset, plane: 0 };
        // The L_d planes are copied out first: the network's input tensors may share one
        // buffer, which a dispatch cannot bind both read-only and read-write.
        let ld_bytes = 3 * pixels * 4;
        let ld_source = gbuffer.byte_offset + gbuffer.plane * pixels * 4;
        if ld_source + ld_bytes > gbuffer.buffer.size() || !ld_source.is_multiple_of(4) {
            return Err(Error::Internal(format!("the L_d planes at byte {ld_source} do not fit their buffer of {}", gbuffer.buffer.size())));
        }
        let mut bound = self.bound.lock().map_err(|_| Error::Internal("the through pass's bindings were poisoned by a panic".into()))?;
        if bound.ld_copy.as_ref().is_none_or(|b| b.size() < ld_bytes) {
            let ld_copy = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("through direct light"),
                size: ld_bytes.next_power_of_two(),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            bound.ld_copy = Some(created(GpuObject::Buffer, ld_copy));
        }
        let ld_copy = bound.ld_copy.clone().expect("made above");
        let (object_binding, object_offset) = object_planes.binding(&self.device, pixels, (coverage + 1).max(through + layout::THROUGH_CHANNELS as u64))?;
        let object_params = scene.objects[k];
        let f = camera.frame();
        let (tx, ty) = camera.tan_half_fov(width, height);
        let element = |offset: u64| u32::try_from(offset).map_err(|_| Error::Internal(format!("a through-pass binding of {offset} elements")));
        let params = Params {
            view_projection: camera.view_projection(width, height).to_cols_array_2d(),
            camera_position: v4(camera.position, 0.0),
            camera_forward: v4(f.forward, 0.0),
            camera_right: v4(f.right * tx, 0.0),
            camera_up: v4(f.up * ty, 0.0),
            background: v4(scene.background, 0.0),
            width,
            height,
            opaque_root: scene.opaque_root,
            object_root: object_params.root,
            ior: object_params.ior,
            thin: object_params.thin as u32,
            rough: object_params.alpha.is_some() as u32,
            alpha: object_params.alpha.unwrap_or(0.0),
            object: k as u32,
            texture_table: scene.texture_table,
            ld_offset: 0,
            coverage_offset: element(object_offset + coverage * pixels)?,
            through_offset: element(object_offset + through * pixels)?,
            pixel_size: 2.0 * ty / height as f32,
            light_count: scene.light_count,
            _pad: 0,
        };
        let key = (scene.arrays.clone(), ld_copy.clone(), object.clone(), object_binding.offset, object_binding.size.map_or(0, |s| s.get()));
        let mut refused = None;
        let bind_group = bound
            .groups
            .get_or_make(key, || {
                // Whatever wgpu refuses here comes back as an error, not as a panic of its
                // handler; a kept bind group was checked when it was made.
                let scope = crate::gpu_errors::ValidationScope::push(&self.device);
                let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: self.uniform.as_entire_binding() }];
                for (i, buffer) in scene.arrays.iter().enumerate() {
                    entries.push(wgpu::BindGroupEntry { binding: i as u32 + 1, resource: buffer.as_entire_binding() });
                }
                entries.push(wgpu::BindGroupEntry { binding: 7, resource: ld_copy.as_entire_binding() });
                entries.push(wgpu::BindGroupEntry { binding: 8, resource: wgpu::BindingResource::Buffer(object_binding) });
                let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("through"),
                    layout: &self.pipeline.get_bind_group_layout(0),
                    entries: &entries,
                });
                refused = scope.pop();
                created(GpuObject::BindGroup, bind_group)
            })
            .clone();
        if let Some(e) = refused {
            return Err(Error::Internal(format!("the GPU through pass: {e}")));
        }
        drop(bound);
        self.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&params));
        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("through pass") });
        encoder.copy_buffer_to_buffer(gbuffer.buffer, ld_source, &ld_copy, 0, ld_bytes);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("through pass"), timestamp_writes: None });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(WORKGROUP_SIDE), height.div_ceil(WORKGROUP_SIDE), 1);
        }
        let commands = encoder.finish();
        self.queue.submit([commands]);
        Ok(())
    }
}

/// Planes of f32 in a GPU buffer, from `byte_offset` on; `plane` names one of them.
#[derive(Clone, Copy)]
pub struct PlanesAt<'a> {
    pub buffer: &'a wgpu::Buffer,
    pub byte_offset: u64,
    pub plane: u64,
}

impl<'a> PlanesAt<'a> {
    /// A binding of the first `planes` planes of `pixels` values, starting at the nearest
    /// offset below the planes that the device lets a storage binding start at, and how many
    /// elements the planes start after it.
    fn binding(&self, device: &wgpu::Device, pixels: u64, planes: u64) -> Result<(wgpu::BufferBinding<'a>, u64)> {
        let alignment = u64::from(device.limits().min_storage_buffer_offset_alignment);
        let start = self.byte_offset / alignment * alignment;
        let skip = self.byte_offset - start;
        if !skip.is_multiple_of(4) {
            return Err(Error::Internal(format!("planes at byte {} are not f32-aligned", self.byte_offset)));
        }
        let size = skip + planes * pixels * 4;
        let limit = device.limits().max_storage_buffer_binding_size;
        if size > limit {
            return Err(Error::bad_input(
                "frame",
                "resolution",
                format!("the through pass binds {size} bytes of planes for {pixels} pixels; this GPU binds at most {limit}"),
            ));
        }
        if start + size > self.buffer.size() {
            return Err(Error::Internal(format!(
                "{planes} planes of {pixels} values from byte {} overrun a buffer of {}",
                self.byte_offset,
                self.buffer.size()
            )));
        }
        Ok((wgpu::BufferBinding { buffer: self.buffer, offset: start, size: std::num::NonZeroU64::new(size) }, skip / 4))
    }
}

/// Each triangle's attribute record (`gpu_scene`), set after set; and the first triangle of
/// each set.
fn triangle_attributes(sets: &[(Vec<TriangleAttributes>, String)]) -> (Vec<[f32; 4]>, Vec<u32>) {
    let mut attributes: Vec<[f32; 4]> = Vec::new();
    let mut firsts = Vec::with_capacity(sets.len());
    for (triangles, _) in sets {
        firsts.push((attributes.len() / ATTRIBUTE_VEC4S) as u32);
        gpu_scene::push_attributes(triangles, &mut attributes);
    }
    (attributes, firsts)
}

/// The scene's materials (base colour and texture, emission) and texture table, and
/// rectangle lights, as the through kernel reads them.
struct PackedMaterials {
    materials: Vec<[f32; 4]>,
    /// Where the texture table starts in `materials`.
    texture_table: u32,
    lights: Vec<[f32; 4]>,
}

/// The scene's textures with their mip chains, as the kernel reads them
/// (`gpu_scene::push_mip_textures`): the table's records and the texels, and the textures
/// they were packed from.
struct PackedTextures {
    sources: Vec<Arc<Texture>>,
    table: Vec<[f32; 4]>,
    texels: Vec<[f32; 4]>,
}

impl PackedTextures {
    fn new(scene: &Scene) -> PackedTextures {
        let chains: Vec<MipChain> = scene.textures.iter().map(|t| MipChain::new(t)).collect();
        let (mut table, mut texels) = (Vec::new(), Vec::new());
        gpu_scene::push_mip_textures(&chains, &mut table, &mut texels);
        PackedTextures { sources: scene.textures.clone(), table, texels }
    }

    fn made_from(&self, scene: &Scene) -> bool {
        self.sources.len() == scene.textures.len() && self.sources.iter().zip(&scene.textures).all(|(a, b)| Arc::ptr_eq(a, b))
    }
}

fn pack_materials(scene: &Scene, textures: &PackedTextures) -> PackedMaterials {
    let mut materials = Vec::with_capacity(scene.materials.len() * MATERIAL_VEC4S + scene.textures.len());
    for m in &scene.materials {
        let texture = m.base_color_texture.filter(|&t| t < scene.textures.len()).map_or(NONE, |t| t as u32);
        materials.extend([v4(m.base_color, bits(texture)), v4(m.emission, diffuse_share(m))]);
    }
    let texture_table = materials.len() as u32;
    materials.extend_from_slice(&textures.table);
    let lights: Vec<[f32; 4]> = scene
        .rect_lights
        .iter()
        .flat_map(|l| [v4(l.normal(), if l.two_sided { 1.0 } else { 0.0 }), v4(l.radiance, 0.0), v4(l.corner, 0.0), v4(l.edge_u, 0.0), v4(l.edge_v, 0.0)])
        .collect();
    PackedMaterials { materials, texture_table, lights }
}
