//! The GPU home of a frame's own data (the camera's and the shadow maps' views, the lights,
//! the shadow matrices, each object's uniforms) and the bind groups over it, kept by the
//! rasterizer across frames. A frame writes its data in with `queue.write_buffer`; buffers
//! and bind groups are made only when a frame needs more room than the last (they grow to the
//! next power of two) or binds an object to other textures. What the shadow maps hold is
//! remembered, so that they are drawn again only when a light or an occluder moved.

use glassbake_rays::gpu_cache::Recent;
use glassbake_rays::gpu_stats::{created, GpuObject};

use crate::rasterizer::KEPT_TARGET_SIZES;

/// Bytes per view uniform slot (>= every device's `min_uniform_buffer_offset_alignment`).
const VIEW_STRIDE: u64 = 256;
/// Bytes reserved per object in the object uniform buffer (the same bound).
pub(crate) const OBJECT_STRIDE: u64 = 256;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct ViewUniform {
    pub view_proj: [[f32; 4]; 4],
    pub camera_pos: [f32; 4],
    pub params: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct ObjectUniform {
    pub model: [[f32; 4]; 4],
    pub normal_matrix: [[f32; 4]; 4],
    pub base_color: [f32; 4],
    pub emission: [f32; 4],
    pub params: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct LightUniform {
    pub corners: [[f32; 4]; 4],
    pub radiance: [f32; 4],
    pub shadow: [f32; 4],
}

/// What a frame's shadow maps were drawn from: the faces' view-projections and each
/// occluder's mesh and model matrix (bit for bit).
#[derive(Clone, PartialEq)]
pub(crate) struct ShadowContent {
    pub faces: Vec<[[u32; 4]; 4]>,
    pub occluders: Vec<(wgpu::Buffer, [[u32; 4]; 4])>,
}

/// The layouts and fixed resources the bind groups are made against.
pub(crate) struct Layouts<'a> {
    pub view: &'a wgpu::BindGroupLayout,
    pub object: &'a wgpu::BindGroupLayout,
    pub shading: &'a wgpu::BindGroupLayout,
    pub material_sampler: &'a wgpu::Sampler,
    pub shadow_sampler: &'a wgpu::Sampler,
    pub ltc_matrix: &'a wgpu::TextureView,
    pub ltc_amplitude: &'a wgpu::TextureView,
}

/// The texture views the shading bind groups read besides the frame's own buffers.
#[derive(Clone, PartialEq)]
pub(crate) struct ShadingInputs {
    pub shadow_maps: wgpu::TextureView,
    /// What the opaque G-buffer pass reads as "the opaque surface" (nothing: a 1x1 zero).
    pub no_opaque: wgpu::TextureView,
    /// The opaque G-buffer's position target, which the transparency pass reads.
    pub opaque_positions: wgpu::TextureView,
}

/// A buffer that keeps its size until a write needs more.
struct GrowingBuffer {
    label: &'static str,
    usage: wgpu::BufferUsages,
    buffer: Option<wgpu::Buffer>,
}

impl GrowingBuffer {
    fn new(label: &'static str, usage: wgpu::BufferUsages) -> GrowingBuffer {
        GrowingBuffer { label, usage: usage | wgpu::BufferUsages::COPY_DST, buffer: None }
    }

    /// Writes `bytes` from offset 0, first making the buffer anew (at the next power of two
    /// of their size) when they do not fit; true when it was made anew.
    fn write(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, bytes: &[u8]) -> bool {
        let needed = (bytes.len() as u64).max(16);
        let grown = self.buffer.as_ref().is_none_or(|b| b.size() < needed);
        if grown {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: needed.next_power_of_two(),
                usage: self.usage,
                mapped_at_creation: false,
            });
            self.buffer = Some(created(GpuObject::Buffer, buffer));
        }
        queue.write_buffer(self.get(), 0, bytes);
        grown
    }

    fn get(&self) -> &wgpu::Buffer {
        self.buffer.as_ref().expect("written before use")
    }
}

/// Each of `items` at the start of its own `stride`-byte slot.
fn slotted<T: bytemuck::Pod>(items: &[T], stride: u64) -> Vec<u8> {
    let mut bytes = vec![0u8; items.len() * stride as usize];
    for (i, item) in items.iter().enumerate() {
        let at = i * stride as usize;
        bytes[at..at + std::mem::size_of::<T>()].copy_from_slice(bytemuck::bytes_of(item));
    }
    bytes
}

fn uniform_slot(buffer: &wgpu::Buffer, slot: usize, stride: u64, size: usize) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer, offset: slot as u64 * stride, size: wgpu::BufferSize::new(size as u64) })
}

pub(crate) struct FrameData {
    views: GrowingBuffer,
    /// One bind group per view slot: slot 0 the camera, then one per shadow-map face.
    view_groups: Vec<wgpu::BindGroup>,
    lights: GrowingBuffer,
    shadow_matrices: GrowingBuffer,
    objects: GrowingBuffer,
    /// One bind group per object slot, with the (base colour, roughness) views it binds.
    object_groups: Vec<(wgpu::TextureView, wgpu::TextureView, wgpu::BindGroup)>,
    /// The opaque and the transparency passes' shading bind groups, by the views they bind
    /// (one entry per target size the rasterizer keeps).
    shading: Recent<ShadingInputs, (wgpu::BindGroup, wgpu::BindGroup)>,
    /// What the shadow maps hold; `None` when they hold nothing known.
    pub shadow_content: Option<ShadowContent>,
}

impl FrameData {
    pub fn new() -> FrameData {
        FrameData {
            views: GrowingBuffer::new("views", wgpu::BufferUsages::UNIFORM),
            view_groups: Vec::new(),
            lights: GrowingBuffer::new("lights", wgpu::BufferUsages::STORAGE),
            shadow_matrices: GrowingBuffer::new("shadow matrices", wgpu::BufferUsages::STORAGE),
            objects: GrowingBuffer::new("objects", wgpu::BufferUsages::UNIFORM),
            object_groups: Vec::new(),
            shading: Recent::new(KEPT_TARGET_SIZES),
            shadow_content: None,
        }
    }

    /// Writes the view uniforms (the camera's first) and returns one bind group per view.
    pub fn write_views(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, layouts: &Layouts, views: &[ViewUniform]) -> &[wgpu::BindGroup] {
        if self.views.write(device, queue, &slotted(views, VIEW_STRIDE)) {
            self.view_groups.clear();
        }
        let buffer = self.views.get();
        for slot in self.view_groups.len()..views.len() {
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("view"),
                layout: layouts.view,
                entries: &[wgpu::BindGroupEntry { binding: 0, resource: uniform_slot(buffer, slot, VIEW_STRIDE, std::mem::size_of::<ViewUniform>()) }],
            });
            self.view_groups.push(created(GpuObject::BindGroup, group));
        }
        &self.view_groups[..views.len()]
    }

    /// Writes the objects' uniforms and returns one bind group per object, binding its
    /// (base colour, roughness) texture views.
    pub fn write_objects(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        layouts: &Layouts,
        objects: &[ObjectUniform],
        textures: &[(wgpu::TextureView, wgpu::TextureView)],
    ) -> Vec<wgpu::BindGroup> {
        if self.objects.write(device, queue, &slotted(objects, OBJECT_STRIDE)) {
            self.object_groups.clear();
        }
        let buffer = self.objects.get();
        for (slot, (base, rough)) in textures.iter().enumerate() {
            if self.object_groups.get(slot).is_some_and(|(b, r, _)| b == base && r == rough) {
                continue;
            }
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("object"),
                layout: layouts.object,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: uniform_slot(buffer, slot, OBJECT_STRIDE, std::mem::size_of::<ObjectUniform>()) },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(base) },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(rough) },
                    wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(layouts.material_sampler) },
                ],
            });
            let entry = (base.clone(), rough.clone(), created(GpuObject::BindGroup, group));
            if slot < self.object_groups.len() {
                self.object_groups[slot] = entry;
            } else {
                self.object_groups.push(entry);
            }
        }
        self.object_groups[..textures.len()].iter().map(|(_, _, group)| group.clone()).collect()
    }

    /// Writes the lights and the shadow faces' matrices and returns the opaque and the
    /// transparency passes' shading bind groups.
    pub fn write_shading(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        layouts: &Layouts,
        lights: &[LightUniform],
        shadow_matrices: &[[[f32; 4]; 4]],
        inputs: ShadingInputs,
    ) -> (wgpu::BindGroup, wgpu::BindGroup) {
        let lights_grown = self.lights.write(device, queue, bytemuck::cast_slice(lights));
        let matrices_grown = self.shadow_matrices.write(device, queue, bytemuck::cast_slice(shadow_matrices));
        if lights_grown || matrices_grown {
            self.shading = Recent::new(KEPT_TARGET_SIZES);
        }
        let (lights, matrices) = (self.lights.get(), self.shadow_matrices.get());
        let (opaque, transparency) = self.shading.get_or_make(inputs.clone(), || {
            let group = |surface: &wgpu::TextureView| {
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("shading"),
                    layout: layouts.shading,
                    entries: &[
                        wgpu::BindGroupEntry { binding: 0, resource: lights.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&inputs.shadow_maps) },
                        wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(layouts.shadow_sampler) },
                        wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(layouts.ltc_matrix) },
                        wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(layouts.ltc_amplitude) },
                        wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::TextureView(surface) },
                        wgpu::BindGroupEntry { binding: 6, resource: matrices.as_entire_binding() },
                    ],
                });
                created(GpuObject::BindGroup, group)
            };
            (group(&inputs.no_opaque), group(&inputs.opaque_positions))
        });
        (opaque.clone(), transparency.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_item_starts_its_own_slot() {
        let bytes = slotted(&[1u32, 2, 3], 8);
        assert_eq!(bytes.len(), 24);
        assert_eq!(bytemuck::cast_slice::<u8, u32>(&bytes), &[1, 0, 2, 0, 3, 0]);
    }
}
