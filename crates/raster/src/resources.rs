//! GPU copies of meshes and textures, cached by the identity of the scene's shared `Arc`s, so
//! that rendering many instances of one scene (which share meshes and textures) uploads each
//! only once.

use std::collections::HashMap;
use std::sync::Arc;

use glam::Vec4;
use glassbake_rays::gpu_stats::{created, GpuObject};
use glassbake_scene::{Mesh, RectLight, Texture};
use wgpu::util::DeviceExt;

/// Interleaved vertex: position, normal, uv (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
}

pub(crate) const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 3] = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2];

pub(crate) fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    wgpu::VertexBufferLayout { array_stride: std::mem::size_of::<Vertex>() as u64, step_mode: wgpu::VertexStepMode::Vertex, attributes: &VERTEX_ATTRIBUTES }
}

pub(crate) struct GpuMesh {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub index_count: u32,
}

fn vertices(mesh: &Mesh) -> Vec<Vertex> {
    (0..mesh.positions.len())
        .map(|i| Vertex {
            position: mesh.positions[i].to_array(),
            normal: mesh.normals.get(i).copied().unwrap_or_default().to_array(),
            uv: mesh.uvs.get(i).copied().unwrap_or_default().to_array(),
        })
        .collect()
}

impl GpuMesh {
    pub fn upload(device: &wgpu::Device, mesh: &Mesh, label: &str) -> Option<GpuMesh> {
        GpuMesh::upload_with(device, mesh, label, wgpu::BufferUsages::empty())
    }

    /// [`GpuMesh::upload`] with the vertex buffer's usage widened by `vertex_usage` (COPY_DST
    /// for a mesh rewritten in place).
    fn upload_with(device: &wgpu::Device, mesh: &Mesh, label: &str, vertex_usage: wgpu::BufferUsages) -> Option<GpuMesh> {
        if mesh.indices.is_empty() || mesh.positions.is_empty() {
            return None;
        }
        let vertices = vertices(mesh);
        let indices: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
        Some(GpuMesh {
            vertices: created(
                GpuObject::Buffer,
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: wgpu::BufferUsages::VERTEX | vertex_usage,
                }),
            ),
            indices: created(
                GpuObject::Buffer,
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(&indices),
                    usage: wgpu::BufferUsages::INDEX,
                }),
            ),
            index_count: indices.len() as u32,
        })
    }
}

/// The mip chain of a texture, each level a 2x2 box filter of the one above (odd sizes
/// clamp at the edge).
pub(crate) fn mip_chain(width: u32, height: u32, texels: &[Vec4]) -> Vec<(u32, u32, Vec<Vec4>)> {
    let mut levels = vec![(width, height, texels.to_vec())];
    loop {
        let (w, h, prev) = levels.last().expect("level 0 exists");
        let (w, h) = (*w, *h);
        if w == 1 && h == 1 {
            break;
        }
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let at = |x: u32, y: u32| prev[(y.min(h - 1) * w + x.min(w - 1)) as usize];
        let mut next = Vec::with_capacity((nw * nh) as usize);
        for y in 0..nh {
            for x in 0..nw {
                let (x0, y0) = (2 * x, 2 * y);
                next.push(0.25 * (at(x0, y0) + at(x0 + 1, y0) + at(x0, y0 + 1) + at(x0 + 1, y0 + 1)));
            }
        }
        levels.push((nw, nh, next));
    }
    levels
}

/// Upload a linear RGBA texture with its full mip chain as Rgba16Float (filterable on every
/// Vulkan device, unlike Rgba32Float).
pub(crate) fn upload_texture(device: &wgpu::Device, queue: &wgpu::Queue, texture: &Texture) -> wgpu::Texture {
    let levels = mip_chain(texture.width, texture.height, &texture.texels);
    let mut bytes: Vec<u16> = Vec::new();
    for (_, _, texels) in &levels {
        for t in texels {
            for c in t.to_array() {
                bytes.push(half::f16::from_f32(c).to_bits());
            }
        }
    }
    device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some(&texture.name),
            size: wgpu::Extent3d { width: texture.width, height: texture.height, depth_or_array_layers: 1 },
            mip_level_count: levels.len() as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&bytes),
    )
}

/// Caches keyed by `Arc` identity; the `Arc` is kept so the address cannot be reused while
/// the entry lives.
#[derive(Default)]
pub(crate) struct Cache {
    meshes: HashMap<usize, (Arc<Mesh>, Option<GpuMesh>)>,
    textures: HashMap<usize, (Arc<Texture>, wgpu::TextureView)>,
    /// The last frame's light quads, with their corners (bit for bit).
    light_quads: Vec<([[u32; 3]; 4], Option<GpuMesh>)>,
}

impl Cache {
    pub fn mesh(&mut self, device: &wgpu::Device, mesh: &Arc<Mesh>) -> Option<&GpuMesh> {
        let key = Arc::as_ptr(mesh) as usize;
        self.meshes.entry(key).or_insert_with(|| (mesh.clone(), GpuMesh::upload(device, mesh, "mesh"))).1.as_ref()
    }

    pub fn texture(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, texture: &Arc<Texture>) -> wgpu::TextureView {
        let key = Arc::as_ptr(texture) as usize;
        self.textures
            .entry(key)
            .or_insert_with(|| {
                let t = created(GpuObject::Texture, upload_texture(device, queue, texture));
                (texture.clone(), created(GpuObject::Texture, t.create_view(&wgpu::TextureViewDescriptor::default())))
            })
            .1
            .clone()
    }

    /// The quad of each of `lights`: the last call's quad of the same index, its vertices
    /// written anew where the light moved (a quad's four vertices always fit), so moving a
    /// light makes no buffer.
    pub fn light_quads(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, lights: &[RectLight]) -> Vec<Option<&GpuMesh>> {
        self.light_quads.truncate(lights.len());
        for (i, light) in lights.iter().enumerate() {
            let key = light.corners().map(|c| c.to_array().map(f32::to_bits));
            match self.light_quads.get_mut(i) {
                Some((kept, Some(quad))) => {
                    if *kept != key {
                        queue.write_buffer(&quad.vertices, 0, bytemuck::cast_slice(&vertices(&light.to_mesh())));
                        *kept = key;
                    }
                }
                _ => {
                    let quad = GpuMesh::upload_with(device, &light.to_mesh(), "light quad", wgpu::BufferUsages::COPY_DST);
                    if i < self.light_quads.len() {
                        self.light_quads[i] = (key, quad);
                    } else {
                        self.light_quads.push((key, quad));
                    }
                }
            }
        }
        self.light_quads.iter().map(|(_, quad)| quad.as_ref()).collect()
    }

    pub fn clear(&mut self) {
        self.meshes.clear();
        self.textures.clear();
        self.light_quads.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_chain_averages_and_ends_at_one_texel() {
        let texels: Vec<Vec4> = (0..12).map(|i| Vec4::splat(i as f32)).collect();
        let levels = mip_chain(4, 3, &texels);
        let sizes: Vec<(u32, u32)> = levels.iter().map(|l| (l.0, l.1)).collect();
        assert_eq!(sizes, vec![(4, 3), (2, 1), (1, 1)]);
        // Level 1, texel 0: mean of texels (0,0),(1,0),(0,1),(1,1) = (0+1+4+5)/4.
        assert_eq!(levels[1].2[0].x, 2.5);
    }
}
