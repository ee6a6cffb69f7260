//! A frame: [`Rasterizer::begin_frame`] uploads an instance and camera and draws the shadow
//! maps and opaque G-buffer; [`Frame`] then draws and reads back what is asked of it (the naive
//! G-buffer, each transparency buffer, the light coverage), into host memory or GPU buffers.

// The rasterizer's half that draws a frame: it uses the module's targets, maps and constants.
use super::*;
use crate::light_coverage::exact::{ExactCoverage, ExactParams};
use crate::light_coverage::sampled::CoverageReducer;
use crate::light_coverage::Reduction;

impl Rasterizer {
    /// Upload a frame (scene instance + camera), render the shadow maps and the opaque
    /// G-buffer on the GPU, and return a handle that produces the buffers on request. The
    /// transparency buffers are rendered one at a time into one reused set of targets.
    pub fn begin_frame(&mut self, scene: &Scene, camera: &Camera, width: u32, height: u32) -> Result<Frame<'_>> {
        self.check_resolution(scene, width, height)?;
        camera.check()?;
        if scene.rect_lights.is_empty() {
            tracing::warn!("scene {:?} has no rectangle light: L_d holds only emission", scene.name);
        }
        self.ensure_targets(width, height);

        let (mut light_data, shadow_views) = self.light_uniforms(scene);
        let light_count = light_data.len() as u32;
        if light_data.is_empty() {
            light_data.push(LightUniform::zeroed_light());
        }
        if self.ensure_shadow_maps(shadow_views.len() as u32) {
            self.frame_data.shadow_content = None;
        }
        let mut matrix_data: Vec<[[f32; 4]; 4]> = shadow_views.iter().map(|m| mat4_cols(*m)).collect();
        if matrix_data.is_empty() {
            matrix_data.push(mat4_cols(Mat4::IDENTITY));
        }
        let drawn = self.frame_draws(scene)?;

        // The frame's data into the buffers kept across frames.
        let layouts = Layouts {
            view: &self.view_layout,
            object: &self.object_layout,
            shading: &self.shading_layout,
            material_sampler: &self.material_sampler,
            shadow_sampler: &self.shadow_sampler,
            ltc_matrix: &self.ltc_matrix,
            ltc_amplitude: &self.ltc_amplitude,
        };
        let object_groups = self.frame_data.write_objects(&self.device, &self.queue, &layouts, &drawn.uniforms, &drawn.textures);
        let mut views = vec![ViewUniform {
            view_proj: mat4_cols(camera.view_projection(width, height)),
            camera_pos: camera.position.extend(1.0).to_array(),
            params: [light_count, u32::from(self.options.shadows), 0, 0],
        }];
        views.extend(shadow_views.iter().map(|m| ViewUniform { view_proj: mat4_cols(*m), camera_pos: [0.0; 4], params: [0; 4] }));
        let view_groups = self.frame_data.write_views(&self.device, &self.queue, &layouts, &views).to_vec();
        let shadows = self.shadows.as_ref().expect("ensured");
        let targets = self.targets.as_ref().expect("ensured");
        let inputs =
            ShadingInputs { shadow_maps: shadows.array_view.clone(), no_opaque: self.no_opaque.clone(), opaque_positions: targets.opaque.views[1].clone() };
        let (shading_opaque, shading_transparency) = self.frame_data.write_shading(&self.device, &self.queue, &layouts, &light_data, &matrix_data, inputs);

        let mut encoder = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        self.draw_shadow_maps(&mut encoder, &view_groups[1..], &object_groups, &drawn, &matrix_data);
        let FrameDraws { draws, transparent_slot, meshes, .. } = drawn;
        let frame = Frame {
            width,
            height,
            view: view_groups[0].clone(),
            shading_opaque,
            shading_transparency,
            object_groups,
            meshes,
            draws,
            transparent_slot,
            rasterizer: self,
        };
        frame.encode_pass(&mut encoder, PassKind::Opaque);
        frame.rasterizer.queue.submit([encoder.finish()]);
        Ok(frame)
    }

    /// The scene's rectangle lights as the shaders read them, and the view-projection of each
    /// face of their shadow hemicubes (5 faces a lit side; none without shadows).
    fn light_uniforms(&self, scene: &Scene) -> (Vec<LightUniform>, Vec<Mat4>) {
        let bounds = scene.bounds().unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
        let extent = (bounds.1 - bounds.0).length().max(1e-3);
        let mut light_data = Vec::with_capacity(scene.rect_lights.len());
        let mut shadow_views: Vec<Mat4> = Vec::new();
        let tan_half = SHADOW_HALF_FOV_DEG.to_radians().tan();
        let normal_offset = 1.5 * 2.0 * tan_half / self.options.shadow_map_size.max(16) as f32;
        for light in &scene.rect_lights {
            let centre = light.center();
            let n = light.normal();
            let t = light.edge_u.normalize_or(n.any_orthonormal_vector());
            let far = 2.0 * extent + (centre - 0.5 * (bounds.0 + bounds.1)).length();
            let proj = Mat4::perspective_rh(2.0 * SHADOW_HALF_FOV_DEG.to_radians(), 1.0, far * 1e-4, far);
            // The hemicube of one side: faces along s, t, -t, b, -b (as the shader expects).
            let mut hemicube = |s: Vec3| -> f32 {
                if !self.options.shadows {
                    return -1.0;
                }
                let first = shadow_views.len() as f32;
                let b = s.cross(t);
                for (dir, up) in [(s, t), (t, s), (-t, s), (b, s), (-b, s)] {
                    shadow_views.push(proj * Mat4::look_at_rh(centre, centre + dir, up));
                }
                first
            };
            let front_layer = hemicube(n);
            let back_layer = if light.two_sided { hemicube(-n) } else { -1.0 };
            let c = light.corners();
            light_data.push(LightUniform {
                corners: c.map(|p| p.extend(1.0).to_array()),
                radiance: light.radiance.extend(if light.two_sided { 1.0 } else { 0.0 }).to_array(),
                shadow: [front_layer, back_layer, normal_offset, 0.0],
            });
        }
        (light_data, shadow_views)
    }

    /// What a frame draws: the objects (opaque, transparent) and the lights' own quads.
    fn frame_draws(&mut self, scene: &Scene) -> Result<FrameDraws> {
        let mut uniforms: Vec<ObjectUniform> = Vec::new();
        let mut draws: Vec<Draw> = Vec::new();
        let mut transparent_slot = vec![usize::MAX; scene.transparent_count()];
        let transparent_index: Vec<usize> = scene.transparent_objects();
        let mut meshes_to_draw: Vec<(wgpu::Buffer, wgpu::Buffer, u32)> = Vec::new();
        let mut textures: Vec<(wgpu::TextureView, wgpu::TextureView)> = Vec::new();
        for (oi, object) in scene.objects.iter().enumerate() {
            let Some(mesh) = scene.meshes.get(object.mesh) else {
                return Err(Error::bad_input(&scene.name, format!("objects.{}.mesh", object.name), "index out of range"));
            };
            let Some(material) = scene.materials.get(object.material) else {
                return Err(Error::bad_input(&scene.name, format!("objects.{}.material", object.name), "index out of range"));
            };
            let Some(gpu) = self.cache.mesh(&self.device, mesh) else { continue };
            meshes_to_draw.push((gpu.vertices.clone(), gpu.indices.clone(), gpu.index_count));
            let mut texture = |index: Option<usize>| match index.and_then(|i| scene.textures.get(i)) {
                Some(t) => self.cache.texture(&self.device, &self.queue, t),
                None => self.white.clone(),
            };
            textures.push((texture(material.base_color_texture), texture(material.roughness_texture)));
            let model = Mat4::from(object.transform);
            let normal_matrix = Mat4::from_mat3(glam::Mat3::from(object.transform.matrix3).inverse().transpose());
            uniforms.push(ObjectUniform {
                model: mat4_cols(model),
                normal_matrix: mat4_cols(normal_matrix),
                base_color: material.base_color.extend(material.roughness).to_array(),
                emission: material.emission.extend(material.metallic).to_array(),
                params: [material.transmission.map_or(0.0, |t| t.weight.clamp(0.0, 1.0)), 0.0, 0.0, 0.0],
            });
            let class = if object.transparent {
                let k = transparent_index.iter().position(|&i| i == oi).expect("transparent objects are listed");
                transparent_slot[k] = draws.len();
                DrawClass::Transparent
            } else {
                DrawClass::Opaque
            };
            draws.push(Draw { slot: uniforms.len() - 1, class, mesh: meshes_to_draw.len() - 1 });
        }
        if self.options.draw_lights {
            for (light, quad) in scene.rect_lights.iter().zip(self.cache.light_quads(&self.device, &self.queue, &scene.rect_lights)) {
                let Some(quad) = quad else { continue };
                meshes_to_draw.push((quad.vertices.clone(), quad.indices.clone(), quad.index_count));
                textures.push((self.white.clone(), self.white.clone()));
                uniforms.push(ObjectUniform {
                    model: mat4_cols(Mat4::IDENTITY),
                    normal_matrix: mat4_cols(Mat4::IDENTITY),
                    base_color: [0.0, 0.0, 0.0, 1.0],
                    emission: light.radiance.extend(0.0).to_array(),
                    params: [0.0, 1.0, if light.two_sided { 1.0 } else { 0.0 }, 0.0],
                });
                draws.push(Draw { slot: uniforms.len() - 1, class: DrawClass::Light, mesh: meshes_to_draw.len() - 1 });
            }
        }

        Ok(FrameDraws { uniforms, draws, transparent_slot, meshes: meshes_to_draw, textures })
    }

    /// Shadow maps: opaque geometry only (glass and the lights' quads cast no shadow), drawn
    /// again only when a light or an occluder moved.
    fn draw_shadow_maps(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        face_groups: &[wgpu::BindGroup],
        object_groups: &[wgpu::BindGroup],
        drawn: &FrameDraws,
        matrix_data: &[[[f32; 4]; 4]],
    ) {
        let FrameDraws { uniforms, draws, meshes: meshes_to_draw, .. } = drawn;
        let shadows = self.shadows.as_ref().expect("ensured");
        let occluders = || draws.iter().filter(|d| d.class == DrawClass::Opaque);
        let content = ShadowContent {
            faces: matrix_data.iter().map(|m| m.map(|c| c.map(f32::to_bits))).collect(),
            occluders: occluders().map(|d| (meshes_to_draw[d.mesh].0.clone(), uniforms[d.slot].model.map(|c| c.map(f32::to_bits)))).collect(),
        };
        if self.frame_data.shadow_content.as_ref() != Some(&content) {
            for (layer, group) in face_groups.iter().enumerate() {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shadow"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &shadows.layer_views[layer],
                        depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                pass.set_pipeline(&self.shadow_pipeline);
                pass.set_bind_group(0, group, &[]);
                for d in occluders() {
                    let (v, i, n) = &meshes_to_draw[d.mesh];
                    pass.set_bind_group(1, &object_groups[d.slot], &[]);
                    pass.set_vertex_buffer(0, v.slice(..));
                    pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..*n, 0, 0..1);
                }
            }
            self.frame_data.shadow_content = Some(content);
        }
    }
}

/// What a frame draws, in draw order: each draw's uniform, its mesh's buffers and its textures.
struct FrameDraws {
    uniforms: Vec<ObjectUniform>,
    draws: Vec<Draw>,
    /// The draw of each transparent object, in the scene's order of transparent objects.
    transparent_slot: Vec<usize>,
    meshes: Vec<(wgpu::Buffer, wgpu::Buffer, u32)>,
    textures: Vec<(wgpu::TextureView, wgpu::TextureView)>,
}

impl LightUniform {
    fn zeroed_light() -> LightUniform {
        bytemuck::Zeroable::zeroed()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DrawClass {
    Opaque,
    Transparent,
    Light,
}

struct Draw {
    slot: usize,
    class: DrawClass,
    mesh: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PassKind {
    Opaque,
    Naive,
    Transparency(usize),
}

/// One frame in flight: the opaque G-buffer is rendered; the naive G-buffer and the
/// transparency buffers are rendered on request, each transparency buffer into the same
/// reused targets and readback buffer (memory does not grow with the object count).
pub struct Frame<'r> {
    rasterizer: &'r mut Rasterizer,
    width: u32,
    height: u32,
    view: wgpu::BindGroup,
    shading_opaque: wgpu::BindGroup,
    shading_transparency: wgpu::BindGroup,
    object_groups: Vec<wgpu::BindGroup>,
    meshes: Vec<(wgpu::Buffer, wgpu::Buffer, u32)>,
    draws: Vec<Draw>,
    /// Draw index of transparency buffer k.
    transparent_slot: Vec<usize>,
}

impl Frame<'_> {
    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Number of transparency buffers (the scene's transparent objects).
    pub fn transparent_count(&self) -> usize {
        self.transparent_slot.len()
    }

    fn encode_pass(&self, encoder: &mut wgpu::CommandEncoder, kind: PassKind) {
        let r = &*self.rasterizer;
        let targets = r.targets.as_ref().expect("frame has targets");
        let (set, pipeline, shading) = match kind {
            PassKind::Opaque => (&targets.opaque, &r.gbuffer_pipeline, &self.shading_opaque),
            PassKind::Naive => (targets.naive.as_ref().expect("created"), &r.gbuffer_pipeline, &self.shading_opaque),
            PassKind::Transparency(_) => (&targets.transparency, &r.transparency_pipeline, &self.shading_transparency),
        };
        let near_targets = match kind {
            PassKind::Transparency(_) => 0..TRANSPARENCY_NEAR_TARGETS,
            _ => 0..set.views.len(),
        };
        // Nearest surfaces: depth cleared to 1, "less".
        let draws: Vec<&Draw> = match kind {
            PassKind::Opaque => self.draws.iter().filter(|d| d.class != DrawClass::Transparent).collect(),
            PassKind::Naive => self.draws.iter().collect(),
            // An object without drawable geometry leaves its buffer cleared: coverage 0.
            PassKind::Transparency(k) => self.draws.get(self.transparent_slot[k]).into_iter().collect(),
        };
        self.encode_draws(encoder, &set.color_attachments(near_targets), pipeline, shading, 1.0, &draws);
        if let PassKind::Transparency(_) = kind {
            // Farthest surfaces of the same object: depth cleared to 0, "greater".
            let far = set.color_attachments(TRANSPARENCY_NEAR_TARGETS..TRANSPARENCY_TARGETS as usize);
            self.encode_draws(encoder, &far, &r.transparency_far_pipeline, shading, 0.0, &draws);
        }
    }

    fn encode_draws(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        attachments: &[Option<wgpu::RenderPassColorAttachment<'_>>],
        pipeline: &wgpu::RenderPipeline,
        shading: &wgpu::BindGroup,
        clear_depth: f32,
        draws: &[&Draw],
    ) {
        let targets = self.rasterizer.targets.as_ref().expect("frame has targets");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("gbuffer"),
            color_attachments: attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(clear_depth), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.view, &[]);
        pass.set_bind_group(2, shading, &[]);
        for d in draws {
            let (v, i, n) = &self.meshes[d.mesh];
            pass.set_bind_group(1, &self.object_groups[d.slot], &[]);
            pass.set_vertex_buffer(0, v.slice(..));
            pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..*n, 0, 0..1);
        }
    }

    /// Read back the opaque G-buffer (17 channels, `layout::opaque_channel_names()`).
    pub fn opaque(&mut self) -> Result<PlanarImage> {
        let mut out = PlanarImage::new(self.width, self.height, layout::opaque_channel_names());
        let r = &*self.rasterizer;
        r.targets.as_ref().expect("targets").opaque.read_into(&r.device, &r.queue, &OPAQUE_MAP, self.width, self.height, out.data_mut())?;
        Ok(out)
    }

    /// Render and read back the naive G-buffer (glass overwrites what is behind it; same 17
    /// channels, `layout::naive_channel_names()`).
    pub fn naive(&mut self) -> Result<PlanarImage> {
        self.ensure_naive_targets();
        let r = &*self.rasterizer;
        let mut encoder = r.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("naive") });
        self.encode_pass(&mut encoder, PassKind::Naive);
        r.queue.submit([encoder.finish()]);
        let mut out = PlanarImage::new(self.width, self.height, layout::naive_channel_names());
        r.targets.as_ref().expect("targets").naive.as_ref().expect("created").read_into(
            &r.device,
            &r.queue,
            &OPAQUE_MAP,
            self.width,
            self.height,
            out.data_mut(),
        )?;
        Ok(out)
    }

    fn ensure_naive_targets(&mut self) {
        let r = &mut *self.rasterizer;
        let targets = r.targets.as_mut().expect("targets");
        if targets.naive.is_none() {
            targets.naive = Some(TargetSet::new(&r.device, GBUFFER_TARGETS, self.width, self.height, "naive"));
        }
    }

    /// The light coverage (`layout::LIGHT_COVERAGE_CHANNELS` planes, channel names `names`)
    /// of this frame's opaque G-buffer, or of its naive one (rendered here) if `naive`, for a
    /// frame `reduction.factor()` times smaller on each side than this one: reduced on the
    /// GPU, so that only the coverage's planes are read back.
    pub(crate) fn light_coverage(&mut self, naive: bool, reduction: &Reduction, names: Vec<String>) -> Result<PlanarImage> {
        let (width, height) = self.reduce_light_coverage(naive, reduction, None)?;
        let r = &*self.rasterizer;
        let readback = &r.targets.as_ref().expect("targets").coverage.as_ref().expect("reduced above").readback;
        map_for_reading(&r.device, readback)?;
        let planes = readback.get_mapped_range(..).map(|view| bytemuck::pod_collect_to_vec::<u8, f32>(&view));
        readback.unmap();
        let planes = planes.map_err(|e| Error::Internal(format!("reading the light coverage: {e}")))?;
        PlanarImage::from_planes(width, height, names, planes)
    }

    /// [`Self::light_coverage`] written into `out` from `byte_offset` on (4 f32 planes, e.g.
    /// a network input tensor's storage on this device), on the GPU: submitted, not waited
    /// for, and nothing read back.
    pub(crate) fn light_coverage_to_buffer(&mut self, naive: bool, reduction: &Reduction, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        self.reduce_light_coverage(naive, reduction, Some((out, byte_offset))).map(|_| ())
    }

    /// Reduces the light coverage on the GPU into the targets' coverage buffer and copies it
    /// to `out` when given, else to the readback buffer (to be mapped). Returns the
    /// coverage's size.
    fn reduce_light_coverage(&mut self, naive: bool, reduction: &Reduction, out: Option<(&wgpu::Buffer, u64)>) -> Result<(u32, u32)> {
        let factor = reduction.factor();
        if factor == 0 || !self.width.is_multiple_of(factor) || !self.height.is_multiple_of(factor) {
            return Err(Error::Internal(format!("light coverage of a {}x{} frame at factor {factor}", self.width, self.height)));
        }
        let (width, height) = (self.width / factor, self.height / factor);
        let bytes = (layout::LIGHT_COVERAGE_CHANNELS as u64) * (width as u64) * (height as u64) * 4;
        if let Some((buffer, offset)) = out {
            if !offset.is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT) || offset + bytes > buffer.size() {
                return Err(Error::Internal(format!("the light coverage's {bytes} bytes at byte {offset} of a buffer of {}", buffer.size())));
            }
        }
        if naive {
            self.ensure_naive_targets();
        }
        let (kind, lights) = match reduction {
            Reduction::Sampled { factor } => (Some(*factor), 0),
            Reduction::Exact { lights, outlines } => (None, (*lights).max(outlines.len())),
        };
        let r = &mut *self.rasterizer;
        let targets = r.targets.as_mut().expect("targets");
        if targets.coverage.as_ref().is_none_or(|c| !c.serves(kind, lights)) {
            targets.coverage = Some(CoverageBuffers::new(&r.device, kind, bytes, lights));
        }
        let coverage = targets.coverage.as_mut().expect("made above");
        let set = if naive { targets.naive.as_ref().expect("created above") } else { &targets.opaque };
        let slot = &mut coverage.groups[usize::from(naive)];
        let group = match reduction {
            Reduction::Sampled { factor } => {
                let reducer = r.coverage_reducer.get_or_insert_with(|| CoverageReducer::new(&r.device));
                slot.get_or_insert_with(|| reducer.bind(&r.device, &set.views[LD_TARGET as usize], width, height, *factor, &coverage.reduced)).clone()
            }
            Reduction::Exact { outlines, .. } => {
                let pass = r.exact_coverage.get_or_insert_with(|| ExactCoverage::new(&r.device));
                let inputs = coverage.exact.as_ref().expect("made for the exact pass");
                inputs.write(&r.queue, &ExactParams::new(width, height, outlines.len()), outlines);
                slot.get_or_insert_with(|| pass.bind(&r.device, &set.views[POSITION_DEPTH_TARGET as usize], inputs, &coverage.reduced)).clone()
            }
        };
        let r = &*self.rasterizer;
        let mut encoder = r.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("light coverage") });
        if naive {
            self.encode_pass(&mut encoder, PassKind::Naive);
        }
        match reduction {
            Reduction::Sampled { .. } => r.coverage_reducer.as_ref().expect("made above").encode(&mut encoder, &group, width, height),
            Reduction::Exact { .. } => r.exact_coverage.as_ref().expect("made above").encode(&mut encoder, &group, width, height),
        }
        let coverage = r.targets.as_ref().expect("targets").coverage.as_ref().expect("made above");
        match out {
            Some((buffer, offset)) => encoder.copy_buffer_to_buffer(&coverage.reduced, 0, buffer, offset, bytes),
            None => encoder.copy_buffer_to_buffer(&coverage.reduced, 0, &coverage.readback, 0, bytes),
        }
        r.queue.submit([encoder.finish()]);
        Ok((width, height))
    }

    /// Render transparency buffer `k` into the reused transparency targets, on the GPU only
    /// (the readbacks and copies into buffers read them from there).
    pub fn render_transparent(&mut self, k: usize) -> Result<()> {
        if k >= self.transparent_count() {
            return Err(Error::Internal(format!("transparency buffer {k} of {}", self.transparent_count())));
        }
        let r = &*self.rasterizer;
        let mut encoder = r.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("transparency") });
        self.encode_pass(&mut encoder, PassKind::Transparency(k));
        r.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Render transparency buffer `k` and read it back into `planes`: `layout::TRANSPARENT_CHANNELS` planes of
    /// width x height f32 in the channel order of `layout::transparent_channel_names`
    /// (planar, row 0 at the top). The streaming path for the network: the caller keeps one
    /// buffer and the GPU one set of targets, whatever the number of objects.
    pub fn transparent_into(&mut self, k: usize, planes: &mut [f32]) -> Result<()> {
        let expected = layout::TRANSPARENT_CHANNELS * (self.width * self.height) as usize;
        if planes.len() != expected {
            return Err(Error::Internal(format!("transparency planes: got {} floats, expected {expected}", planes.len())));
        }
        self.render_transparent(k)?;
        let r = &*self.rasterizer;
        r.targets.as_ref().expect("targets").transparency.read_into(&r.device, &r.queue, &TRANSPARENT_MAP, self.width, self.height, planes)
    }

    /// Write the opaque G-buffer into `out` from `byte_offset` on as 17 f32 planes of
    /// width x height (NCHW, `layout::opaque_channel_names()` order), on the GPU: no host copy.
    /// `out` must have STORAGE usage, and lives on this rasterizer's device (e.g. a tensor's
    /// storage when the network shares the device). Submitted; not waited for.
    pub fn opaque_to_buffer(&mut self, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        let mut encoder = self.rasterizer.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("opaque to buffer") });
        self.encode_unpack(&mut encoder, false, out, byte_offset)?;
        self.rasterizer.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Render transparency buffer `k` and write it into `out` from `byte_offset` on as `layout::TRANSPARENT_CHANNELS` f32
    /// planes (`layout::transparent_channel_names(k)` order), on the GPU, in one submission.
    pub fn transparent_to_buffer(&mut self, k: usize, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        if k >= self.transparent_count() {
            return Err(Error::Internal(format!("transparency buffer {k} of {}", self.transparent_count())));
        }
        let mut encoder = self.rasterizer.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("transparency to buffer") });
        self.encode_pass(&mut encoder, PassKind::Transparency(k));
        self.encode_unpack(&mut encoder, true, out, byte_offset)?;
        self.rasterizer.queue.submit([encoder.finish()]);
        Ok(())
    }

    fn encode_unpack(&mut self, encoder: &mut wgpu::CommandEncoder, transparency: bool, out: &wgpu::Buffer, byte_offset: u64) -> Result<()> {
        let r = &mut *self.rasterizer;
        if r.unpacker.is_none() {
            r.unpacker = Some(crate::unpack::Unpacker::new(&r.device));
        }
        let targets = r.targets.as_ref().expect("targets");
        let (set, map, channels): (&TargetSet, &ChannelMap, usize) = if transparency {
            (&targets.transparency, &TRANSPARENT_MAP, layout::TRANSPARENT_CHANNELS)
        } else {
            (&targets.opaque, &OPAQUE_MAP, layout::OPAQUE_CHANNELS)
        };
        r.unpacker.as_mut().expect("made above").encode(&r.device, encoder, &set.views, map, channels, self.width, self.height, out, byte_offset)
    }

    /// Render and read back transparency buffer `k`.
    pub fn transparent(&mut self, k: usize) -> Result<PlanarImage> {
        let mut out = PlanarImage::new(self.width, self.height, layout::transparent_channel_names(k));
        self.transparent_into(k, out.data_mut())?;
        Ok(out)
    }

    /// Block until the GPU has finished all submitted work (for timing).
    pub fn wait(&self) -> Result<()> {
        gpu_stats::wait(&self.rasterizer.device).map_err(Error::Internal)
    }
}
