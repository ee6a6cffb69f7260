//! The rasterizer's GPU memory kept across frames: render targets of one size and the buffer
//! they are read back through, the light coverage's buffers, the shadow maps.

use glassbake_core::{Error, Result};
use glassbake_rays::gpu_readback::map_for_reading;
use glassbake_rays::gpu_stats::{created, GpuObject};

use super::{ChannelMap, DEPTH_FORMAT, TARGET_FORMAT};
use crate::light_coverage::exact::ExactInputs;

/// One set of same-sized Rgba32Float render targets and the buffer they are read back
/// through (rows padded to 256 bytes).
pub(super) struct TargetSet {
    pub(super) textures: Vec<wgpu::Texture>,
    pub(super) views: Vec<wgpu::TextureView>,
    pub(super) readback: wgpu::Buffer,
    pub(super) padded_row: u64,
}

impl TargetSet {
    pub(super) fn new(device: &wgpu::Device, count: u32, width: u32, height: u32, label: &str) -> TargetSet {
        let textures: Vec<wgpu::Texture> = (0..count)
            .map(|_| {
                let texture = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: TARGET_FORMAT,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                });
                created(GpuObject::Texture, texture)
            })
            .collect();
        let views = textures.iter().map(|t| created(GpuObject::Texture, t.create_view(&wgpu::TextureViewDescriptor::default()))).collect();
        let padded_row = padded_row_bytes(width);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: padded_row * height as u64 * count as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let readback = created(GpuObject::Buffer, readback);
        TargetSet { textures, views, readback, padded_row }
    }

    /// Attachments of targets `range`, cleared to 0.
    pub(super) fn color_attachments(&self, range: std::ops::Range<usize>) -> Vec<Option<wgpu::RenderPassColorAttachment<'_>>> {
        self.views[range]
            .iter()
            .map(|view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT), store: wgpu::StoreOp::Store },
                })
            })
            .collect()
    }

    /// Copy the targets to the host and scatter their components into `out`'s planes.
    pub(super) fn read_into(&self, device: &wgpu::Device, queue: &wgpu::Queue, map: &ChannelMap, width: u32, height: u32, data: &mut [f32]) -> Result<()> {
        let plane_bytes = self.padded_row * height as u64;
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
        for (t, texture) in self.textures.iter().enumerate() {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo { texture, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: t as u64 * plane_bytes,
                        bytes_per_row: Some(self.padded_row as u32),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            );
        }
        queue.submit([encoder.finish()]);
        map_for_reading(device, &self.readback)?;
        {
            let view = match self.readback.get_mapped_range(..) {
                Ok(view) => view,
                Err(e) => {
                    // Leave the buffer usable for the next frame.
                    self.readback.unmap();
                    return Err(Error::Internal(format!("reading the readback buffer: {e}")));
                }
            };
            let bytes: &[u8] = &view;
            let n = (width * height) as usize;
            for &(first, count, target, component) in map {
                for c in 0..count {
                    let plane = &mut data[(first + c) * n..(first + c + 1) * n];
                    let base = target as u64 * plane_bytes;
                    for y in 0..height as usize {
                        let row = base as usize + y * self.padded_row as usize;
                        for x in 0..width as usize {
                            let at = row + x * 16 + (component as usize + c) * 4;
                            plane[y * width as usize + x] = f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
                        }
                    }
                }
            }
        }
        self.readback.unmap();
        Ok(())
    }
}

/// Bytes per readback row: 16 bytes per texel, padded to wgpu's 256-byte copy alignment.
pub(crate) fn padded_row_bytes(width: u32) -> u64 {
    let unpadded = width as u64 * 16;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64;
    unpadded.div_ceil(align) * align
}

pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) depth: wgpu::TextureView,
    pub(super) opaque: TargetSet,
    pub(super) transparency: TargetSet,
    pub(super) naive: Option<TargetSet>,
    /// The light coverage reduced from this frame, and its host copy's staging buffer, for
    /// the one coverage size (made on first use).
    pub(super) coverage: Option<CoverageBuffers>,
}

/// Where a frame's light coverage is reduced to, and read back through.
pub(super) struct CoverageBuffers {
    /// The sampled reduction's factor (the coverage is the frame's size over it); `None` for
    /// the exact pass.
    pub(super) factor: Option<u32>,
    pub(super) reduced: wgpu::Buffer,
    pub(super) readback: wgpu::Buffer,
    /// The exact pass's parameters and outlines.
    pub(super) exact: Option<ExactInputs>,
    /// The reduction's bind groups from the opaque and the naive G-buffer (made on first use).
    pub(super) groups: [Option<wgpu::BindGroup>; 2],
}

impl CoverageBuffers {
    /// Buffers for `bytes` of coverage, and for the exact pass's outlines of `lights` lights
    /// when `factor` is `None`.
    pub(super) fn new(device: &wgpu::Device, factor: Option<u32>, bytes: u64, lights: usize) -> CoverageBuffers {
        let buffer = |label: &str, usage: wgpu::BufferUsages| {
            created(GpuObject::Buffer, device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: bytes, usage, mapped_at_creation: false }))
        };
        CoverageBuffers {
            factor,
            reduced: buffer("light coverage", wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC),
            readback: buffer("light coverage readback", wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ),
            exact: factor.is_none().then(|| ExactInputs::new(device, lights)),
            groups: [None, None],
        }
    }

    /// Whether these buffers serve a reduction at `factor` (`None`: exact) of `lights` lights.
    pub(super) fn serves(&self, factor: Option<u32>, lights: usize) -> bool {
        self.factor == factor && self.exact.as_ref().is_none_or(|e| e.capacity >= lights)
    }
}

pub(super) struct ShadowMaps {
    pub(super) size: u32,
    pub(super) layers: u32,
    pub(super) array_view: wgpu::TextureView,
    pub(super) layer_views: Vec<wgpu::TextureView>,
}

impl ShadowMaps {
    pub(super) fn new(device: &wgpu::Device, size: u32, layers: u32) -> ShadowMaps {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow maps"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: layers },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let texture = created(GpuObject::Texture, texture);
        let array_view = texture.create_view(&wgpu::TextureViewDescriptor { dimension: Some(wgpu::TextureViewDimension::D2Array), ..Default::default() });
        let array_view = created(GpuObject::Texture, array_view);
        let layer_views = (0..layers)
            .map(|l| {
                let view = texture.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: l,
                    array_layer_count: Some(1),
                    ..Default::default()
                });
                created(GpuObject::Texture, view)
            })
            .collect();
        ShadowMaps { size, layers, array_view, layer_views }
    }
}
